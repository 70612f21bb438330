"""A segmented replay: the record cut into segments, each started again from the state
the record shows at its start.

A replay of the whole record is an output-error model: a tiny change of a friction
moves when the piston sticks, and from then on the replay is in another place than the
record, for good (tests/replay_sensitivity.py measures it: a millionth more friction
moves the whole replay's cost by up to 1,800 % through the controller). Past the horizon
over which the loop is predictable, a cost built on the whole replay has no valley at
the truth. Restarting short segments from the measured state is the textbook remedy
(multiple shooting: Bock, 1981; MATLAB ``nlgreyest``'s prediction focus): each sample
is then predicted from a state at most one segment old, and a parameter's change moves
the cost as far as one segment lets it.

At each segment's start the states the record measures are set from it (a chamber
pressure, the position); every other state (a velocity, a spool, a bristle, an
unmeasured pressure) is carried on from the previous segment's end. The whole run is
still one compiled call (simulation ``Resets``). A velocity taken from the recorded
position's smoothed derivative was tried: near rest its sign is the noise's, friction's
direction follows it, and on a record with Coulomb friction of 300 N the chamber
pressures then jumped by 7 noise levels at random, which a bulk modulus fitted (it was
added, z 3.9 against a threshold of 2.6); carried on, nothing but the friction was.

A segment is as long as the loop's replay is predictable on this record
(:func:`horizon`): the longest length, halving from a quarter of the training part,
at which a millionth more of any parameter of a probe moves the segmented training
cost by less than a thousandth (a smooth cost moves by about a millionth times its
elasticity; a chaotic one by its own size). The probes are the starting model with each
candidate effect at five points of its range (the models the fit will compare; chaos
comes and goes with a friction's size), and the shortest of their
horizons is taken. A probe chaotic even over the shortest segment (stiction's
breakaway happens within a sample or not) has no horizon and is left out: no
segment length smooths it. On the seed-002 rig under P K=10 with Coulomb
friction of 300 N, the whole replay's cost moves by 550 % with a millionth more
friction; restarted every 0.2 s, by 0.1 %.

The fit, the held-out test and the intervals use the segmented replay; what the user
sees (the overlays, fit % before and after) is the whole record's replay
(:meth:`Replay.whole`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from fuzzyservo.calibration.replay import DIVERGED_COST, Replay
from fuzzyservo.components.effects import LIBRARY
from fuzzyservo.rig import Rig
from fuzzyservo.simulation import Resets

LONGEST_SHARE = 0.25  # the longest segment: this share of the training part
SHORTEST_PERIODS = 10  # the shortest segment, in replay samples
NUDGE = 1e-6  # the relative change of a probe's parameters that tells chaos
SMOOTH = 1e-3  # ... moving the cost by less than this share of itself: predictable
PROBE_SAMPLES = 10_000  # the horizon is measured on the training part's first samples
PROBE_POINTS = (0.1, 0.3, 0.5, 0.7, 0.9)  # where in its range each effect is probed


def segmented(replay: Replay, rig: Rig, probes: Sequence[tuple[Rig, Rig]] = ()) -> Replay:
    """``replay`` restarted from the record's state every :func:`horizon` of the
    ``probes`` ((model, the model nudged) pairs, :func:`probe_rigs`; the module
    docstring); ``replay`` itself when the record measures no state of ``rig``."""
    measured = _measured_states(replay, rig)
    if not measured:
        return replay
    dt = replay.sample_time_s
    longest = max(SHORTEST_PERIODS, round(LONGEST_SHARE * replay.training_s / dt))
    horizons = [horizon(replay, measured, pair, longest) for pair in probes]
    length = min((h for h in horizons if h is not None), default=longest)
    return dataclasses.replace(
        _with(replay, measured, length),
        segment_s=length * dt,
        segment_words=(
            f"segments of {length * dt:.3g} s, each from the recorded {', '.join(measured)}"
        ),
    )


def probe_rigs(rig: Rig, effects: Sequence[str]) -> list[tuple[Rig, Rig]]:
    """``rig`` with each of ``effects`` at PROBE_POINTS of the range its fit searches
    (candidates.fit_space), its optional parts off (the law a fit tries first: friction
    that sticks without pre-sliding is the chaotic one), each with that model's
    parameters a millionth larger: the models a calibration compares, and how
    :func:`horizon` tells chaos."""
    from fuzzyservo.calibration.candidates import fit_space

    out = []
    for effect in effects:
        space = fit_space(rig, effect)
        law = LIBRARY[effect]
        for point in PROBE_POINTS:
            values = {
                f: 0.0 if law.param_by_field(f).optional else space.value(j, point)
                for j, (o, f) in enumerate(space.names)
                if o == effect
            }
            try:
                probe = rig.with_effect(effect).with_params(**values)
                nudged = probe.with_params(**{f: v * (1.0 + NUDGE) for f, v in values.items()})
            except ValueError:  # a value the plant rejects (geometry): not a probe
                continue
            out.append((probe, nudged))
    return out


def horizon(
    replay: Replay, measured: dict[str, str], probe: tuple[Rig, Rig], longest: int
) -> int | None:
    """The longest segment, in replay samples (``longest``, then halving to
    SHORTEST_PERIODS), over which ``probe``'s segmented training cost (on its first
    PROBE_SAMPLES) moves by less than SMOOTH with the nudge: past it the replay is
    chaotic (the module docstring). None where even the shortest is: a law whose
    cost jumps within a few samples (stiction's breakaway), which no segment smooths."""
    n = min(replay.split, PROBE_SAMPLES)
    part = slice(0, n)
    length = longest
    while True:
        seg = _with(replay, measured, length)
        costs = []
        for model in probe:
            channels, _ = seg.run(model, training=True)
            costs.append(seg.cost(channels, part))
        a, b = costs
        if math.isfinite(a) and a < DIVERGED_COST and abs(b - a) <= SMOOTH * a:
            return length
        if length <= SHORTEST_PERIODS:
            return None
        length = max(length // 2, SHORTEST_PERIODS)


def _measured_states(replay: Replay, rig: Rig) -> dict[str, str]:
    """Plant state -> the record's channel that measures it."""
    states = rig.plant.states
    return {signal: channel for channel, signal in replay.channels.items() if signal in states}


def _with(replay: Replay, measured: dict[str, str], every: int) -> Replay:
    """``replay`` with the ``measured`` states set from the record every ``every``
    replay samples."""
    dt = replay.sample_time_s
    n = round(replay.scenario.duration_s / dt)
    at = np.arange(every, n, every, dtype=np.int64)
    columns = [np.interp(at * dt, replay.t, replay.measured(c)) for c in measured.values()]
    values = np.column_stack(columns) if columns else np.empty((at.size, 0))
    return dataclasses.replace(replay, resets=Resets(at, tuple(measured), values))
