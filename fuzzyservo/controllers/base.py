"""What every controller offers, compiled or not.

A controller is a frozen description. ``pack(T_s)`` turns it into two float64 vectors
for the compiled loop: constant parameters ``cp`` and an initial state ``cs``. The
Python face, ``init``/``step``, runs the very same compiled kernel, so a test, the
fast loop and a replay of measured data all compute the same numbers.
"""

from __future__ import annotations

import dataclasses
import re
from typing import ClassVar

import numpy as np

_STEP = re.compile(r"([^.\[\]]+)|\[(\d+)\]")


def parameter_path(path: str) -> tuple[str | int, ...]:
    """``'input.increments[3]'`` → ``('input', 'increments', 3)``: where a searchable
    number sits in a controller (its name in ``params()``, its place in the file).
    ``ValueError`` for a path written any other way."""
    parts = tuple(int(index) if index else name for name, index in _STEP.findall(path))
    rebuilt = "".join(f"[{p}]" if isinstance(p, int) else f".{p}" for p in parts).lstrip(".")
    if not parts or rebuilt != path:
        raise ValueError(
            f"cannot read parameter path {path[:60]!r}; write it like 'input.reshape' or "
            "'input.increments[3]'"
        )
    return parts


class Controller:
    """Base of the controllers; subclasses are frozen dataclasses with a ``kind`` code."""

    kind: ClassVar[int]  # controllers/kinds.py
    kernel: ClassVar  # the compiled step(cp, cs, r, y) -> u (a staticmethod)
    name: str
    u_min: float
    u_max: float
    # (gain field, lower, upper): gains a controller file declares unknown (`fit: [lo, hi]`),
    # which calibration fits in a closed-loop replay; none by default
    unknowns: tuple[tuple[str, float, float], ...] = ()
    #: the numbers a tuning study may search: name (as controller files write it) -> field
    TUNABLE: ClassVar[dict[str, str]] = {}

    def pack(self, sample_time_s: float) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover
        raise NotImplementedError

    def __post_init__(self) -> None:
        if not self.u_min < self.u_max:
            raise ValueError(
                f"output_limits: `u_min < u_max` must hold, but got (u_min={self.u_min}, u_max={self.u_max})"
            )

    def with_limits(self, u_min: float, u_max: float) -> Controller:
        """The same controller with other output limits [V]."""
        return dataclasses.replace(self, u_min=u_min, u_max=u_max)

    def with_gains(self, **gains: float) -> Controller:
        """The same controller with the named gain fields changed (e.g. ``kp=2.0``)."""
        return dataclasses.replace(self, **gains)

    def params(self) -> dict[str, float]:
        """The searchable numbers by name (:attr:`TUNABLE`), e.g. ``{"kp": 2.0, "ki": 0.5}``."""
        return {name: float(getattr(self, f)) for name, f in self.TUNABLE.items()}

    def with_params(self, **values: float) -> Controller:
        """The same controller with the named searchable numbers changed (``kp=2.0``);
        ``ValueError`` for a name it does not have or a value it cannot take."""
        unknown = [name for name in values if name not in self.TUNABLE]
        if unknown:
            raise ValueError(
                f"{self.name}: no searchable number {unknown[0]!r}; "
                f"a {type(self).__name__} controller has {', '.join(self.TUNABLE) or 'none'}"
            )
        return dataclasses.replace(
            self, **{self.TUNABLE[name]: float(v) for name, v in values.items()}
        )

    def renamed(self, name: str) -> Controller:
        """The same controller under another name."""
        return dataclasses.replace(self, name=name)

    def gain_bounds(self) -> dict[str, tuple[float, float]]:
        """Gain field -> (lower, upper) of the gains declared unknown."""
        return {name: (lo, hi) for name, lo, hi in self.unknowns}

    @property
    def has_limits(self) -> bool:
        return bool(np.isfinite(self.u_min) and np.isfinite(self.u_max))

    def init(self, sample_time_s: float) -> tuple[np.ndarray, np.ndarray]:
        """Initial state: ``(cp, cs)``; pass it to :meth:`step`."""
        cp, cs = self.pack(sample_time_s)
        return cp, cs.copy()

    def step(
        self, state: tuple[np.ndarray, np.ndarray], r: float, y: float
    ) -> tuple[float, tuple[np.ndarray, np.ndarray]]:
        """One sample: command ``u`` for reference ``r`` and measurement ``y``, and the new state."""
        cp, cs = state
        cs = cs.copy()
        u = self.kernel(cp, cs, float(r), float(y))
        return float(u), (cp, cs)
