"""The notebook API: everything a user needs is importable from ``fuzzyservo`` and
visible to ``dir()``; a rig, a controller and a study are built in code."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from support import DATA

import fuzzyservo

PUBLIC = (
    "Rig", "compose_rig", "load_rig", "P", "PI", "FuzzyController", "load_controller",
    "Study", "Parameter", "FuzzyDesign", "Objective", "load_study", "simulate", "compare", "tune",
    "calibrate", "read_measured", "read_rig_data", "result_metrics", "Scenario", "LinearSensor", "Actuator",
    "METRIC_UNITS",
)  # fmt: skip


def test_public_names_are_visible_and_import() -> None:
    listed = dir(fuzzyservo)
    for name in PUBLIC:
        assert name in listed and name in fuzzyservo.__all__
        assert getattr(fuzzyservo, name) is not None


def test_import_pulls_in_no_plotting_yaml_or_optuna() -> None:
    code = (
        "import sys, fuzzyservo; dir(fuzzyservo); "
        "print([m for m in ('matplotlib', 'yaml', 'optuna') if m in sys.modules])"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def _lift_in_code():
    from fuzzyservo import Actuator, LinearSensor, Scenario, compose_rig
    from fuzzyservo.signals import Steps

    return compose_rig(
        "servo_lift_in_code",
        {
            "oil": ("oil", {"bulk_modulus": 1.4e9, "laminar_pressure": 1e4}),
            "supply": ("pump_supply", {
                "pump_flow": 12 / 60e3, "supply_pressure": 140e5,
                "relief_cracking_pressure": 135e5, "relief_knee": 0.5e5, "supply_volume": 0.5e-3,
            }),
            "valve": ("servo_valve", {
                "rated_flow": 10 / 60e3, "rated_pressure_drop": 70e5, "rated_signal": 0.010,
                "spool_natural_frequency": 120.0, "spool_damping": 0.7,
            }),
            "cylinder": ("double_rod_cylinder", {
                "piston_diameter": 0.040, "rod_diameter": 0.025, "stroke": 0.3,
                "piston_mass": 4.0, "dead_volume_a": 30e-6, "dead_volume_b": 30e-6,
                "end_stop_damping": 6.4e4,
            }),
            "payload": ("mass", {"mass": 100.0}),
            "weight": ("gravity", {}),
            "guides": ("damper", {"coefficient": 500.0}),
        },
        feedback=LinearSensor("y", gain=33.333),
        actuator=Actuator("servo amplifier", 1e-3, -0.010, 0.010, "A"),
        sample_time_s=1e-3,
        scenarios=[
            Scenario("steps", 8.0, Steps((0.5, 3.0, 5.5), (6.6667, 3.3333, 4.3333), 5.0), warmup_s=0.2)
        ],
        initial={"position": 0.15},
        io_delay_s=1e-3,  # the file's controller.io_delay (issue 11)
    )  # fmt: skip


@pytest.mark.slow
def test_a_rig_built_in_code_runs_like_its_file(tmp_path: Path) -> None:
    from fuzzyservo import P, compare, load_rig, simulate

    in_code = _lift_in_code()
    from_file = load_rig(DATA / "rigs" / "servo_lift.yaml")
    p4 = P(gain=4.0, u_min=-10.0, u_max=10.0, name="p4")
    a = simulate(in_code, p4, "steps")
    b = simulate(from_file, p4, "steps")
    # the file's reference is in mm through the 33.333 V/m sensor: the same steps
    np.testing.assert_allclose(a.signals["y"], b.signals["y"], atol=2e-5)
    runs = compare(in_code, [p4, P(gain=2.0, u_min=-10.0, u_max=10.0, name="p2")], "steps")
    assert list(runs) == ["p4", "p2"] and all(r.ok for r in runs.values())


def test_a_study_written_in_python_runs_resumes_and_reports(tmp_path: Path) -> None:
    """Issue 25: a study built from Python objects alone (no rig, controller or study
    file; only the SQLite storage the user names) runs, resumes with its finished trials
    kept, and reports like one read from a file."""
    from fuzzyservo import PI, Objective, P, Parameter, Study, tune
    from fuzzyservo.workflows import write_study_report

    study = Study(
        name="lift_in_code",
        rig=_lift_in_code(),
        scenarios=("steps",),
        template=PI(kp=1.0, ki=0.5, u_min=-10.0, u_max=10.0, name="pi_lift"),
        parameters=(Parameter("kp", 0.5, 8.0, log=True), Parameter("ki", 0.01, 20.0, log=True)),
        objective=Objective(weights={"settling_time_s": 1.0, "sse_abs": 1000.0}),
        baseline=P(gain=4.0, u_min=-10.0, u_max=10.0, name="p4"),
        warm_start=(PI(kp=4.0, ki=30.0).params(),),  # ki clipped to 20
        trials=3,
        seed=3,
    )
    storage = f"sqlite:///{tmp_path / 'lift.db'}"
    first = tune(study, tmp_path / "out", storage=storage, progress=False)
    assert first.trials_complete == 3 and first.best.status == "ok"
    import optuna

    stored = optuna.load_study(study_name="lift_in_code", storage=storage)
    assert stored.trials[0].params == {"kp": 4.0, "ki": 20.0}  # the warm start, clipped
    assert first.storage_url == storage and not list((tmp_path / "out").iterdir())
    again = tune(study, tmp_path / "out", trials=5, storage=storage, progress=False)
    assert again.trials_complete == 5
    before = {h["number"]: h["values"] for h in first.history}
    assert all(h["values"] == before[h["number"]] for h in again.history if h["number"] in before)
    assert len(before) == 3
    _, paths = write_study_report(again, tmp_path / "report")
    from fuzzyservo import load_controller

    best = load_controller(paths["controller"])
    assert best.params() == pytest.approx(again.best_params)
    assert "lift_in_code" in paths["report"].read_text(encoding="utf-8")


def test_a_shipped_study_loads_by_name_as_a_shipped_rig_does() -> None:
    study = fuzzyservo.load_study("dinca_flc")
    assert study == fuzzyservo.load_study(DATA / "studies" / "dinca_flc.yaml")
    with pytest.raises(fuzzyservo.ConfigError, match="no study named 'dinca_flx'"):
        fuzzyservo.load_study("dinca_flx")
