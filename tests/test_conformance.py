"""fuzzylite's example systems (../shared/conformance/fuzzylite/, GPL-3.0, read in place).

Every ``.fis`` there that is a type-1 Mamdani or Sugeno system in MATLAB's format loads;
each one with a ``.fld`` table beside it (fuzzylite 6's outputs) agrees with it within
1e-3 of the output range in the ``matlab`` semantics with the output sampled finely
(1001 points: fuzzylite integrates on 200 points, so its own values are off the
continuous answer by up to about 1e-4 of the range, SOURCE.md). A Sugeno output's
declared range does not bound it (invkine1.fis reaches 300 times its range); there the
tolerance is 1e-3 of the span the reference values cover when that is wider. What does
not load is listed with the reason. ``python tests/test_conformance.py`` prints the
table in docs/interop.md (Conformance).
"""

from __future__ import annotations

import dataclasses
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from fuzzyservo.controllers.fuzzy.evaluate import evaluate_inputs
from fuzzyservo.errors import ConfigError, FileWarning
from fuzzyservo.io.fuzzy_files import read_fis

FOLDER = Path(__file__).resolve().parents[2] / "shared" / "conformance" / "fuzzylite" / "examples"
TOLERANCE = 1e-3
FINE_POINTS = 1001

#: what does not load, and why (everything else must load)
NOT_LOADED = {
    "hybrid/ObstacleAvoidance.fis": "type 'hybrid' (fuzzylite: Mamdani and Sugeno outputs mixed)",
    "hybrid/tipper.fis": "type 'hybrid' (fuzzylite: Mamdani and Sugeno outputs mixed)",
    "tsukamoto/tsukamoto.fis": "type 'tsukamoto' (fuzzylite only)",
    "original/tsukamoto/tsukamoto.fis": "fuzzylite's own keys (Enabled, Lock…): not MATLAB's format",
    "mamdani/AllTerms.fis": "fuzzylite-only shapes (rampmf, concavemf, cosinemf …)",
    "original/mamdani/AllTerms.fis": "fuzzylite-only shapes (rampmf, concavemf, cosinemf …)",
    "mamdani/Laundry.fis": "fuzzylite-only shape discretemf",
    "mamdani/ObstacleAvoidance.fis": "fuzzylite-only shape rampmf",
    "takagi-sugeno/ObstacleAvoidance.fis": "fuzzylite-only shape rampmf",
    "mamdani/SimpleDimmerChained.fis": "fuzzylite-only shape cosinemf",
    "mamdani/SimpleDimmerInverse.fis": "fuzzylite-only shape cosinemf",
    "takagi-sugeno/approximation.fis": "fuzzylite-only output term 'function'",
    "original/takagi-sugeno/approximation.fis": "fuzzylite's own keys (Enabled, Lock…): not MATLAB's format",
    "original/takagi-sugeno/SimpleDimmer.fis": "fuzzylite's own keys (Enabled, Lock…): not MATLAB's format",
    "original/mamdani/SimpleDimmer.fis": "fuzzylite's own keys (Default, Lock…): not MATLAB's format",
    "mamdani/octave/investment_portfolio.fis": "fuzzylite/Octave-only operator einstein_product",
    "original/mamdani/octave/investment_portfolio.fis": "fuzzylite/Octave-only operator einstein_product",
    "takagi-sugeno/octave/sugeno_tip_calculator.fis": "fuzzylite/Octave-only operator einstein_product",
    "original/takagi-sugeno/octave/sugeno_tip_calculator.fis": "fuzzylite/Octave-only operator einstein_product",
}
#: the MATLAB demos: systems MATLAB's evalfis computes (evalfis-mode figures)
MATLAB_DEMOS = ("mamdani/matlab/", "takagi-sugeno/matlab/")

pytestmark = pytest.mark.skipif(
    not FOLDER.is_dir(), reason=f"conformance data absent ({FOLDER}); see ../shared"
)


def fis_files() -> list[str]:
    return sorted(p.relative_to(FOLDER).as_posix() for p in FOLDER.rglob("*.fis"))


def deviation(rel: str, semantics: str, sample_points: int) -> tuple[float, int]:
    """Largest |ours − fuzzylite| over the file's own .fld, as a fraction of the output
    range (or of the reference span, when wider); and the rows fuzzylite left NaN."""
    system = read_fis(FOLDER / rel)
    system = dataclasses.replace(system, semantics=semantics, sample_points=sample_points)
    data = np.loadtxt((FOLDER / rel).with_suffix(".fld"), skiprows=1, ndmin=2)
    n_in = len(system.inputs)
    ours, _ = evaluate_inputs(system, data[:, :n_in])
    ref = data[:, n_in:]
    worst = 0.0
    for o, var in enumerate(system.outputs):
        col = ref[:, o]
        ok = ~np.isnan(col)
        span = max(var.high - var.low, np.ptp(col[ok]) if ok.any() else 0.0)
        worst = max(worst, float(np.max(np.abs(ours[ok, o] - col[ok]))) / span)
    return worst, int(np.isnan(ref).sum())


