"""The closed loop's shared logic: the integrator tableau, the linear algebra, and the
sample logic (sensor noise and ADC, limits, saturation, input effects, transport and
I/O delay) that the compiled loop and the scipy reference path both call.

The compiled loop itself (``_plant_loop.py``) is compiled once per install; it calls the
plant's and the controller's kernels through their addresses (``_calls.py``,
``binding.py``); everything in here is plant-free.

The plant is integrated between samples by an adaptive linearly implicit
Rosenbrock-W method, ROS34PW2 (order 3, embedded order 2), with a finite-difference
Jacobian evaluated at the start of each control interval and refreshed when a step is
rejected. It is L-stable, so the stiff valve-chamber modes of seed 002 (β/V·K/√p_lam
up to ~1e6 1/s, docs/modelling.md "Stiffness") cost no step-size restriction, and the
error estimate keeps the slow piston motion accurate. On the seed-002 pulses it needs
40 % fewer steps than MATLAB's ode23s pair (tried first) for the same accuracy. The
stages are solved in Hairer & Wanner's transformed variables (``_A_U`` .. ``_E_U``
below), which need no Jacobian-vector product: the same steps, 7 % less CPU time.
Nothing in here raises: a failure ends the run with a status code the caller turns
into a result.

The loop's stages are declared once, in order, in :data:`LOOP_STAGES`: the feedback
sensor, its noise and ADC, the sample and hold, the actuator's current limit, the I/O
delay, then the input effects (components/effects.py) between the held actuator value
and the plant. :class:`LoopSettings` is made from their parameters. The two delays,
``io_delay`` (a loop setting) and ``transport_delay`` (an effect), shift the held
sequence in time together (an interval is integrated in two parts where the delayed
input switches); ``valve_bias`` adds to it, ``valve_lag`` appends the spool's states
(its position, and for a second-order spool its velocity) to the plant's, and ``valve_deadband`` maps the spool onto
the plant input around its null.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from fractions import Fraction
from typing import Any, NamedTuple

import numpy as np

from fuzzyservo._jit import njit
from fuzzyservo.components.effects import LIBRARY, E, deadband
from fuzzyservo.components.sensor import adc
from fuzzyservo.simulation._calls import call_step
from fuzzyservo.units import parse_unit

STATUS_OK = 0
STATUS_DIVERGED = 1
STATUS_END_STOP = 2
STATUS_STEP_FAILURE = 3

# ROS34PW2: Rang & Angermann, "New Rosenbrock W-methods of order 3 for partial
# differential algebraic equations of index 1", BIT 45 (2005), Table 4. Order 3 with an
# embedded order-2 solution, L-stable and stiffly accurate, and a W-method: it keeps
# its order with an approximate Jacobian, so J is evaluated once per control interval.
_STAGES = 4
_GAMMA = 4.3586652150845900e-1
_A = np.array(
    [
        [0.0, 0.0, 0.0, 0.0],
        [8.7173304301691801e-1, 0.0, 0.0, 0.0],
        [8.4457060015369423e-1, -1.1299064236484185e-1, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
    ]
)
_G = np.array(
    [
        [0.0, 0.0, 0.0, 0.0],
        [-8.7173304301691801e-1, 0.0, 0.0, 0.0],
        [-9.0338057013044082e-1, 5.4180672388095326e-2, 0.0, 0.0],
        [2.4212380706095346e-1, -1.2232505839045147, 5.4526025533510214e-1, 0.0],
    ]
)
_B = np.array(
    [2.4212380706095346e-1, -1.2232505839045147, 1.5452602553351020, 4.3586652150845900e-1]
)
_B_EMBEDDED = np.array([3.7810903145819369e-1, -9.6042292212423178e-2, 0.5, 2.1793326075422950e-1])


def _transformed() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The method in transformed variables u_i = Σ_j γ_ij·k_j (Hairer & Wanner, Solving
    ODEs II, §IV.7, eq. 7.25): the stages need no product J·Σγ_ij·k_j, so a step costs
    one LU and four solves, and no matrix-vector product. Returns (A·Γ⁻¹, −(strictly
    lower part of Γ⁻¹), b·Γ⁻¹, (b − b̂)·Γ⁻¹) with Γ = G + γ·I.

    Computed exactly in rationals from the tableau's binary values and rounded once, so
    every machine gets the same coefficients to the bit. ``np.linalg.inv`` and ``@`` go
    through OpenBLAS, whose kernels depend on the CPU: its AVX-512 and AVX2 kernels gave
    coefficients one ULP apart, which moved a stick-slip run's stop positions by up to
    14 µm (examples/run_dinca_friction.csv)."""
    n = _STAGES
    a, g, b, bh = (np.asarray(m).tolist() for m in (_A, _G, _B, _B_EMBEDDED))
    gam = [
        [Fraction(g[i][j]) + (Fraction(_GAMMA) if i == j else 0) for j in range(n)]
        for i in range(n)
    ]
    inv = [[Fraction(0)] * n for _ in range(n)]  # Γ is lower triangular: forward substitution
    for j in range(n):
        for i in range(j, n):
            rest = sum((gam[i][k] * inv[k][j] for k in range(j, i)), Fraction(0))
            inv[i][j] = (Fraction(int(i == j)) - rest) / gam[i][i]

    def times_inv(row: list[Fraction]) -> list[float]:
        return [float(sum((row[k] * inv[k][j] for k in range(n)), Fraction(0))) for j in range(n)]

    a_u = np.array([times_inv([Fraction(v) for v in row]) for row in a])
    c_u = np.array([[-float(inv[i][j]) if j < i else 0.0 for j in range(n)] for i in range(n)])
    m_u = np.array(times_inv([Fraction(v) for v in b]))
    e_u = np.array(times_inv([Fraction(v) - Fraction(w) for v, w in zip(b, bh, strict=True)]))
    return a_u, c_u, m_u, e_u


