"""How small an effect calibration finds, and how often it adds one that is not there.

Both are measured, not assumed: synthetic runs of a rig (:mod:`.synthetic`) with the
effect at a ladder of sizes, each over several noise draws.

* **false-positive rate**: the full calibration on runs without any effect; the share
  of draws in which an effect is added (decision.py promises at most ``ALPHA``).
* **detection limit**: for each effect, the smallest size at which the effect's own
  candidate is added by the first round's rule (null.py: the test at the threshold of
  the full library and of the record's bootstrap, and a contribution that matters) in
  at least ``REQUIRED`` of the draws.
  Only the true effect is fitted (a whole library per draw would take hours); whether
  it is also ranked first is checked by the tests at the typical sizes.

``tests/detection_limits.py`` prints the seed-002 table of docs/calibration.md.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

from fuzzyservo.calibration.candidates import candidate_effects, fit
from fuzzyservo.calibration.decision import held_out_evidence
from fuzzyservo.calibration.null import assess, null_round
from fuzzyservo.calibration.replay import make_replay
from fuzzyservo.calibration.search import search_effects
from fuzzyservo.calibration.synthetic import synthetic_run
from fuzzyservo.controllers.base import Controller
from fuzzyservo.rig import Rig

REQUIRED = 0.9  # share of draws in which an effect must be found


@dataclass(frozen=True)
class Detection:
    """One effect at one size: how many of ``draws`` runs found it."""

    effect: str
    params: dict[str, float]
    found: int
    draws: int

    @property
    def rate(self) -> float:
        return self.found / self.draws if self.draws else 0.0


def false_positive_rate(
    rig: Rig,
    controller: Controller,
    scenario: str,
    noise: Mapping[str, float],
    draws: int,
    *,
    first_seed: int = 1000,
    progress: Callable[[str], None] | None = None,
) -> tuple[int, list[list[str]]]:
    """Full calibrations on ``draws`` runs without an effect: (runs that added one, what
    each run added)."""
    added = []
    for k in range(draws):
        data = synthetic_run(rig, controller, scenario, {}, noise, seed=first_seed + k)
        outcome = search_effects(make_replay(rig, data, controller), rig)
        added.append([c.name for c in outcome.added])
        if progress:
            progress(f"null draw {k + 1}/{draws}: added {added[-1] or 'none'}")
    return sum(1 for a in added if a), added


def detected(
    rig: Rig,
    controller: Controller,
    scenario: str,
    effect: str,
    params: Mapping[str, float],
    noise: Mapping[str, float],
    seed: int,
) -> bool:
    """Whether ``effect`` at ``params`` passes the first-round test on one noisy run."""
    data = synthetic_run(rig, controller, scenario, {effect: params}, noise, seed=seed)
    replay = make_replay(rig, data, controller)
    nominal, _ = replay.run(rig)
    _, candidate = fit(replay, rig, effect)
    z = held_out_evidence(replay, nominal, candidate.model).z
    null = null_round(replay, nominal, [candidate.model], candidates=len(candidate_effects(rig)))
    return assess(replay, nominal, candidate.model, effect, z, null).verdict == "added"


def detection_ladder(
    rig: Rig,
    controller: Controller,
    scenario: str,
    effect: str,
    sizes: Sequence[Mapping[str, float]],
    noise: Mapping[str, float],
    draws: int,
    *,
    first_seed: int = 0,
    progress: Callable[[str], None] | None = None,
) -> list[Detection]:
    """``effect`` at each of ``sizes`` (largest first) over ``draws`` runs; stops after
    the first size found in fewer than ``REQUIRED`` of the draws."""
    out = []
    for params in sizes:
        found = sum(
            detected(rig, controller, scenario, effect, params, noise, first_seed + k)
            for k in range(draws)
        )
        out.append(Detection(effect, dict(params), found, draws))
        if progress:
            progress(f"{effect} {dict(params)}: found in {found}/{draws}")
        if found < REQUIRED * draws:
            break
    return out


def limit(ladder: Sequence[Detection]) -> Detection | None:
    """The smallest size of a ladder found in at least ``REQUIRED`` of the draws."""
    found = [d for d in ladder if d.rate >= REQUIRED]
    return found[-1] if found else None


def _ladder(base: Mapping[str, float], factors: Sequence[float]) -> list[dict[str, float]]:
    return [{k: v * f for k, v in base.items()} for f in factors]


QUARTERS = tuple(4.0**-k for k in range(8))  # 1, 1/4 … 1/16384
# Seed 002, P K=10, pulses: the tests' typical sizes (tests/test_calibration.py), quartered
# down the ladder. Bulk modulus and pump flow grow towards "no effect" instead.
SEED002_LADDERS: dict[str, list[dict[str, float]]] = {
    "coulomb_friction": _ladder({"force": 300.0}, QUARTERS),
    "stribeck_friction": [
        {"coulomb_force": 200.0 * f, "stiction_force": 100.0 * f, "stribeck_velocity": 5e-3}
        for f in QUARTERS
    ],
    "line_resistance": _ladder({"resistance": 2e10}, QUARTERS),
    "internal_leakage": _ladder({"coefficient": 1e-12}, QUARTERS),
    "valve_deadband": _ladder({"width": 0.5e-3}, QUARTERS),
    "valve_bias": _ladder({"offset": 0.5e-3}, QUARTERS),
    "valve_lag": _ladder({"time_constant": 3e-3}, QUARTERS),
    "transport_delay": _ladder({"delay": 0.015}, QUARTERS),
    "bulk_modulus": [{"effective": e} for e in (0.6e9, 1.2e9, 1.5e9, 1.65e9, 1.72e9, 1.76e9)],
    "supply_droop": [{"pump_flow": q} for q in (1.0e-4, 1.25e-4, 1.5e-4, 1.75e-4, 2.0e-4)],
}
