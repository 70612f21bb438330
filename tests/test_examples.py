"""The example files of ``examples/`` are what ``examples/make_examples.py`` writes, and
they do what its docstring says (issue 31)."""

from __future__ import annotations

import csv
import json
import runpy
from pathlib import Path

import numpy as np
import pytest

from fuzzyservo.cli import main

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
GENERATED = ("pd_valve_inputs.csv", "valve_hydroprax.csv", "run_dinca_friction.csv")


def _table(path: Path) -> tuple[list[str], np.ndarray]:
    with path.open(encoding="utf-8", newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], np.array(rows[1:], dtype=float)


@pytest.mark.slow
def test_the_script_regenerates_the_shipped_examples(tmp_path: Path, dinca, p_k10) -> None:
    """Same header and rows. The input table and the valve data are computed without
    feedback, so they agree to the last written digit (10 significant: rtol 1e-9). The
    friction run agrees to the bit whatever code numba, numpy and OpenBLAS pick for the
    CPU (tried: AVX-512, AVX2 and generic x86-64), but a CPU without FMA gets glibc's
    other exp/pow/tanh, a last bit apart now and then, and this is a stick-slip record:
    a change in the last bit of anything moves where the piston sticks by up to one step
    of the 16-bit position converter (15.8 µm) and the command by that step times the
    loop gain (0.0305 mA); a stuck piston's chamber pressures are fixed only within the
    friction band (300 N / 7.07 cm² = 4.2 bar). Measured over eight one-bit changes (the
    friction force ±1-5 ULP, glibc without FMA): position RMS 1.4-1.7 µm, at most
    14.6 µm; current at most one step; pressures at most 0.67 bar. 5 % more friction
    gives 13 µm RMS, 97 µm, 6 steps. So the run is held to what the loop resolves:
    position RMS difference below the file's position noise (5 µm), at most two steps of
    position and of current, pressures within 1.5 bar (a third of the friction band);
    time and reference to the written digit. What the record is for, the calibration
    finding 300 N of Coulomb friction, is the next test."""
    make = runpy.run_path(str(EXAMPLES / "make_examples.py"))
    assert make["main"](["--out", str(tmp_path)]) == 0
    tables = {}
    for name in GENERATED:
        (header, rows), (shipped_header, shipped) = _table(tmp_path / name), _table(EXAMPLES / name)
        assert header == shipped_header and rows.shape == shipped.shape, name
        tables[name] = (
            dict(zip(header, rows.T, strict=True)),
            dict(zip(header, shipped.T, strict=True)),
        )
        if name != "run_dinca_friction.csv":
            np.testing.assert_allclose(rows, shipped, rtol=1e-9, atol=1e-12, err_msg=name)
    run, ship = tables["run_dinca_friction.csv"]
    for key in ("t_s", "ref_cm"):
        np.testing.assert_allclose(run[key], ship[key], rtol=1e-9, atol=1e-12, err_msg=key)
    fb = dinca.feedback
    y_step_cm = fb.adc_step / fb.slope * 100  # the converter's step in position
    i_step_ma = dinca.actuator.gain * p_k10.gain * fb.adc_step * 1e3  # ... in the command
    dy, di = run["y_cm"] - ship["y_cm"], run["i_mA"] - ship["i_mA"]
    assert np.sqrt(np.mean(dy**2)) < 5e-4  # cm: the position noise written into the file
    assert np.abs(dy).max() < 2 * y_step_cm
    assert np.abs(di).max() < 2 * i_step_ma + 1e-6
    for key in ("p_a_bar", "p_b_bar"):
        assert np.abs(run[key] - ship[key]).max() < 1.5, key


def test_the_example_fis_evaluates_its_inputs(tmp_path: Path) -> None:
    out = tmp_path / "u.csv"
    code = main(
        ["evaluate", str(EXAMPLES / "pd_valve.fis"), str(EXAMPLES / "pd_valve_inputs.csv"),
         "--out", str(out)]
    )  # fmt: skip
    assert code == 0
    (header, inputs), (names, u) = _table(EXAMPLES / "pd_valve_inputs.csv"), _table(out)
    assert header == ["e", "de"] and names == ["u"]
    assert u.shape == (len(inputs), 1)
    # an odd PD table: zero at the origin, odd in (e, de), saturating toward ±10
    np.testing.assert_allclose(u[:, 0], -u[::-1, 0], atol=1e-9)
    assert abs(u[len(u) // 2, 0]) < 1e-9 and -10 < u.min() < -5 and 5 < u.max() < 10


@pytest.mark.slow
def test_calibration_names_the_effect_hidden_in_the_example_run(tmp_path: Path) -> None:
    summary = tmp_path / "summary.json"
    code = main(
        ["calibrate", "dinca_cylinder", str(EXAMPLES / "run_dinca_friction.csv"),
         "--controller", "p_k10", "--effects", "coulomb_friction,valve_bias",
         "--max-effects", "1", "--workers", "1", "--out", str(tmp_path / "cal"),
         "--json", str(summary)]
    )  # fmt: skip
    assert code == 0
    result = json.loads(summary.read_text(encoding="utf-8"))
    added = result["effects_added"]
    assert [e["name"] for e in added] == ["coulomb_friction"]
    assert added[0]["params"]["force"] == pytest.approx(300.0, rel=0.1)  # declared: 300 N
    # friction fitted through the quantised loop on a record that has its current: the
    # user is told the interval may not hold, and how to fit it where it does
    (loop,) = [w for w in result["warnings"] if "through the controller" in w]
    assert loop.startswith("coulomb_friction was fitted through the controller")
    assert "has the valve current i: leave out --controller" in loop
