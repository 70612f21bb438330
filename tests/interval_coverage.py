"""Coverage of the 95 % intervals calibration reports for a fitted effect (issue 40):
how often the interval holds the value the record was made with.

Each draw is a run of the shipped seed-002 rig (``rigs/dinca_cylinder.yaml``) under
P K=10 on ``pulses`` with one library effect switched on, at the middle of its typical
range (tests/independent_rig.py's MIDDLE, mapped to this library's parameters) times a
factor drawn uniformly in 0.8-1.2 for each parameter (a physical difference between
draws, not only the noise), recorded with the example's noise (5 µm position, 0.05 bar
pressures) from a seed of its own. The effect is fitted on the closed-loop replay
(candidates.fit) and its intervals computed as the final calibration computes them
(intervals.fitted_intervals with the fitted candidate added). Prints each draw and the table
docs/calibration.md shows ("Coverage of the 95 % intervals").

Run from the repository root (a few seconds per draw; one process at a time on a shared
machine, niced):

    PYTHONPATH=. nice python tests/interval_coverage.py [draws=50] [effect ...] [--from-truth]
        [--in-loop] [--open-loop]

An effect may name a variant of :data:`VARIANTS` (``valve_lag:second_order``).

``--from-truth`` refines each fit from the true values instead of searching: the
intervals' coverage apart from a search that ends in the wrong valley. ``--in-loop``:
the rig's own feedback noise (1 mV, about 52 µm) is in the loop, as on a rig, and the
record's position is what the controller read (synthetic_run's ``in_loop``); the
pressures keep their recorded noise. ``--open-loop``: the record is replayed from its
valve current, not through the controller.
"""

from __future__ import annotations

import math
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from support import controller_named, rig_named

from fuzzyservo.calibration import candidates, intervals
from fuzzyservo.calibration.replay import Replay, make_replay
from fuzzyservo.calibration.synthetic import synthetic_run
from fuzzyservo.calibration.uncertainty import Estimate
from fuzzyservo.components.effects import LIBRARY
from fuzzyservo.rig import Rig

NOISE = {"y": 5e-6, "p_a": 0.05e5, "p_b": 0.05e5}  # as examples/make_examples.py
SPREAD = 0.2  # each draw's size: the middle times a factor uniform in 1 ± SPREAD
SEED = 4000  # noise seed of draw k of the effect with library index i: SEED + 100·i + k


def middle(rig: Rig) -> dict[str, dict[str, float]]:
    """Each screened effect at the middle of its typical range (tests/independent_rig.py
    MIDDLE, in this library's parameters; a share of the rig's stall force or rated
    current where MIDDLE gives one)."""
    s = rig.scales()
    return {
        "coulomb_friction": {"force": 0.035 * s.force},  # MIDDLE: ~170 N, 3.5 %
        "stribeck_friction": {  # MIDDLE: Fc 150 N, breakaway 225 N, vs 5 mm/s, LuGre
            "coulomb_force": 150.0,  # bristles of 1e7 N/m: 22.5 µm at breakaway
            "stiction_force": 75.0,
            "stribeck_velocity": 5e-3,
            "presliding_distance": 22.5e-6,
        },
        "line_resistance": {"resistance": 2e10},  # 2 bar at 10 cm³/s
        "internal_leakage": {"coefficient": 1e-13},  # geometric middle of 1e-14..1e-12
        "valve_deadband": {"width": 0.017 * s.input},  # 1.7 % of rated current
        "valve_bias": {"offset": 0.015 * s.input},  # 1.5 % of rated current
        # a 100 Hz spool of damping 0.7: τ1 = 2ζ/ωn, τ2 = τ1/(4ζ²)
        "valve_lag": {"time_constant": 2e-3, "second_time_constant": 0.0},  # first order
        "transport_delay": {"delay": 4.3e-3},
        "bulk_modulus": {"effective": 0.45e9},
        "supply_droop": {"pump_flow": 1e-4},
        "external_leakage": {"coefficient": 1e-13},  # as internal leakage's middle
    }


# other truths for an effect, measured as rows of their own: "<effect>:<variant>"
VARIANTS = {
    # tests/independent_rig.py's Coulomb friction: LuGre bristles of 1e7 N/m at ~170 N
    "coulomb_friction:lugre": {"force": 170.0, "presliding_distance": 17e-6},
    # tests/independent_rig.py's spool, 100 Hz at ζ 0.7: τ1 = 2ζ/ωn, τ2 = τ1/(4ζ²)
    "valve_lag:second_order": {"time_constant": 2.228e-3, "second_time_constant": 1.137e-3},
    "stribeck_friction:static": {  # the tanh law, which creeps (no pre-sliding distance)
        "coulomb_force": 150.0, "stiction_force": 75.0, "stribeck_velocity": 5e-3,
        "presliding_distance": 0.0,
    },
}  # fmt: skip


def effects() -> tuple[str, ...]:
    """The library's screened effects, in its order."""
    return tuple(name for name, e in LIBRARY.items() if e.screened)