# stage states x + Σ_j a_ij·u_j; stage right-hand sides f + Σ_j c_ij·u_j / h; the order-3
# solution x + Σ_i m_i·u_i; its difference from the embedded order-2 solution
_A_U, _C_U, _M_U, _E_U = _transformed()


class Tableau(NamedTuple):
    """The method the loop integrates with, in transformed variables (:func:`_transformed`):
    what another implementation of it (an exported plant FMU's co-simulation solver)
    needs to take the same steps."""

    stages: int
    gamma: float
    a: np.ndarray
    c: np.ndarray
    m: np.ndarray
    e: np.ndarray


#: ROS34PW2 as the loop runs it
ROS34PW2 = Tableau(_STAGES, _GAMMA, _A_U, _C_U, _M_U, _E_U)
_MAX_STEPS_PER_INTERVAL = 200_000


@njit(cache=True)
def _lu_factor(a: np.ndarray, piv: np.ndarray) -> bool:
    """In-place LU factorisation with partial pivoting; False when singular."""
    n = a.shape[0]
    for k in range(n):
        m = k
        big = abs(a[k, k])
        for i in range(k + 1, n):
            if abs(a[i, k]) > big:
                big = abs(a[i, k])
                m = i
        if big == 0.0 or not math.isfinite(big):
            return False
        piv[k] = m
        if m != k:
            for j in range(n):
                tmp = a[k, j]
                a[k, j] = a[m, j]
                a[m, j] = tmp
        inv = 1.0 / a[k, k]
        for i in range(k + 1, n):
            a[i, k] *= inv
            f = a[i, k]
            if f != 0.0:
                for j in range(k + 1, n):
                    a[i, j] -= f * a[k, j]
    return True


@njit(cache=True)
def _lu_solve(a: np.ndarray, piv: np.ndarray, b: np.ndarray) -> None:
    """Solve in place with the factors of :func:`_lu_factor`."""
    n = a.shape[0]
    for k in range(n):
        m = piv[k]
        if m != k:
            tmp = b[k]
            b[k] = b[m]
            b[m] = tmp
    for i in range(n):
        s = b[i]
        for j in range(i):
            s -= a[i, j] * b[j]
        b[i] = s
    for i in range(n - 1, -1, -1):
        s = b[i]
        for j in range(i + 1, n):
            s -= a[i, j] * b[j]
        b[i] = s / a[i, i]


@dataclass(frozen=True)
class StageParam:
    """One parameter of a loop stage: its name in :class:`LoopSettings`, its unit (an SI
    expression, checked here, or ``reading``: the feedback sensor's unit, ``command``: the
    controller output's, ``input``: the plant input's), what it is, and how it is read
    from a rig. ``compiled`` False: used before the loop (the noise is drawn in
    :func:`~fuzzyservo.simulation.closed_loop.prepare`), not passed to it."""

    name: str
    unit: str
    doc: str
    read: Callable[[Any], float]
    kind: type = float
    compiled: bool = True

    def __post_init__(self) -> None:
        if self.unit not in _STAGE_UNIT_TOKENS:
            parse_unit(self.unit)  # raises on a misspelled unit, at import


