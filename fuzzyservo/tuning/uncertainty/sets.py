"""Uncertainty in a study: sampled plants and noise realisations, drawn once, scored alike.

A study's ``uncertainty:`` section (read by :mod:`fuzzyservo.io.studies`) becomes an
:class:`Uncertainty`: distributions of rig parameters (plant parameters by their rig-file
key, effect parameters as ``effect.parameter``, and the loop's ``io_delay``), how many
samples, their seed, and how a trial's values over the samples are aggregated.

Common random numbers: :meth:`Uncertainty.draw` is deterministic in the seed, so every
trial of a study runs the same N plants with the same sensor-noise realisations, and a
difference between two trials is the controllers' doing, not the dice's.

Aggregates over the samples (all values minimised): ``worst`` (the largest), ``mean``,
``cvar`` (conditional value at risk: the mean of the worst ``alpha`` fraction, at least
one sample; Rockafellar & Uryasev, J. Risk 2 (2000) 21-41).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from fuzzyservo.limits import plant_samples_problem

if TYPE_CHECKING:
    from fuzzyservo.rig import Rig

KINDS = ("uniform", "normal", "log-uniform")
SAMPLE_AGGREGATES = ("worst", "mean", "cvar")
#: the loop's I/O delay: a rig setting, not a plant parameter
IO_DELAY = "io_delay"
#: a normal distribution is cut at mean ± this many standard deviations (no negative masses)
NORMAL_CUT = 3.0


@dataclass(frozen=True)
class Distribution:
    """One uncertain number of the rig, in SI.

    ``target``: what the study file names (``bulk_modulus``, ``coulomb_friction.force``,
    ``io_delay``); ``field``: the parameter field it sets (``effect`` names the effect for
    effect parameters); ``kind``: uniform/log-uniform on ``[a, b]``, or normal with mean
    ``a`` and standard deviation ``b`` cut at ±3σ. ``unit``: how the file gave it (for
    tables); ``origin``: where the range came from when not the study file (``fitted``:
    a calibrated rig's 95 % interval).
    """

    target: str
    kind: str
    a: float
    b: float
    field: str = ""
    effect: str = ""
    unit: str = ""
    scale: float = 1.0  # SI per file unit, to show drawn values in the file's unit
    origin: str = ""  # e.g. "fitted" for an interval read from a calibrated rig file

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(
                f"{self.target}: unknown distribution {self.kind!r}; choose one of {list(KINDS)}"
            )
        if not (math.isfinite(self.a) and math.isfinite(self.b)):
            raise ValueError(f"{self.target}: bounds must be finite, got ({self.a}, {self.b})")
        if self.kind == "normal":
            if not self.b > 0:
                raise ValueError(f"{self.target}: `std > 0` must hold, but got std={self.b}")
        elif not self.a < self.b:
            raise ValueError(
                f"{self.target}: `low < high` must hold, but got (low={self.a}, high={self.b}); swap them"
            )
        if self.kind == "log-uniform" and self.a <= 0:
            raise ValueError(f"{self.target}: a log-uniform range needs low > 0, got low={self.a}")

    @property
    def bounds(self) -> tuple[float, float]:
        """The range the draws fall in [SI]."""
        if self.kind == "normal":
            return self.a - NORMAL_CUT * self.b, self.a + NORMAL_CUT * self.b
        return self.a, self.b

    def draw(self, rng: np.random.Generator, n: int) -> np.ndarray:
        if self.kind == "uniform":
            return rng.uniform(self.a, self.b, n)
        if self.kind == "log-uniform":
            return np.exp(rng.uniform(math.log(self.a), math.log(self.b), n))
        return np.clip(rng.normal(self.a, self.b, n), *self.bounds)

    def describe(self) -> str:
        s = self.scale or 1.0
        u = f" {self.unit}" if self.unit else ""
        why = f" ({self.origin})" if self.origin else ""
        if self.kind == "normal":
            return f"{self.target} ~ N({self.a / s:.4g}, {self.b / s:.4g}){u}{why}"
        return f"{self.target} ~ {self.kind}[{self.a / s:.4g}, {self.b / s:.4g}]{u}{why}"


@dataclass(frozen=True)
class Sample:
    """One drawn plant: ``values`` by target (SI) and its noise seed."""

    index: int
    values: dict[str, float]
    noise_seed: int

    def describe(self, dists: Sequence[Distribution]) -> str:
        by = {d.target: d for d in dists}
        parts = []
        for k, v in self.values.items():
            d = by.get(k)
            s = d.scale if d and d.scale else 1.0
            parts.append(f"{k}={v / s:.4g}{(' ' + d.unit) if d and d.unit else ''}")
        return f"sample {self.index} ({', '.join(parts) or 'nominal'})"


@dataclass(frozen=True)
class Uncertainty:
    """What is uncertain, how often it is drawn, and how the samples' values aggregate."""

    parameters: tuple[Distribution, ...] = ()
    samples: int = 8
    seed: int = 0
    noise: bool = True
    aggregate: str = "worst"
    alpha: float = 0.25
    margin_scenario: str = ""
    draws: tuple[Sample, ...] = field(default=(), repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.samples < 1:
            raise ValueError(f"samples: must be >= 1, got {self.samples}")
        if self.aggregate not in SAMPLE_AGGREGATES:
            raise ValueError(
                f"aggregate: unknown {self.aggregate!r}; choose one of {list(SAMPLE_AGGREGATES)}"
            )
        if not 0 < self.alpha <= 1:
            raise ValueError(f"alpha: must lie in (0, 1], got {self.alpha}")
        targets = [d.target for d in self.parameters]
        if len(set(targets)) != len(targets):
            raise ValueError(f"parameters: each once, got {targets}")
        if not self.draws:
            object.__setattr__(self, "draws", tuple(self.draw(self.samples)))

    def draw(self, n: int, seed: int | None = None) -> list[Sample]:
        """``n`` samples from ``seed`` (default: the study's): the same every call."""
        if plant_samples_problem(n):
            raise ValueError(f"samples: {plant_samples_problem(n)}")
        seed = self.seed if seed is None else seed
        rng = np.random.default_rng(seed)
        columns = {d.target: d.draw(rng, n) for d in self.parameters}
        return [
            Sample(
                i,
                {k: float(v[i]) for k, v in columns.items()},
                (1_000_003 * seed + 7919 * (i + 1)) % (2**31) if self.noise else 0,
            )
            for i in range(n)
        ]

    def describe(self) -> str:
        agg = f"CVaR {self.alpha:g}" if self.aggregate == "cvar" else self.aggregate
        what = "; ".join(d.describe() for d in self.parameters) or "noise only"
        noise = ", a noise realisation each" if self.noise else ""
        return f"{self.samples} samples (seed {self.seed}{noise}), {agg} over them: {what}"

    def describe_data(self) -> dict[str, Any]:
        """Plain data for the study's fingerprint."""
        return {
            "parameters": {d.target: [d.kind, d.a, d.b] for d in self.parameters},
            "samples": self.samples,
            "seed": self.seed,
            "noise": self.noise,
            "aggregate": self.aggregate,
            "alpha": self.alpha,
            "margin_scenario": self.margin_scenario,
        }


def aggregate(values: Sequence[float], how: str, alpha: float = 0.25) -> float:
    """Worst (max), mean or CVaR-``alpha`` (mean of the largest ``ceil(alpha·n)``) of ``values``;
    NaN when any value is not finite."""
    v = np.asarray(values, dtype=float)
    if v.size == 0 or not np.isfinite(v).all():
        return math.nan
    if how == "worst":
        return float(v.max())
    if how == "mean":
        return float(v.mean())
    if how == "cvar":
        k = max(1, math.ceil(alpha * v.size))
        return float(np.sort(v)[-k:].mean())
    raise ValueError(f"unknown aggregate {how!r}; choose one of {list(SAMPLE_AGGREGATES)}")


def sample_rig(rig: Rig, dists: Sequence[Distribution], sample: Sample) -> Rig:
    """``rig`` with ``sample``'s values set (plant parameters, effect parameters, I/O delay);
    raises ``ValueError`` when a value is outside what the rig accepts."""
    plain: dict[str, float] = {}
    effects: dict[str, dict[str, float]] = {}
    delay = None
    for d in dists:
        value = sample.values[d.target]
        if d.target == IO_DELAY:
            delay = value
        elif d.effect:
            effects.setdefault(d.effect, {})[d.target.split(".", 1)[1]] = value
        else:
            plain[d.field] = value
    out = rig.with_params(**plain) if plain else rig
    for name, values in effects.items():
        current = out.effect_values(name) if name in out.effects else {}
        out = out.with_effect(name, **{**current, **values})
    if delay is not None:
        out = dataclasses.replace(out, io_delay_s=float(delay))
    return out
