"""Loop analysis against python-control on a linear test plant (tests/linear_plant.py):
the stepped-sine frequency response and the gain margin of the sampled P loop."""

from __future__ import annotations

import math

import numpy as np
import pytest

control = pytest.importorskip("control")

import linear_plant  # noqa: E402  (tests/ is on sys.path)
from reference_plants import from_module  # noqa: E402

from fuzzyservo.analysis import frequency_response, gain_margin, oscillation  # noqa: E402
from fuzzyservo.controllers.classical import P  # noqa: E402
from fuzzyservo.metrics import command_tv  # noqa: E402
from fuzzyservo.rig import Actuator, LinearSensor, Rig, Scenario  # noqa: E402
from fuzzyservo.signals import Steps  # noqa: E402
from fuzzyservo.simulation import simulate  # noqa: E402

DT = 1e-3
VALUES = {"force_gain": 1000.0, "force_lag_s": 0.02, "mass_kg": 1.0, "damping": 12.0,
          "stiffness": 1000.0}  # fmt: skip


def _rig() -> Rig:
    plant = from_module("linear_test", linear_plant, "linear test plant")
    return Rig(
        name="linear_test",
        plant=plant,
        params=linear_plant.LinearParams(**VALUES),
        feedback=LinearSensor("y", gain=1.0, unit="V"),
        actuator=Actuator("amp", gain=1.0, lower=-1e6, upper=1e6, unit="V"),
        sample_time_s=DT,
        output="y_out",
        scenarios={
            "step": Scenario("step", 4.0, Steps((0.5,), (0.01,)), warmup_s=0.2),
        },
    )


def _plant_tf():
    v = VALUES
    s = control.tf("s")
    return v["force_gain"] / (
        (v["force_lag_s"] * s + 1) * (v["mass_kg"] * s**2 + v["damping"] * s + v["stiffness"])
    )


def test_frequency_response_matches_the_sampled_transfer_function() -> None:
    rig, k = _rig(), 0.5
    freqs = np.array([0.5, 2.0, 5.0, 10.0, 20.0])
    fr = frequency_response(rig, P(name="p", gain=k), freqs, amplitude=0.01,
                            operating_point=0.0, settle_s=0.2, discard_s=2.0)  # fmt: skip
    gd = control.c2d(_plant_tf(), DT, method="zoh")
    closed = control.feedback(k * gd, 1)
    expected = np.array([complex(closed(np.exp(2j * np.pi * f * DT))) for f in freqs])
    mag = 20 * np.log10(np.abs(expected))
    phase = np.degrees(np.unwrap(np.angle(expected)))
    assert np.all(np.abs(fr.magnitude_db - mag) < 0.5), (fr.magnitude_db, mag)
    assert np.all(np.abs(fr.phase_deg - phase) < 3.0), (fr.phase_deg, phase)


@pytest.mark.filterwarnings("ignore:stability_margins:UserWarning")  # the analytic reference
def test_gain_margin_of_a_sampled_third_order_loop() -> None:
    rig, k = _rig(), 0.5
    gd = control.c2d(_plant_tf(), DT, method="zoh")
    gm, _, wcg, _ = control.margin(k * gd)
    found = gain_margin(rig, P(name="p", gain=k), rel_tol=0.005)
    assert found.value == pytest.approx(gm, rel=0.05)
    assert found.frequency_hz == pytest.approx(wcg / (2 * math.pi), rel=0.05)


def test_detector_and_chatter_on_a_stable_run() -> None:
    result = simulate(_rig(), P(name="p", gain=0.5))
    osc = oscillation(result)
    assert not osc.sustained and osc.reason in ("decaying", "below_floor")
    assert command_tv(result.command, DT) > 0


def _with_error(result, error: np.ndarray):
    """``result`` with the tracking error after the reference step replaced by ``error``."""
    import dataclasses

    start = int(np.flatnonzero(np.diff(result.reference))[-1]) + 1
    feedback = result.reference.copy()
    feedback[start:] += error[: feedback.size - start]
    return dataclasses.replace(result, feedback=feedback)


