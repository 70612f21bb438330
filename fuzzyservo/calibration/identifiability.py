"""Which experiment would tell apart effects the data cannot (issue 12, docs/modelling.md
"Identifiability").

Two effects that change the residual in the same way on one experiment cannot be told
apart on it (cross-port leakage and a valve null shift under no-load position steps
both shift the holding current). Each tied candidate, with the values it was fitted
to, is simulated on a few other excitations built from the recorded one: the same
reference at other positions, under a load, and a sine sweep. The excitations are
ranked by the predicted difference between the candidates in noise units,
``D = Σ_c Σ_t ((ŷ_a − ŷ_b)/σ_c)²`` (the expected log-likelihood ratio of the right
model over the wrong one is ``D/2``); the one with the largest smallest-pairwise ``D``
separates them best.
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from fuzzyservo.calibration.replay import Replay
from fuzzyservo.rig import Rig, Scenario
from fuzzyservo.signals import Constant, Sampled

LOAD_SHARE = 0.2  # load of the "under a load" excitation, share of the stall force
SWEEP_HZ = (0.1, 5.0)  # sine sweep from, to [Hz]


@dataclass(frozen=True)
class Separation:
    """One excitation and how far apart it drives the tied candidates.

    ``distance``: the smallest over candidate pairs of ``D`` (noise units, see the
    module); ``by_pair``: ``"a vs b"`` -> ``D``.
    """

    name: str
    description: str
    distance: float
    by_pair: dict[str, float]
    scenario: Scenario = dataclasses.field(repr=False, compare=False)


def excitations(replay: Replay, rig: Rig) -> list[Scenario]:
    """The recorded experiment and variations of it that load the rig differently."""
    base = replay.scenario
    t = replay.t
    ref = np.asarray(base.reference.sample(t), dtype=float)
    span = float(np.ptp(ref)) or max(abs(float(np.mean(ref))) * 0.1, 1e-3)
    mean = float(np.mean(ref))
    force = rig.scales().force
    chirp_rate = (SWEEP_HZ[1] - SWEEP_HZ[0]) / max(t[-1], 1e-9)
    phase = 2.0 * np.pi * (SWEEP_HZ[0] * t + 0.5 * chirp_rate * t**2)
    sweep = mean + 0.5 * span * np.sin(phase)

    def variant(name: str, description: str, **changes) -> Scenario:
        return dataclasses.replace(base, name=name, description=description, **changes)

    def shifted(offset: float) -> Sampled:
        return Sampled(times_s=t, values=ref + offset)

    return [
        variant("recorded", "the recorded experiment again"),
        variant(
            "positions_up",
            f"the recorded reference shifted up by half its span ({0.5 * span:+.3g} in "
            "feedback units): steps at other positions",
            reference=shifted(0.5 * span),
        ),
        variant(
            "positions_down",
            f"the recorded reference shifted down by half its span ({-0.5 * span:+.3g})",
            reference=shifted(-0.5 * span),
        ),
        variant(
            "load_push",
            f"the recorded reference under a constant load of {LOAD_SHARE * force:.3g} "
            f"({LOAD_SHARE:.0%} of the stall force)",
            load=Constant(LOAD_SHARE * force),
        ),
        variant(
            "load_pull",
            f"the recorded reference under a constant load of {-LOAD_SHARE * force:.3g}",
            load=Constant(-LOAD_SHARE * force),
        ),
        variant(
            "sine_sweep",
            f"a sine sweep {SWEEP_HZ[0]:g}-{SWEEP_HZ[1]:g} Hz of half the recorded span "
            "around its mean",
            reference=Sampled(times_s=t, values=sweep),
        ),
    ]


def _channels(replay: Replay, rig: Rig, scenario: Scenario) -> dict[str, np.ndarray] | None:
    replay_rig = dataclasses.replace(rig, sample_time_s=replay.sample_time_s, initial={})
    from fuzzyservo.simulation import simulate

    result = simulate(replay_rig, replay.controller, scenario)
    out = {}
    for channel, signal in replay.channels.items():
        values = np.interp(replay.t, result.t, result.signals[signal])
        if not np.isfinite(values).all():
            return None
        out[channel] = values
    return out


def separating_experiments(replay: Replay, rigs: Mapping[str, Rig]) -> list[Separation]:
    """Excitations ranked by how far apart they drive the candidate ``rigs`` (name ->
    the rig with that candidate fitted), best first."""
    out = []
    for scenario in excitations(replay, next(iter(rigs.values()))):
        runs = {name: _channels(replay, rig, scenario) for name, rig in rigs.items()}
        by_pair = {}
        for a, b in itertools.combinations(rigs, 2):
            if runs[a] is None or runs[b] is None:
                by_pair[f"{a} vs {b}"] = float("nan")
                continue
            by_pair[f"{a} vs {b}"] = float(
                sum(
                    np.sum(((runs[a][c] - runs[b][c]) / replay.sigma[c]) ** 2)
                    for c in replay.channels
                )
            )
        finite = [d for d in by_pair.values() if np.isfinite(d)]
        distance = min(finite) if len(finite) == len(by_pair) else float("nan")
        out.append(Separation(scenario.name, scenario.description, distance, by_pair, scenario))
    out.sort(key=lambda s: -s.distance if np.isfinite(s.distance) else np.inf)
    return out
