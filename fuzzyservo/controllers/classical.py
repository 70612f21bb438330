"""Classical baseline controllers: open loop, P and PI with anti-windup.

Each controller passes its state explicitly: ``init() -> state`` and
``step(state, r, y) -> (u, state)`` in Python, and the same arithmetic as a compiled
kernel ``*_step(cp, cs, r, y) -> u`` (``cs`` updated in place) for the fast loop.
The error is ``e = r − y`` in the rig's feedback unit (volts on both seed rigs).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fuzzyservo._jit import njit
from fuzzyservo.controllers.base import Controller
from fuzzyservo.controllers.kinds import KIND_OPEN_LOOP, KIND_P, KIND_PI


@njit(cache=True, inline="always")
def _clip(u: float, lo: float, hi: float) -> float:
    return min(max(u, lo), hi)


@njit(cache=True)
def open_loop_step(cp: np.ndarray, cs: np.ndarray, r: float, y: float) -> float:
    """u = K·r, clipped to [u_min, u_max]; the measurement is ignored. cp = (K, u_min, u_max)."""
    return _clip(cp[0] * r, cp[1], cp[2])


@njit(cache=True)
def p_step(cp: np.ndarray, cs: np.ndarray, r: float, y: float) -> float:
    """u = K·(r − y), clipped to [u_min, u_max]. cp = (K, u_min, u_max)."""
    return _clip(cp[0] * (r - y), cp[1], cp[2])


@njit(cache=True)
def pi_step(cp: np.ndarray, cs: np.ndarray, r: float, y: float) -> float:
    """Discrete PI with conditional-integration anti-windup.

    u_k = clip(Kp·e_k + Ki·I_k),  I_{k+1} = I_k + e_k·T_s unless u_k sits at a limit
    and e_k would drive it further (clamping; Åström & Hägglund, "Advanced PID
    control", §3.5). cp = (Kp, Ki, u_min, u_max, T_s); cs = (I,).
    """
    e = r - y
    u_free = cp[0] * e + cp[1] * cs[0]
    u = _clip(u_free, cp[2], cp[3])
    saturated_high = u_free > cp[3] and e > 0.0
    saturated_low = u_free < cp[2] and e < 0.0
    if not (saturated_high or saturated_low):
        cs[0] += e * cp[4]
    return u


@dataclass(frozen=True)
class P(Controller):
    """Proportional controller ``u = K·(r − y)`` with output limits (seed 002 §5: K = 10)."""

    gain: float = 1.0
    u_min: float = -np.inf
    u_max: float = np.inf
    name: str = "P"

    kind = KIND_P
    kernel = staticmethod(p_step)

    def pack(self, sample_time_s: float) -> tuple[np.ndarray, np.ndarray]:
        return np.array([self.gain, self.u_min, self.u_max]), np.zeros(1)


@dataclass(frozen=True)
class OpenLoop(P):
    """Feed-forward ``u = K·r``: the seed-000 open-loop tests apply the command to the valve."""

    name: str = "open_loop"

    kind = KIND_OPEN_LOOP
    kernel = staticmethod(open_loop_step)


@dataclass(frozen=True)
class PI(Controller):
    """PI controller ``u = Kp·e + Ki·∫e dt`` with output limits and anti-windup (clamping)."""

    kp: float = 1.0
    ki: float = 0.0
    u_min: float = -np.inf
    u_max: float = np.inf
    name: str = "PI"

    kind = KIND_PI
    kernel = staticmethod(pi_step)

    def pack(self, sample_time_s: float) -> tuple[np.ndarray, np.ndarray]:
        return np.array([self.kp, self.ki, self.u_min, self.u_max, sample_time_s]), np.zeros(1)
