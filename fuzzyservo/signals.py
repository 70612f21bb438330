"""Reference and load signals of a scenario: pure functions of a time vector.

Values are in the unit of what they drive (the rig's feedback volts for a
reference, the plant's load unit for a load); times in seconds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


class Signal:
    """A time signal; :meth:`sample` evaluates it on a time vector [s]."""

    def sample(self, t: np.ndarray) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError


@dataclass(frozen=True)
class Constant(Signal):
    """``s(t) = value``."""

    value: float = 0.0

    def sample(self, t: np.ndarray) -> np.ndarray:
        return np.full(np.shape(t), float(self.value))


@dataclass(frozen=True)
class Steps(Signal):
    """Piecewise constant: ``values[k]`` from ``times_s[k]`` on, ``initial`` before the first time."""

    times_s: tuple[float, ...]
    values: tuple[float, ...]
    initial: float = 0.0

    def __post_init__(self) -> None:
        if len(self.times_s) != len(self.values):
            raise ValueError(
                f"times_s and values must have the same length, got {len(self.times_s)} and {len(self.values)}"
            )
        if any(b <= a for a, b in zip(self.times_s, self.times_s[1:], strict=False)):
            raise ValueError(f"times_s must increase strictly, got {list(self.times_s)}")

    def sample(self, t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        out = np.full(t.shape, float(self.initial))
        for time, value in zip(self.times_s, self.values, strict=True):
            out[t >= time - 1e-12] = value
        return out


@dataclass(frozen=True)
class Pulse(Signal):
    """MATLAB/Simulink Pulse Generator plus an offset: ``base + amplitude`` during the first
    ``duty`` fraction of each ``period_s``, counted from ``delay_s``; ``base`` elsewhere
    (seed 002 §3: 0..1 V pulses on a 6.2 V offset)."""

    base: float
    amplitude: float
    period_s: float
    duty: float = 0.5
    delay_s: float = 0.0

    def __post_init__(self) -> None:
        if not self.period_s > 0:
            raise ValueError(f"period_s must be > 0, got {self.period_s}")
        if not 0 < self.duty < 1:
            raise ValueError(f"duty must lie in (0, 1), got {self.duty}")
        if self.delay_s < 0:
            raise ValueError(f"delay_s must be >= 0, got {self.delay_s}")

    def sample(self, t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        phase = np.mod(t - self.delay_s + 1e-12, self.period_s)
        high = (t >= self.delay_s - 1e-12) & (phase < self.duty * self.period_s)
        return self.base + self.amplitude * high


@dataclass(frozen=True)
class Sines(Signal):
    """Sum of sinusoids ``offset + Σ a_k·sin(2π f_k t + φ_k)`` (e.g. a sea-wave profile)."""

    amplitudes: tuple[float, ...]
    frequencies_hz: tuple[float, ...]
    phases_rad: tuple[float, ...] = ()
    offset: float = 0.0

    def __post_init__(self) -> None:
        if len(self.amplitudes) != len(self.frequencies_hz):
            raise ValueError("amplitudes and frequencies_hz must have the same length")
        if self.phases_rad and len(self.phases_rad) != len(self.amplitudes):
            raise ValueError("phases_rad must be empty or as long as amplitudes")

    def sample(self, t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        out = np.full(t.shape, float(self.offset))
        phases = self.phases_rad or (0.0,) * len(self.amplitudes)
        for a, f, ph in zip(self.amplitudes, self.frequencies_hz, phases, strict=True):
            out += a * np.sin(2 * np.pi * f * t + ph)
        return out


@dataclass(frozen=True)
class Affine(Signal):
    """``offset + gain·inner(t)``: a signal written in another unit (e.g. cm through a sensor)."""

    inner: Signal
    gain: float = 1.0
    offset: float = 0.0

    def sample(self, t: np.ndarray) -> np.ndarray:
        return self.offset + self.gain * self.inner.sample(t)


@dataclass(frozen=True, eq=False)
class Sampled(Signal):
    """A recorded signal held between its samples (zero-order hold, like a DAC):
    ``s(t) = values[k]`` for ``times_s[k] <= t < times_s[k+1]``; the first value before
    the first sample. Replays measured references and commands."""

    times_s: np.ndarray
    values: np.ndarray

    def __post_init__(self) -> None:
        if np.shape(self.times_s) != np.shape(self.values) or np.ndim(self.times_s) != 1:
            raise ValueError("times_s and values must be vectors of the same length")
        if np.any(np.diff(self.times_s) <= 0):
            raise ValueError("times_s must increase strictly")

    def sample(self, t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        # a small tolerance so that a grid computed as k·dt lands on its own sample
        k = np.searchsorted(self.times_s, t + 1e-9 * (1.0 + np.abs(t)), side="right") - 1
        return np.asarray(self.values, dtype=float)[np.clip(k, 0, None)]
