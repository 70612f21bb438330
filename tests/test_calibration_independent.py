"""Calibration on data from formulations the library did not write (issue 12, item 5).

``tests/independent_rig.py`` regenerates seed 002 under P K=10 with scipy's solve_ivp and
its own effect formulations (LuGre friction with pressure-dependent seal friction,
turbulent line loss, a 4.3 ms delay that is not a whole number of samples, a
second-order spool, a pump with a relief valve …) at the middle of docs/modelling.md's
typical ranges. ``calibrate`` gets the nominal seed-002 rig and the CSV-like record.

Measured (README, "Formulations the library did not write"): 8 of 10 named first and
added. The two misses are marked xfail with what was seen.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from independent_rig import MIDDLE, independent_run
from support import controller_named
from test_calibration import NOISE, old_loop

from fuzzyservo.calibration.replay import make_replay
from fuzzyservo.calibration.search import calibrate
from fuzzyservo.io.rigs import load_rig

MISSES = {
    "internal_leakage": "1e-13 m³/(s·Pa) stays below what the 40 % formulation mismatch "
    "(held-out cost 1.36 with nothing added) lets the test see",
    "bulk_modulus": "the generator's pressure form differs from the library's mass form by "
    "p/E (1.5 % at 0.45 GPa): a lower E fits the pressures but not the position",
}


@pytest.mark.slow
@pytest.mark.parametrize(
    "effect",
    [
        pytest.param(e, marks=pytest.mark.xfail(reason=MISSES[e], strict=False))
        if e in MISSES
        else e
        for e in MIDDLE
    ],
)
def test_independent_formulation_is_named_first_and_added(tmp_path: Path, effect: str) -> None:
    rig = load_rig(old_loop(tmp_path))
    ctl = controller_named("p_k10")
    data = independent_run(effect, NOISE, seed=11)
    outcome = calibrate(make_replay(rig, data, ctl), rig)
    assert outcome.rounds[0].candidates[0].name == effect
    assert [c.name for c in outcome.added][:1] == [effect]


@pytest.mark.slow
def test_independent_null_run_adds_nothing(tmp_path: Path) -> None:
    rig = load_rig(old_loop(tmp_path))
    ctl = controller_named("p_k10")
    data = independent_run(None, NOISE, seed=11)
    assert calibrate(make_replay(rig, data, ctl), rig).added == ()