def survey() -> dict[str, dict]:
    rows = {}
    for rel in fis_files():
        row: dict = {"has_fld": (FOLDER / rel).with_suffix(".fld").is_file()}
        try:
            with warnings.catch_warnings():  # slcp1's MF2 read as MF3: its own test
                warnings.simplefilter("ignore", FileWarning)
                read_fis(FOLDER / rel)
        except ConfigError as exc:
            row["error"] = str(exc)
        else:
            if row["has_fld"]:
                row["fine"], row["nan"] = deviation(rel, "matlab", FINE_POINTS)
                if rel.startswith(MATLAB_DEMOS):
                    row["evalfis"], _ = deviation(rel, "matlab", 101)
        rows[rel] = row
    return rows


@pytest.fixture(scope="module")
def rows() -> dict[str, dict]:
    return survey()


def test_every_matlab_type1_system_loads(rows):
    failed = {rel: r["error"] for rel, r in rows.items() if "error" in r}
    assert set(failed) == set(NOT_LOADED), failed
    assert len(rows) == 72


def test_every_loaded_system_agrees_with_its_fld(rows):
    off = {rel: r["fine"] for rel, r in rows.items() if r.get("fine", 0.0) > TOLERANCE}
    assert not off, off
    assert sum("fine" in r for r in rows.values()) == 27


def test_matlab_demos_in_evalfis_mode(rows):
    """MATLAB samples the output at 101 points where fuzzylite integrates on 200: the
    demos differ by up to 4.2e-3 of the range (mam21, mam22: narrow clipped sets);
    Sugeno systems are not sampled and agree as in the fine mode."""
    demos = {rel: r["evalfis"] for rel, r in rows.items() if "evalfis" in r}
    assert len(demos) == 21
    assert max(demos.values()) < 5e-3
    sugeno = [v for rel, v in demos.items() if rel.startswith("takagi-sugeno")]
    assert max(sugeno) < TOLERANCE


def test_a_duplicated_mf_key_is_read_in_order_as_matlab_does():
    """MATLAB's own slcp1.fis gives ``MF2`` twice in [Input5]: MATLAB reads MF lines in
    order, so the second is MF3 ('large'); read so with a warning naming the line, it
    agrees with fuzzylite's re-export (which numbers it MF3) on the re-export's table."""
    original = FOLDER / "original/takagi-sugeno/matlab/slcp1.fis"
    with pytest.warns(FileWarning, match=r"\[Input5\]\.MF2 \(line 40\): read as MF3"):
        system = read_fis(original)
    assert [t.name for t in system.inputs[4].terms] == ["small", "medium", "large"]
    again = read_fis(FOLDER / "takagi-sugeno/matlab/slcp1.fis")
    data = np.loadtxt(FOLDER / "takagi-sugeno/matlab/slcp1.fld", skiprows=1, ndmin=2)
    n_in = len(system.inputs)
    ours, _ = evaluate_inputs(system, data[:, :n_in])
    theirs, _ = evaluate_inputs(again, data[:, :n_in])
    span = np.ptp(data[:, n_in:])
    # the re-export rounds the linear outputs' coefficients to three decimals
    assert np.max(np.abs(ours - theirs)) / span < TOLERANCE


def table(rows: dict[str, dict]) -> str:
    """The counts table of docs/interop.md and the per-file figures."""
    groups = {
        "MATLAB demos (`*/matlab/`)": lambda rel: "/matlab/" in rel,
        "Octave demos (`*/octave/`)": lambda rel: "/octave/" in rel,
        "fuzzylite's own examples": lambda rel: "/matlab/" not in rel and "/octave/" not in rel,
    }
    lines = [
        "| files | found | loaded | with a .fld | agree within 1e-3 | evalfis mode (101 points): largest deviation |",
        "|---|---|---|---|---|---|",
    ]
    for label, pick in groups.items():
        sel = {rel: r for rel, r in rows.items() if pick(rel)}
        fld = [r for r in sel.values() if "fine" in r]
        ev = [r["evalfis"] for r in sel.values() if "evalfis" in r]
        lines.append(
            f"| {label} | {len(sel)} | {sum('error' not in r for r in sel.values())} | "
            f"{len(fld)} | {sum(r['fine'] <= TOLERANCE for r in fld)} | "
            f"{f'{max(ev):.1e}' if ev else '–'} |"
        )
    lines.append(
        f"| **all** | {len(rows)} | {sum('error' not in r for r in rows.values())} | "
        f"{sum('fine' in r for r in rows.values())} | "
        f"{sum(r.get('fine', 1) <= TOLERANCE for r in rows.values())} | |"
    )
    lines += ["", "| file | fine (1001 points) | evalfis mode (101) |", "|---|---|---|"]
    for rel, r in rows.items():
        if "fine" in r:
            ev = f"{r['evalfis']:.1e}" if "evalfis" in r else ""
            lines.append(f"| {rel} | {r['fine']:.1e} | {ev} |")
    lines += ["", "Not loaded:", ""]
    lines += [
        f"- `{rel}`: {NOT_LOADED.get(rel, r['error'])}" for rel, r in rows.items() if "error" in r
    ]
    return "\n".join(lines)


if __name__ == "__main__":  # pragma: no cover
    if not FOLDER.is_dir():
        sys.exit(f"no conformance data at {FOLDER}")
    print(table(survey()))