def replayed(
    rig: Rig, effect: str, k: int, *, in_loop: bool = False, open_loop: bool = False
) -> tuple[dict[str, float], Replay]:
    """Draw ``k``'s true parameters of ``effect`` (a variant: ``effect:variant``; key ->
    SI) and the replay of its record, a run under P K=10 on ``pulses``: through the
    controller, or (``open_loop``) from the recorded valve current."""
    effect, variant = effect.partition(":")[::2]
    # a variant's draws take the second half of its effect's seeds (≤ 50 draws each)
    seed = SEED + 100 * list(LIBRARY).index(effect) + (50 if variant else 0) + k
    rng = np.random.default_rng(seed)
    size = VARIANTS[f"{effect}:{variant}"] if variant else middle(rig)[effect]
    truth = {key: v * rng.uniform(1.0 - SPREAD, 1.0 + SPREAD) for key, v in size.items()}
    for param in LIBRARY[effect].fitted:  # an optional part the record leaves off
        if param.optional:
            truth.setdefault(param.key, 0.0)
    controller = controller_named("p_k10")
    data = synthetic_run(rig, controller, "pulses", {effect: truth}, NOISE, seed=seed,
                         in_loop=in_loop)  # fmt: skip
    return truth, make_replay(rig, data, None if open_loop else controller)


def draw(
    rig: Rig,
    effect: str,
    k: int,
    *,
    from_truth: bool = False,
    in_loop: bool = False,
    open_loop: bool = False,
) -> tuple[dict[str, float], dict[str, Estimate]]:
    """Draw ``k`` of ``effect``: its true parameters (key -> SI) and the fitted
    parameters' estimates (key -> Estimate). ``from_truth``: the fit refines from the
    true values (no global search), which measures the intervals apart from the search."""
    truth, replay = replayed(rig, effect, k, in_loop=in_loop, open_loop=open_loop)
    effect = effect.partition(":")[0]
    start = None
    if from_truth:  # a candidate at the truth (nothing to fit) to start from
        _, start = candidates.fit(replay, rig.with_effect(effect, **truth), None)
    fitted, candidate = candidates.fit(replay, rig, effect, start_from=start)
    found = intervals.fitted_intervals(replay, fitted, [candidate], candidate.model)
    keys = {p.field: p.key for p in LIBRARY[effect].fitted}
    return truth, {keys[f]: e for f, e in found.items() if f in keys}


def covers(estimate: Estimate, truth: float) -> bool:
    return estimate.interval[0] <= truth <= estimate.interval[1]


def coverage(
    rig: Rig,
    effect: str,
    draws: int,
    *,
    from_truth: bool = False,
    in_loop: bool = False,
    open_loop: bool = False,
    log=print,
) -> list[tuple[str, int, int, float]]:
    """(parameter, draws, covered, median half-width / truth) of each fitted parameter."""
    hits: dict[str, list[bool]] = {}
    widths: dict[str, list[float]] = {}
    for k in range(draws):
        start = time.perf_counter()
        truth, found = draw(rig, effect, k, from_truth=from_truth, in_loop=in_loop,
                            open_loop=open_loop)  # fmt: skip
        words = []
        for key, est in found.items():
            hits.setdefault(key, []).append(covers(est, truth[key]))
            half = 0.5 * (est.interval[1] - est.interval[0])
            widths.setdefault(key, []).append(half / abs(truth[key]) if truth[key] else half)
            words.append(
                f"{key} true {truth[key]:.4g} fit {est.value:.4g} "
                f"[{est.interval[0]:.4g}, {est.interval[1]:.4g}]"
                f"{'' if hits[key][-1] else ' MISSED'}"
            )
        log(f"{effect} {k + 1}/{draws}: {'; '.join(words)} ({time.perf_counter() - start:.1f} s)")
    return [
        (f"{effect}.{key}", len(h), sum(h), statistics.median(widths[key]))
        for key, h in hits.items()
    ]


def main(
    draws: int = 50,
    names: tuple[str, ...] = (),
    *,
    from_truth: bool = False,
    in_loop: bool = False,
    open_loop: bool = False,
) -> None:
    rig = rig_named("dinca_cylinder")
    rows = []
    for effect in names or effects():
        rows += coverage(rig, effect, draws, from_truth=from_truth, in_loop=in_loop,
                         open_loop=open_loop, log=lambda line: print(line, flush=True))  # fmt: skip
    print("\n| effect parameter | draws | covered | median half-width / truth |")
    print("|---|---|---|---|")
    for name, n, hit, width in rows:
        share = f"{hit} ({100 * hit / n:.0f} %)"
        print(f"| {name} | {n} | {share} | {width:.2g} |" if math.isfinite(width) else
              f"| {name} | {n} | {share} | whole bounds |")  # fmt: skip


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    main(int(args[0]) if args else 50, tuple(args[1:]), from_truth="--from-truth" in sys.argv,
         in_loop="--in-loop" in sys.argv, open_loop="--open-loop" in sys.argv)  # fmt: skip
