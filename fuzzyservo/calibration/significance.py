"""Whether a fitted effect matters physically: its size against the sizes real rigs show,
or, for an effect with no size of its own, its contribution against the signal.

A test against noise (decision.py, null.py) says whether the data show an effect; this
says whether what they show is worth adding to the model. It is judged against what the
effect does physically, never against the residual the starting model leaves: on a
clean record that residual is mostly sensor noise, and no real effect moves the outputs
by a fixed share of it.

* An effect with a size parameter (``EffectParam.typical``, docs/modelling.md "Typical
  ranges": a friction force of 1-10 % of the stall force, a leakage passing 0.1-10 % of
  the rated flow at full pressure, a null bias of 0.5-3 % of the rated current, ...)
  matters when its fitted size is at least ``SIZE_FLOOR`` of the smallest typical one.
* An effect without one (a bulk modulus, a pump's flow) matters when it moves some
  recorded channel by at least ``SIGNAL_FLOOR`` of that channel's own variation (RMS
  of the change over RMS of the signal about its mean, the whole record).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from fuzzyservo.calibration.replay import Replay
from fuzzyservo.components.effects import LIBRARY, EffectParam
from fuzzyservo.rig import Rig

SIZE_FLOOR = 0.1  # share of the smallest typical size that matters
SIGNAL_FLOOR = 0.01  # share of a channel's own variation that matters


@dataclass(frozen=True)
class Practical:
    """``fraction``: the fitted size over its floor's reference (the smallest typical
    size, or SIGNAL_FLOOR's share of the signal); ``words``: the comparison in words
    (for a report)."""

    fraction: float
    floor: float
    words: str

    @property
    def matters(self) -> bool:
        """At least the floor: the effect matters."""
        return self.fraction >= self.floor


def size_param(effect: str) -> EffectParam | None:
    """The parameter that is an effect's size (it has a typical range), if any."""
    return next((p for p in LIBRARY[effect].fitted if p.typical is not None), None)


def signal_share(
    replay: Replay, base: Mapping[str, np.ndarray], model: Mapping[str, np.ndarray]
) -> tuple[float, str]:
    """The largest share of a channel's own variation (RMS about its mean) that ``model``
    moves it from ``base`` by, whole record, and that channel."""
    best, where = 0.0, next(iter(replay.channels))
    for channel in replay.channels:
        y = np.asarray(replay.measured(channel), dtype=float)
        spread = float(np.sqrt(np.mean((y - np.mean(y)) ** 2)))
        change = float(np.sqrt(np.mean((np.asarray(model[channel]) - base[channel]) ** 2)))
        share = change / spread if spread > 0.0 else 0.0
        if share > best:
            best, where = share, channel
    return best, where


def practical(
    replay: Replay,
    rig: Rig,
    effect: str,
    params: Mapping[str, float],
    base: Mapping[str, np.ndarray],
    model: Mapping[str, np.ndarray],
) -> Practical:
    """Does ``effect`` at the fitted ``params`` (key -> SI) matter on ``rig`` (module
    docstring)? ``base`` and ``model``: the channels without and with it."""
    param = size_param(effect)
    low = param.typical(rig.scales())[0] if param is not None else math.nan
    if param is not None and math.isfinite(low) and low > 0.0:
        size = abs(float(params.get(param.key, 0.0)))
        fraction = size / low
        unit = rig.plant.effect_unit(param.unit)
        words = (
            f"its {param.key.replace('_', ' ')} {size:.3g} {unit} is {100 * fraction:.3g} % "
            f"of the smallest a real rig typically shows ({low:.3g} {unit})"
        ).replace("  ", " ")
        return Practical(fraction, SIZE_FLOOR, words)
    share, channel = signal_share(replay, base, model)
    words = f"it moves {channel} by {100 * share:.3g} % of that signal's own variation"
    return Practical(share / SIGNAL_FLOOR, 1.0, words)
