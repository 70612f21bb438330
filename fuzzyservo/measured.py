"""Measured rig data as the domain sees it: sampled signals on one time axis, in SI units.

:mod:`fuzzyservo.io.measured` reads and writes the files (CSV, MATLAB ``.mat``); this module
holds only the typed record and how a raw column is scaled, so calibration and the rig model
use measured data without importing the file layer.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True, eq=False)
class Measured:
    """Sampled signals on one time axis, all in SI units.

    ``t`` is time in s (as in the file, not shifted to zero); ``signals`` maps a signal
    name (``y``, ``u``, ``p1`` ...) to an array of the same length as ``t``; ``units``
    gives the SI unit of each signal (``m``, ``Pa``, ``rad/s``, ``1`` ...);
    ``sample_period_s`` is the median of ``diff(t)``. Arrays are read-only.
    ``columns`` names the file's column of each signal and of ``t`` (for messages).
    """

    t: np.ndarray
    signals: dict[str, np.ndarray]
    units: dict[str, str]
    source: str
    sample_period_s: float
    columns: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        t = np.array(self.t, dtype=np.float64)
        if t.ndim != 1 or t.size < 2:
            raise ValueError(f"t must be a vector of at least 2 samples, got shape {t.shape}")
        signals = {}
        for name, values in self.signals.items():
            x = np.array(values, dtype=np.float64)
            if x.shape != t.shape:
                raise ValueError(
                    f"signal {name!r} has shape {x.shape}, t has {t.shape}; give one value per time"
                )
            x.setflags(write=False)
            signals[name] = x
        if set(self.units) != set(signals):
            raise ValueError(
                f"units name {sorted(self.units)} but signals are {sorted(signals)}; "
                "give one unit per signal"
            )
        t.setflags(write=False)
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "signals", signals)
        object.__setattr__(self, "units", dict(self.units))

    def __len__(self) -> int:
        return int(self.t.size)

    def _take(self, index: slice | np.ndarray, source: str) -> Measured:
        t = self.t[index]
        if t.size < 2:
            raise ValueError(
                f"{source} holds {t.size} sample(s) of {self.source}; choose a range with at least 2"
            )
        return Measured(
            t=t,
            signals={k: v[index] for k, v in self.signals.items()},
            units=self.units,
            source=source,
            sample_period_s=float(np.median(np.diff(t))),
            columns=self.columns,
        )

    def segment(self, t0_s: float, t1_s: float) -> Measured:
        """Samples with ``t0_s <= t < t1_s`` (half-open, so consecutive segments do not overlap)."""
        if not t0_s < t1_s:
            raise ValueError(f"segment needs t0_s < t1_s, but got (t0_s={t0_s}, t1_s={t1_s})")
        mask = (self.t >= t0_s) & (self.t < t1_s)
        return self._take(mask, f"{self.source}[{t0_s:g} s, {t1_s:g} s)")

    def split(self, fraction: float) -> tuple[Measured, Measured]:
        """(training, held-out): the first ``fraction`` of the samples and the rest, in time order."""
        if not 0.0 < fraction < 1.0:
            raise ValueError(f"split needs 0 < fraction < 1, but got fraction={fraction}")
        k = round(fraction * len(self))
        train = self._take(slice(0, k), f"{self.source}[:{k}]")
        held_out = self._take(slice(k, len(self)), f"{self.source}[{k}:]")
        return train, held_out


@dataclass(frozen=True)
class ColumnScaling:
    """A raw column turned into its signal: ``value = scale·raw + offset``, then, with
    ``tare_samples`` > 0, minus the mean of its first ``tare_samples`` values (a load
    cell zeroed at the start). ``scale`` and ``offset`` are in the unit the column is
    mapped to (per raw unit for ``scale``), e.g. 20 mm/V for a 0-10 V sensor over 200 mm.
    """

    scale: float = 1.0
    offset: float = 0.0
    tare_samples: int = 0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.scale) and self.scale != 0):
            raise ValueError(f"scale must be finite and non-zero, got {self.scale}")
        if self.tare_samples < 0:
            raise ValueError(f"tare must be >= 0 samples, got {self.tare_samples}")


__all__ = ["ColumnScaling", "Measured"]