def test_detector_measures_the_dominant_sinusoid_not_noise_driven_jitter() -> None:
    """A sustained 8 Hz sinusoid twice the floor is an oscillation of its own amplitude;
    broadband jitter (a resonance at 8 Hz, damping 0.3, driven by white noise) whose
    half peak-to-peak swing is 1.5 times the floor, like noise through a stable loop, is
    not (its dominant sinusoid: 0.5-0.7 of the floor over five noise seeds)."""
    base = simulate(_rig(), P(name="p", gain=0.5))
    floor = oscillation(base).floor
    t = np.arange(base.t.size) * DT
    tone = oscillation(_with_error(base, 2 * floor * np.sin(2 * np.pi * 8.0 * t)))
    assert tone.sustained and tone.amplitude == pytest.approx(2 * floor, rel=0.03)
    assert tone.frequency_hz == pytest.approx(8.0, rel=0.02)
    w, z = 2 * np.pi * 8.0 * DT, 0.3  # AR(2) resonance, sampled
    a1, a2 = 2 * math.exp(-z * w) * math.cos(w * math.sqrt(1 - z * z)), -math.exp(-2 * z * w)
    x, e = np.zeros(t.size), np.random.default_rng(3).standard_normal(t.size)
    for k in range(2, t.size):
        x[k] = a1 * x[k - 1] + a2 * x[k - 2] + e[k]
    jitter = _with_error(base, x * (1.5 * floor / (0.5 * np.ptp(x[-1000:]))))
    osc = oscillation(jitter)
    assert not osc.sustained and osc.reason == "below_floor" and osc.amplitude < floor


def test_command_tv_is_the_total_variation_per_second() -> None:
    u = np.array([0.0, 1.0, -1.0, -1.0, 0.0])  # |Δu| sums to 4 over 5 samples of 0.1 s
    assert command_tv(u, 0.1) == pytest.approx(8.0)


def test_margin_constraints_are_accepted_by_a_study(tmp_path) -> None:
    from fuzzyservo.tuning.spec import MARGIN_METRICS, Constraint

    c = Constraint.parse("gain_margin >= 2")
    assert c.metric in MARGIN_METRICS and c.violation(1.5) == pytest.approx(0.5)
    assert Constraint.parse("delay_margin_s >= 0.01").violation(0.02) < 0


@pytest.mark.slow
def test_margins_command_writes_the_json(tmp_path) -> None:
    import json

    from fuzzyservo.cli import main

    out = tmp_path / "m.json"
    assert main(["margins", "dinca_cylinder", "p_k10", "--json", str(out)]) == 0
    m = json.loads(out.read_text())
    assert m["gain_bracket"][0] < m["gain_margin"] < m["gain_bracket"][1]
    assert m["oscillation_hz"] > 0 and m["delay_margin_s"] > 0


@pytest.mark.slow
def test_frequency_command_writes_json_and_bode_plot(tmp_path, capsys) -> None:
    import json

    from fuzzyservo.cli import main

    out = tmp_path / "f.json"
    args = ["frequency", "dinca_cylinder", "p_k10", "--out", str(tmp_path), "--json", str(out)]
    assert main(args) == 0
    f = json.loads(out.read_text())
    assert len(f["frequency_hz"]) == len(f["magnitude_db"]) == len(f["phase_deg"])
    assert abs(f["magnitude_db"][0]) < 0.5 and f["bandwidth_hz"] > 0
    assert list(tmp_path.glob("bode_*.png"))
    assert main(["frequency", "dinca_cylinder", "p_k10", "--amplitude", "-1"]) == 2
    assert "--amplitude" in capsys.readouterr().err


@pytest.mark.filterwarnings("ignore:stability_margins:UserWarning")  # the analytic reference
def test_a_margin_constraint_is_decided_at_its_bound() -> None:
    """A study's `gain_margin >= b` costs one run at b: met (recorded as b, a lower bound)
    below the analytic margin, violated (undefined) above it."""
    from fuzzyservo.tuning.objective import margin_metrics
    from fuzzyservo.tuning.spec import Constraint

    rig, ctrl = _rig(), P(name="p", gain=0.5)
    gm = control.margin(0.5 * control.c2d(_plant_tf(), DT, method="zoh"))[0]
    below, above = (
        Constraint.parse(f"gain_margin >= {0.9 * gm}"),
        Constraint.parse(f"gain_margin >= {1.1 * gm}"),
    )
    assert margin_metrics(rig, ctrl, "step", [below])["gain_margin"] == pytest.approx(0.9 * gm)
    assert math.isnan(margin_metrics(rig, ctrl, "step", [above])["gain_margin"])
    assert above.violation(math.nan) > 0
