"""Classical controllers: open loop, P, PI and PIDF (PID with a filtered derivative, in
the parallel, PI-D and I-PD forms), each with output limits and anti-windup.

Each controller passes its state explicitly: ``init() -> state`` and
``step(state, r, y) -> (u, state)`` in Python, and the same arithmetic as a compiled
kernel ``*_step(cp, cs, r, y) -> u`` (``cs`` updated in place) for the fast loop.
The error is ``e = r − y`` in the rig's feedback unit (volts on both seed rigs).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from fuzzyservo._jit import njit
from fuzzyservo.controllers.base import Controller
from fuzzyservo.controllers.kinds import KIND_OPEN_LOOP, KIND_P, KIND_PI, KIND_PIDF


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


@njit(cache=True)
def pidf_step(cp: np.ndarray, cs: np.ndarray, r: float, y: float) -> float:
    """Discrete two-degree-of-freedom PID with a first-order derivative filter.

    u = Kp·(b·r − y) + Ki·∫(r − y) dt + Kd·D,   Tf·dD/dt + D = d(c·r − y)/dt

    (Åström & Hägglund, "Advanced PID control", §3.4, set-point weights b and c;
    MATLAB's ``pid(Kp, Ki, Kd, Tf)`` is b = c = 1). The filter is discretised by the
    backward difference, which is stable for every Tf ≥ 0 (Tf = 0: a plain backward
    difference); the integral by the forward rectangle with clamping anti-windup as
    :func:`pi_step`. The derivative starts from the first sample, so it gives no kick.
    cp = (Kp, Ki, Kd, Tf, b, c, u_min, u_max, T_s); cs = (I, D, previous c·r − y, started).
    """
    kp, ki, kd, tf = cp[0], cp[1], cp[2], cp[3]
    ts = cp[8]
    e = r - y
    ed = cp[5] * r - y
    if cs[3] == 0.0:
        cs[2] = ed
        cs[3] = 1.0
    cs[1] = (tf * cs[1] + (ed - cs[2])) / (tf + ts)
    cs[2] = ed
    u_free = kp * (cp[4] * r - y) + ki * cs[0] + kd * cs[1]
    u = _clip(u_free, cp[6], cp[7])
    saturated_high = u_free > cp[7] and e > 0.0
    saturated_low = u_free < cp[6] and e < 0.0
    if not (saturated_high or saturated_low):
        cs[0] += e * ts
    return u


# form -> set-point weights (b on the proportional term, c on the derivative term)
PID_FORMS: dict[str, tuple[float, float]] = {
    "parallel": (1.0, 1.0),  # all three terms act on the error (MATLAB pid, MTS "PIDF")
    "PI-D": (1.0, 0.0),  # derivative on the measurement: no kick at a reference step
    "I-PD": (0.0, 0.0),  # only the integral sees the reference: no overshoot from P or D
}


@dataclass(frozen=True)
class P(Controller):
    """Proportional controller ``u = K·(r − y)`` with output limits (seed 002 §5: K = 10)."""

    gain: float = 1.0
    u_min: float = -np.inf
    u_max: float = np.inf
    name: str = "P"
    unknowns: tuple[tuple[str, float, float], ...] = ()

    kind = KIND_P
    TUNABLE: ClassVar[dict[str, str]] = {"gain": "gain"}
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
    unknowns: tuple[tuple[str, float, float], ...] = ()

    kind = KIND_PI
    TUNABLE: ClassVar[dict[str, str]] = {"kp": "kp", "ki": "ki"}
    kernel = staticmethod(pi_step)

    def pack(self, sample_time_s: float) -> tuple[np.ndarray, np.ndarray]:
        return np.array([self.kp, self.ki, self.u_min, self.u_max, sample_time_s]), np.zeros(1)


@dataclass(frozen=True)
class PIDF(Controller):
    """PID with a filtered derivative, output limits and clamping anti-windup
    (:func:`pidf_step`): ``kp`` [V/V], ``ki`` [1/s], ``kd`` [s], ``filter_time_s`` the
    derivative filter's time constant Tf [s] (MATLAB's 1/N), ``form`` one of
    :data:`PID_FORMS`."""

    kp: float = 1.0
    ki: float = 0.0
    kd: float = 0.0
    filter_time_s: float = 0.0
    form: str = "parallel"
    u_min: float = -np.inf
    u_max: float = np.inf
    name: str = "PIDF"
    unknowns: tuple[tuple[str, float, float], ...] = ()

    kind = KIND_PIDF
    TUNABLE: ClassVar[dict[str, str]] = {
        "kp": "kp",
        "ki": "ki",
        "kd": "kd",
        "filter_time": "filter_time_s",
    }
    kernel = staticmethod(pidf_step)

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.form not in PID_FORMS:
            raise ValueError(
                f"form: unknown PID form {self.form!r}; choose one of {list(PID_FORMS)}"
            )
        if not self.filter_time_s >= 0:
            raise ValueError(
                f"filter_time: `filter_time >= 0` must hold, but got {self.filter_time_s} s"
            )

    def pack(self, sample_time_s: float) -> tuple[np.ndarray, np.ndarray]:
        b, c = PID_FORMS[self.form]
        cp = np.array(
            [self.kp, self.ki, self.kd, self.filter_time_s, b, c, self.u_min, self.u_max,
             sample_time_s]
        )  # fmt: skip
        return cp, np.zeros(4)
