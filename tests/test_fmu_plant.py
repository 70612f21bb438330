"""A model-exchange FMU as the rig's plant (issue 39): integrated by the loop's own solver,
its C functions called from the compiled loop, the same numbers as FMPy's own simulation
of the same FMU, and every command on it.

The FMUs are the Modelica Association's Reference FMUs, built from the sources on the
team's shelf (tests/reference_fmus.py; skipped when absent).
"""

from __future__ import annotations

import json
import pickle
from pathlib import Path

import numpy as np
import pytest
import yaml
from reference_fmus import build
from support import run_cli

import fuzzyservo as fs
from fuzzyservo.errors import ConfigError

fmpy = pytest.importorskip("fmpy", reason="FMU plants need FMPy (the fmi extra)")

#: the docs' example (docs/fmu-plants.md): the Reference FMU StateSpace, first order on its
#: first input, dx1/dt = A[1]·x1 + u1 with A[1] = -2 /s, the other two states unforced;
#: y[1] = x1 + u1 (StateSpace's D is the identity)
EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "fmu" / "state_space.yaml"
STATE_SPACE_RIG = yaml.safe_load(EXAMPLE.read_text(encoding="utf-8"))

VAN_DER_POL_RIG = {
    "name": "van_der_pol",
    "plant": {
        "fmu": {"file": "VanDerPol.fmu", "signals": {"position": "x0", "speed": "x1"}},
        "parameters": {"mu": {"value": 1, "unit": "1", "source": "Reference FMUs default"}},
    },
    "feedback": {"signal": "position", "gain": {"value": 1, "unit": "V"}},
    "actuator": {
        "gain": {"value": 1, "unit": "1/V"},
        "lower": {"value": -10, "unit": "1"},
        "upper": {"value": 10, "unit": "1"},
    },
    "controller": {"sample_time": {"value": 10, "unit": "ms"}},
    "output": {"signal": "position"},
    "scenarios": {
        "free": {
            "duration": {"value": 20, "unit": "s"},
            "reference": {"type": "constant", "unit": "V", "value": 0},
        }
    },
}