@dataclass(frozen=True)
class LoopStage:
    """One stage of the sampled loop, declared once: its parameters, or the input effect
    (:data:`~fuzzyservo.components.effects.LIBRARY`) whose parameters ride in the packed
    plant vector, and what it does."""

    name: str
    doc: str
    params: tuple[StageParam, ...] = ()
    effect: str = ""

    def __post_init__(self) -> None:
        if self.effect and LIBRARY[self.effect].stage != "input":
            raise ValueError(f"loop stage {self.name!r}: {self.effect!r} is not an input effect")


_STAGE_UNIT_TOKENS = ("reading", "reading/state", "command", "input", "input/command")

# The loop's chain from plant state to plant input, in order. Its parameters are the
# fields of LoopSettings; the input effects' are in the plant's packed vector (E).
LOOP_STAGES = (
    LoopStage("sensor", "reading y = offset + gain·x[index] of the feedback sensor", (
        StageParam("sensor_index", "1", "state the sensor reads",
                   lambda rig: rig.plant.states.index(rig.feedback.signal), kind=int),
        StageParam("sensor_offset", "reading", "reading at state 0",
                   lambda rig: rig.feedback.offset),
        StageParam("sensor_gain", "reading/state", "reading per state unit",
                   lambda rig: rig.feedback.slope),
    )),
    LoopStage("sensor_noise", "y += σ·N(0, 1), one draw per sample, seeded", (
        StageParam("noise_std", "reading", "standard deviation σ",
                   lambda rig: rig.feedback.noise_std, compiled=False),
    )),
    LoopStage("adc", "y to the nearest code lo + c·step, clipped to lo .. hi (step 0: off)", (
        StageParam("adc_lo", "reading", "lowest code", lambda rig: rig.feedback.adc_lower),
        StageParam("adc_hi", "reading", "top of the range", lambda rig: rig.feedback.adc_upper),
        StageParam("adc_step", "reading", "code step (0: no ADC)",
                   lambda rig: rig.feedback.adc_step),
    )),
    LoopStage("sample_and_hold", "the controller runs every dt; its output is held", (
        StageParam("dt", "s", "sample time", lambda rig: rig.sample_time_s),
    )),
    LoopStage("current_limit", "a = clip(gain·u, lo, hi): the actuator's amplifier", (
        StageParam("act_gain", "input/command", "plant input per command unit",
                   lambda rig: rig.actuator.gain),
        StageParam("act_lo", "input", "lower limit", lambda rig: rig.actuator.lower),
        StageParam("act_hi", "input", "upper limit", lambda rig: rig.actuator.upper),
    )),
    LoopStage("io_delay", "a(t − d_io): computation and conversion, sample to actuator", (
        StageParam("io_delay_s", "s", "I/O delay d_io", lambda rig: rig.io_delay_s),
    )),
    LoopStage("transport_delay", "a(t − d): bus and converter delay", effect="transport_delay"),
    LoopStage("null_bias", "a + b: a null bias beyond the declared one", effect="valve_bias"),
    LoopStage("spool_lag", "τ1·τ2·s̈ + τ1·ṡ + s = a + b: the spool (τ2 = 0: first order)", effect="valve_lag"),
    LoopStage("dead_band", "spool overlap around the null", effect="valve_deadband"),
)  # fmt: skip

# LoopSettings: the compiled stages' parameters by name (numba reads a namedtuple at no
# cost), then the integrator's local-error tolerance ``tol``.
LoopSettings = NamedTuple(
    "LoopSettings",
    [(p.name, p.kind) for stage in LOOP_STAGES for p in stage.params if p.compiled]
    + [("tol", float)],
)


