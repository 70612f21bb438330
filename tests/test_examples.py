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
def test_the_script_regenerates_the_shipped_examples(tmp_path: Path) -> None:
    """Same header, same rows (to 1e-7 relative: the compiled loop's last digits may
    differ between machines)."""
    make = runpy.run_path(str(EXAMPLES / "make_examples.py"))
    assert make["main"](["--out", str(tmp_path)]) == 0
    for name in GENERATED:
        header, rows = _table(tmp_path / name)
        shipped_header, shipped = _table(EXAMPLES / name)
        assert header == shipped_header, name
        np.testing.assert_allclose(rows, shipped, rtol=1e-7, atol=1e-9, err_msg=name)


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
    added = json.loads(summary.read_text(encoding="utf-8"))["effects_added"]
    assert [e["name"] for e in added] == ["coulomb_friction"]
    assert added[0]["params"]["force"] == pytest.approx(300.0, rel=0.1)  # declared: 300 N
