"""Classical controllers: open loop, P, PI and PIDF (PID with a filtered derivative, in
the parallel, PI-D and I-PD forms), each with output limits and anti-windup.

Each controller passes its state explicitly: ``init(sample_time_s) -> state`` and
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
from fuzzyservo.controllers.layout import Slot, layout, pack

_LIMITS = (Slot("u_min", "lower output limit [V]"), Slot("u_max", "upper output limit [V]"))
_SAMPLE_TIME = Slot("sample_time", "T_s [s]")
#: cp of open loop and P; their state vector holds nothing the kernels read
P_PARAMS = layout("PParams", Slot("gain", "K [V/V]"), *_LIMITS)
P_STATE = layout("PState", Slot("unused", "the compiled loop passes every controller a state"))
PI_PARAMS = layout(
    "PIParams", Slot("kp", "Kp [V/V]"), Slot("ki", "Ki [1/s]"), *_LIMITS, _SAMPLE_TIME
)
PI_STATE = layout("PIState", Slot("integral", "I = ∫e dt [V·s]"))
PIDF_PARAMS = layout(
    "PIDFParams",
    Slot("kp", "Kp [V/V]"),
    Slot("ki", "Ki [1/s]"),
    Slot("kd", "Kd [s]"),
    Slot("filter_time", "Tf [s]"),
    Slot("b", "set-point weight of the proportional term"),
    Slot("c", "set-point weight of the derivative term"),
    *_LIMITS,
    _SAMPLE_TIME,
)
PIDF_STATE = layout(
    "PIDFState",
    Slot("integral", "I = ∫e dt [V·s]"),
    Slot("derivative", "D, the filtered derivative of c·r − y [V/s]"),
    Slot("previous", "c·r − y at the previous sample [V]"),
    Slot("started", "0 before the first sample: the derivative starts there", flag=True),
)


@njit(cache=True, inline="always")
def _clip(u: float, lo: float, hi: float) -> float:
    return min(max(u, lo), hi)


@njit(cache=True)
def open_loop_step(cp: np.ndarray, cs: np.ndarray, r: float, y: float) -> float:
    """u = K·r, clipped to [u_min, u_max]; the measurement is ignored. cp: :data:`P_PARAMS`."""
    return _clip(cp[P_PARAMS.gain] * r, cp[P_PARAMS.u_min], cp[P_PARAMS.u_max])


@njit(cache=True)
def p_step(cp: np.ndarray, cs: np.ndarray, r: float, y: float) -> float:
    """u = K·(r − y), clipped to [u_min, u_max]. cp: :data:`P_PARAMS`."""
    return _clip(cp[P_PARAMS.gain] * (r - y), cp[P_PARAMS.u_min], cp[P_PARAMS.u_max])


@njit(cache=True)
def pi_step(cp: np.ndarray, cs: np.ndarray, r: float, y: float) -> float:
    """Discrete PI with conditional-integration anti-windup.

    u_k = clip(Kp·e_k + Ki·I_k),  I_{k+1} = I_k + e_k·T_s unless u_k sits at a limit
    and e_k would drive it further (clamping; Åström & Hägglund, "Advanced PID
    control", §3.5). cp: :data:`PI_PARAMS`; cs: :data:`PI_STATE`.
    """
    k, st = PI_PARAMS, PI_STATE
    e = r - y
    u_free = cp[k.kp] * e + cp[k.ki] * cs[st.integral]
    u = _clip(u_free, cp[k.u_min], cp[k.u_max])
    saturated_high = u_free > cp[k.u_max] and e > 0.0
    saturated_low = u_free < cp[k.u_min] and e < 0.0
    if not (saturated_high or saturated_low):
        cs[st.integral] += e * cp[k.sample_time]
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
    cp: :data:`PIDF_PARAMS`; cs: :data:`PIDF_STATE`.
    """
    k, st = PIDF_PARAMS, PIDF_STATE
    kp, ki, kd, tf = cp[k.kp], cp[k.ki], cp[k.kd], cp[k.filter_time]
    ts = cp[k.sample_time]
    e = r - y
    ed = cp[k.c] * r - y
    if cs[st.started] == 0.0:
        cs[st.previous] = ed
        cs[st.started] = 1.0
    cs[st.derivative] = (tf * cs[st.derivative] + (ed - cs[st.previous])) / (tf + ts)
    cs[st.previous] = ed
    u_free = kp * (cp[k.b] * r - y) + ki * cs[st.integral] + kd * cs[st.derivative]
    u = _clip(u_free, cp[k.u_min], cp[k.u_max])
    saturated_high = u_free > cp[k.u_max] and e > 0.0
    saturated_low = u_free < cp[k.u_min] and e < 0.0
    if not (saturated_high or saturated_low):
        cs[st.integral] += e * ts
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
        cp = pack(P_PARAMS, gain=self.gain, u_min=self.u_min, u_max=self.u_max)
        return cp, np.zeros(len(P_STATE))


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
        cp = pack(
            PI_PARAMS, kp=self.kp, ki=self.ki, u_min=self.u_min, u_max=self.u_max,
            sample_time=sample_time_s,
        )  # fmt: skip
        return cp, np.zeros(len(PI_STATE))


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
        cp = pack(
            PIDF_PARAMS, kp=self.kp, ki=self.ki, kd=self.kd, filter_time=self.filter_time_s,
            b=b, c=c, u_min=self.u_min, u_max=self.u_max, sample_time=sample_time_s,
        )  # fmt: skip
        return cp, np.zeros(len(PIDF_STATE))