@pytest.fixture(scope="module")
def fmus(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("fmus")
    for model, version in (("VanDerPol", 2), ("VanDerPol", 3), ("StateSpace", 3)):
        build(model, version, folder)
    build("BouncingBall", 2, folder)
    (folder / "StateSpace.fmu").write_bytes((folder / "StateSpace_fmi3.fmu").read_bytes())
    return folder


def write_rig(folder: Path, data: dict, name: str = "rig.yaml") -> Path:
    path = folder / name
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


@pytest.mark.parametrize("version", [2, 3])
def test_van_der_pol_runs_as_fmpy_simulates_it(fmus, tmp_path, version):
    """No input: the loop integrates the oscillator alone; FMPy's CVode at 1e-12 agrees
    within 1e-6 of the amplitude over 20 s (about three periods)."""
    fmu = fmus / f"VanDerPol_fmi{version}.fmu"
    (tmp_path / "VanDerPol.fmu").write_bytes(fmu.read_bytes())
    rig = fs.load_rig(write_rig(tmp_path, VAN_DER_POL_RIG))
    assert rig.plant.states == ("position", "speed")  # named by the signals reading them
    assert f"FMI {version}.0 model exchange" in rig.plant.description
    run = fs.simulate(rig, fs.load_controller("p_k10"), noise=False, tol=1e-6)
    assert run.status == "ok"
    ref = fmpy.simulate_fmu(str(fmu), fmi_type="ModelExchange", stop_time=20,
                            output_interval=0.01, relative_tolerance=1e-12)  # fmt: skip
    for signal, column in (("position", "x0"), ("speed", "x1")):
        expected = np.interp(run.t, ref["time"], ref[column])
        error = np.max(np.abs(run.signal(signal) - expected))
        assert error <= 1e-6 * np.max(np.abs(expected)), (signal, error)


def test_state_space_under_p_control_matches_fmpy(fmus, tmp_path):
    """A P controller drives u[1]; FMPy, fed the same held command, gives the same y[1]
    (a direct feedthrough) at every sample within 1e-6."""
    (tmp_path / "StateSpace.fmu").write_bytes((fmus / "StateSpace.fmu").read_bytes())
    rig = fs.load_rig(write_rig(tmp_path, STATE_SPACE_RIG))
    assert rig.plant.states == ("x1", "x[2]", "x[3]")
    run = fs.simulate(rig, fs.load_controller("p_k10"), noise=False, tol=1e-6)
    assert run.status == "ok"
    # P 10 on dx/dt = -2x + u settles at x = 10/12 of the reference (docs/fmu-plants.md)
    assert run.signal("x1")[190] == pytest.approx(10 / 12, rel=1e-3)
    t, held = run.t, run.actuator
    inputs = np.zeros(2 * t.size - 1, dtype=[("time", float), ("u", float, (3,))])
    inputs["time"] = np.repeat(t, 2)[1:]
    inputs["u"][:, 0] = np.repeat(held, 2)[:-1]
    inputs["u"][:, 1:] = (2.0, 3.0)  # the other inputs at their start values
    ref = fmpy.simulate_fmu(
        str(tmp_path / "StateSpace.fmu"), fmi_type="ModelExchange", stop_time=t[-1],
        output_interval=0.01, relative_tolerance=1e-12, input=inputs, output=["y"],
        start_values={"A": [-2.0, 0, 0, 0, 1, 0, 0, 0, 1]},
    )  # fmt: skip
    at = np.searchsorted(ref["time"], t, side="right") - 1  # after each sample's input step
    error = np.max(np.abs(ref["y"][at, 0] - run.signal("y")))
    assert error <= 1e-6 * np.max(np.abs(run.signal("y")))


def test_an_fmu_plant_pickles_as_its_file_and_mapping(fmus, tmp_path):
    """Worker processes (tuning, calibration) rebuild the plant and its parameters."""
    (tmp_path / "StateSpace.fmu").write_bytes((fmus / "StateSpace.fmu").read_bytes())
    rig = fs.load_rig(write_rig(tmp_path, STATE_SPACE_RIG))
    again = pickle.loads(pickle.dumps(rig))
    assert again.plant is rig.plant  # the cached plant of the same file and mapping
    assert again.params == rig.params


@pytest.mark.parametrize(
    ("edit", "hint"),
    [
        (lambda d: d["plant"]["fmu"]["signals"].update(y="nope"), "'nope' is no real variable"),
        (lambda d: d["plant"]["fmu"].update(input="y[1]"), "not an input"),
        (lambda d: d["plant"]["fmu"].update(input="u"), "holds 3 values; name one as u[1]"),
        (lambda d: d["plant"]["fmu"].update(file="missing.fmu"), "no such FMU file"),
        (lambda d: d["plant"]["fmu"].update(file="BouncingBall_fmi2.fmu"), "event indicators"),
        (lambda d: d["plant"]["fmu"].update(file="Old.fmu"), "FMI 1.0 is not supported"),
        (lambda d: d["plant"]["parameters"].update(B0={"value": 1}), "unknown key"),
        (lambda d: d["output"].update(display_unit="cm"), "display_unit"),
    ],
)
def test_a_mapping_that_does_not_fit_is_one_line(fmus, tmp_path, edit, hint):
    for name in ("StateSpace.fmu", "BouncingBall_fmi2.fmu"):
        (tmp_path / name).write_bytes((fmus / name).read_bytes())
    _fmi1_copy(fmus / "VanDerPol_fmi2.fmu", tmp_path / "Old.fmu")
    data = json.loads(json.dumps(STATE_SPACE_RIG))
    edit(data)
    path = write_rig(tmp_path, data)
    with pytest.raises(ConfigError) as err:
        fs.load_rig(path)
    message = str(err.value)
    assert hint in message and "\n" not in message and str(path) in message


def _fmi1_copy(source: Path, target: Path) -> None:
    """``source`` with its model description claiming FMI 1.0."""
    import zipfile

    with zipfile.ZipFile(source) as zin, zipfile.ZipFile(target, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item)
            if item.filename == "modelDescription.xml":
                data = data.replace(b'fmiVersion="2.0"', b'fmiVersion="1.0"')
            zout.writestr(item, data)


@pytest.mark.slow
def test_commands_run_on_an_fmu_plant(fmus, tmp_path):
    """compare, margins, robustness (sampling the FMU's parameter A[1]) and tune on the
    StateSpace plant from the command line."""
    (tmp_path / "StateSpace.fmu").write_bytes((fmus / "StateSpace.fmu").read_bytes())
    rig = write_rig(tmp_path, STATE_SPACE_RIG)
    study = {
        "name": "fmu_p",
        "rig": str(rig),
        "scenarios": ["step"],
        "controller": "p_k10",
        "baseline": "p_k10",
        "parameters": {"gain": {"low": 1.0, "high": 20.0, "log": True}},
        "objective": {"weights": {"settling_time_s": 1.0, "sse_abs": 10.0}},
        "uncertainty": {
            "samples": 3,
            "seed": 2,
            "parameters": {"A[1]": {"uniform": [-3, -1], "unit": "1"}},
        },
        "seed": 1,
        "trials": 3,
    }
    study_path = tmp_path / "study.yaml"
    study_path.write_text(yaml.safe_dump(study, sort_keys=False), encoding="utf-8")

    def cli(*args: str) -> str:
        return run_cli(tmp_path, *args)

    assert "p_k10" in cli("compare", str(rig), "p_k10", "--out", "cmp")
    assert "gain margin" in cli("margins", str(rig), "p_k10").lower()
    robust = cli("robustness", str(rig), "p_k10", "--uncertainty", str(study_path),
                 "--samples", "3", "--out", "rob")  # fmt: skip
    assert "A[1]" in robust or "3" in robust
    cli("tune", str(study_path), "--out", "tune", "--trials", "3")
    assert (tmp_path / "tune" / "summary.json").is_file()


@pytest.mark.slow
def test_calibrate_fits_an_fmu_parameter_with_an_interval(fmus, tmp_path):
    """A record of the plant with A[1] = -1.4 (2 mV sensor noise); the rig declares A[1]
    unknown in [-4, -0.5] from -2. Calibration fits it, its 95 % interval holds the truth,
    and effects inside the black box are reported as not applicable, not tried."""
    from fuzzyservo.calibration.synthetic import synthetic_run

    (tmp_path / "StateSpace.fmu").write_bytes((fmus / "StateSpace.fmu").read_bytes())
    data = json.loads(json.dumps(STATE_SPACE_RIG))
    data["feedback"].update(noise={"value": 2, "unit": "mV"})
    truth = json.loads(json.dumps(data))
    truth["plant"]["parameters"]["A[1]"]["value"] = -1.4
    data["plant"]["parameters"]["A[1]"]["fit"] = [-4, -0.5]
    rig = fs.load_rig(write_rig(tmp_path, data))
    assert rig.plant.states[0] == "x1" and rig.unknowns == {"A_1": (-4.0, -0.5)}
    p_k10 = fs.load_controller("p_k10")
    record = synthetic_run(fs.load_rig(write_rig(tmp_path, truth, "truth.yaml")), p_k10, None,
                           {}, {"x1": 0.002}, seed=3)  # fmt: skip
    result = fs.calibrate(rig, record, p_k10, effects=["coulomb_friction", "valve_bias"],
                          max_effects=1)  # fmt: skip
    summary = result.to_dict()
    fitted = summary["uncertainty"]["A[1]"]
    assert fitted["interval"][0] <= -1.4 <= fitted["interval"][1]
    assert fitted["value"] == pytest.approx(-1.4, abs=0.02)
    assert summary["fit_after_pct"]["x1"] > 90
    skipped = json.dumps(summary["skipped_effects"])
    assert "coulomb_friction" in skipped and "not applicable" in skipped