@njit(cache=True)
def sample(
    ctrl: int,
    cp: np.ndarray,
    cs: np.ndarray,
    r: float,
    x: np.ndarray,
    s: LoopSettings,
    noise: float,
) -> tuple[float, float, float, bool]:
    """One controller sample: measure (with sensor ``noise`` added, then quantised),
    control (the step kernel at address ``ctrl``, :func:`.binding.controller_entry`), limit. Returns ``(y, u, a, saturated)``, ``y`` the reading the controller saw.

    ``saturated`` is true when ``a`` sits at either limit (to 1e-9 of its magnitude,
    whatever the limit's sign). Updates the controller state ``cs`` in place.
    """
    y = adc(
        s.sensor_offset + s.sensor_gain * x[s.sensor_index] + noise, s.adc_lo, s.adc_hi, s.adc_step
    )
    u = call_step(ctrl, cp, cs, r, y)
    a = s.act_gain * u
    if a > s.act_hi:
        a = s.act_hi
    elif a < s.act_lo:
        a = s.act_lo
    hi_edge = s.act_hi - 1e-9 * abs(s.act_hi)
    lo_edge = s.act_lo + 1e-9 * abs(s.act_lo)
    return y, u, a, a >= hi_edge or a <= lo_edge


@njit(cache=True)
def delay_split(p: np.ndarray, s: LoopSettings) -> tuple[int, float]:
    """The ``io_delay`` and ``transport_delay`` stages together as ``(whole samples,
    fraction of a sample)``: two pure delays in series, exact within the zero-order hold;
    fractions within 1e-9 of a whole sample round to it."""
    delay = (p[E.transport_delay_s] + s.io_delay_s) / s.dt
    whole = int(delay)
    part = delay - whole
    if part < 1e-9:
        part = 0.0
    elif part > 1.0 - 1e-9:
        whole += 1
        part = 0.0
    return whole, part


@njit(cache=True)
def held_inputs(actuator: np.ndarray, k: int, whole: int) -> tuple[float, float]:
    """The held values the plant sees in interval ``k`` under ``transport_delay``: that of
    sample k − whole − 1 (first ``part`` of the interval), then that of k − whole."""
    return actuator[max(k - whole - 1, 0)], actuator[max(k - whole, 0)]


@njit(cache=True)
def spool_states(p: np.ndarray) -> int:
    """How many states ``valve_lag`` appends to the plant's: none when off, the spool's
    position for a first-order spool, its position and velocity for a second-order one."""
    if p[E.valve_lag_s] <= 0.0:
        return 0
    return 2 if p[E.valve_lag2_s] > 0.0 else 1


@njit(cache=True)
def spool_start(p: np.ndarray, a: float) -> float:
    """Where ``valve_lag``'s spool starts: at the first held value plus ``valve_bias``
    (at rest: a second-order spool's velocity starts at 0)."""
    return a + p[E.valve_bias_si]


@njit(cache=True, inline="always")
def input_stage(x: np.ndarray, a: float, p: np.ndarray, null: float, dx: np.ndarray) -> float:
    """The plant input behind the input effects, for held actuator value ``a``.

    Without ``valve_lag`` it is ``dz(a + b)``; with it, the states after the plant's are
    the spool ``s`` (first order, ``τ1·ds/dt = a + b − s``; second order, ``s`` and its
    velocity ``v``, ``τ1·τ2·dv/dt = a + b − s − τ1·v``, written to ``dx``) and the input
    is ``dz(s)``, where ``b`` is ``valve_bias`` and ``dz`` the ``valve_deadband`` around
    ``null``.
    """
    tau = p[E.valve_lag_s]
    if tau > 0.0:
        tau2 = p[E.valve_lag2_s]
        if tau2 > 0.0:
            n = x.size - 2
            s = x[n]
            v = x[n + 1]
            dx[n] = v
            dx[n + 1] = (a + p[E.valve_bias_si] - s - tau * v) / (tau * tau2)
        else:
            n = x.size - 1
            s = x[n]
            dx[n] = (a + p[E.valve_bias_si] - s) / tau
        return deadband(s, null, p[E.valve_deadband_si])
    return deadband(a + p[E.valve_bias_si], null, p[E.valve_deadband_si])


@njit(cache=True)
def plant_states(x: np.ndarray, p: np.ndarray) -> int:
    """How many of ``x`` are the plant's (``valve_lag`` appends the spool's)."""
    return x.size - spool_states(p)


@njit(cache=True)
def workspace(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Scratch arrays for the integrator on a system of ``n`` states."""
    return np.empty((_STAGES + 4, n)), np.empty((2, n, n)), np.empty(n, dtype=np.int64)
