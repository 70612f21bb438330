"""The compiled closed loop: a sampled controller with zero-order hold against a stiff plant.

The plant is integrated between samples by an adaptive linearly implicit
Rosenbrock-W method, ROS34PW2 (order 3, embedded order 2), with a finite-difference
Jacobian evaluated at the start of each control interval and refreshed when a step is
rejected. It is L-stable, so the stiff valve-chamber modes of seed 002 (β/V·K/√p_lam
up to ~1e6 1/s, docs/modelling.md "Stiffness") cost no step-size restriction, and the
error estimate keeps the slow piston motion accurate. On the seed-002 pulses it needs
40 % fewer steps than MATLAB's ode23s pair (tried first) for the same accuracy.
Nothing in here raises: a failure ends the run with a status code the caller turns
into a result.

Input effects (components/effects.py) sit between the held actuator value and the
plant: ``transport_delay`` shifts the held sequence in time (an interval is integrated
in two parts where the delayed input switches), ``valve_bias`` adds to it,
``valve_lag`` appends one state (the spool, ``τ·ds/dt = a + b − s``) to the plant's,
and ``valve_deadband`` maps the spool onto the plant input around its null.
"""

from __future__ import annotations

import math

import numpy as np

from fuzzyservo._jit import njit
from fuzzyservo.components.effects import E_BIAS, E_DEADBAND, E_DELAY, E_LAG, deadband
from fuzzyservo.controllers.kernels import controller_step
from fuzzyservo.plants.kernels import plant_in_end_stop, plant_rhs

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
_E = _B - _B_EMBEDDED
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


@njit(cache=True, inline="always")
def loop_rhs(
    kind: int, x: np.ndarray, a: float, load: float, p: np.ndarray, null: float, dx: np.ndarray
) -> None:
    """dx/dt of the plant behind the input effects, for held actuator value ``a``.

    Without ``valve_lag`` the plant input is ``dz(a + b)``; with it, the last state is
    the spool ``s`` (``ds/dt = (a + b − s)/τ``) and the plant input is ``dz(s)``, where
    ``b`` is ``valve_bias`` and ``dz`` the ``valve_deadband`` around ``null``.
    """
    tau = p[E_LAG]
    if tau > 0.0:
        n = x.size - 1
        s = x[n]
        dx[n] = (a + p[E_BIAS] - s) / tau
        plant_rhs(kind, x[:n], deadband(s, null, p[E_DEADBAND]), load, p, dx[:n])
    else:
        plant_rhs(kind, x, deadband(a + p[E_BIAS], null, p[E_DEADBAND]), load, p, dx)


@njit(cache=True)
def workspace(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Scratch arrays for :func:`integrate_interval` on a system of ``n`` states."""
    return np.empty((_STAGES + 5, n)), np.empty((2, n, n)), np.empty(n, dtype=np.int64)


@njit(cache=True)
def integrate_interval(
    kind: int,
    p: np.ndarray,
    null: float,
    x: np.ndarray,
    u: float,
    load: float,
    duration: float,
    h: float,
    tol: float,
    scale: np.ndarray,
    typical: np.ndarray,
    work: np.ndarray,
    mats: np.ndarray,
    piv: np.ndarray,
) -> tuple[int, float, int]:
    """Advance ``x`` in place over ``duration`` seconds with constant input ``u`` and load.

    ``u`` is the actuator value before the input effects (:func:`loop_rhs`, plant
    null input ``null``). Returns ``(status, h_next, steps)``; ``h`` is the proposed first step. The local
    error of each state is kept below ``tol·scale[i]`` (absolute units per state).
    ``work``, ``mats`` and ``piv`` are scratch space from :func:`workspace`, allocated
    once per run rather than once per interval.

    Stage equations (Hairer & Wanner, Solving ODEs II, §IV.7, autonomous form):
    ``(I − hγJ)·k_i = h·f(x + Σ_j a_ij k_j) + h·J·Σ_j γ_ij k_j``, ``x1 = x + Σ b_i k_i``.
    """
    n = x.size
    k = work[:_STAGES]
    f0 = work[_STAGES]
    xs = work[_STAGES + 1]
    xn = work[_STAGES + 2]
    ftmp = work[_STAGES + 3]
    gk = work[_STAGES + 4]
    jac = mats[0]
    w = mats[1]

    t = 0.0
    steps = 0
    h = min(h, duration)
    h_min = 1e-14 * duration
    loop_rhs(kind, x, u, load, p, null, f0)
    need_jac = True
    jac_fresh = False
    while t < duration * (1.0 - 1e-12):
        if steps >= _MAX_STEPS_PER_INTERVAL:
            return STATUS_STEP_FAILURE, h, steps
        h_step = min(h, duration - t)
        if need_jac:
            for j in range(n):
                xj = x[j]
                dj = 1.4901161193847656e-08 * max(abs(xj), typical[j])
                x[j] = xj + dj
                loop_rhs(kind, x, u, load, p, null, ftmp)
                x[j] = xj
                for i in range(n):
                    jac[i, j] = (ftmp[i] - f0[i]) / dj
            need_jac = False
            jac_fresh = True
        hg = h_step * _GAMMA
        for i in range(n):
            for j in range(n):
                w[i, j] = -hg * jac[i, j]
            w[i, i] += 1.0
        if not _lu_factor(w, piv):
            return STATUS_DIVERGED, h, steps
        for st in range(_STAGES):
            # stage state and the J·Σγ_ij·k_j correction
            for i in range(n):
                acc = x[i]
                g = 0.0
                for j in range(st):
                    acc += _A[st, j] * k[j, i]
                    g += _G[st, j] * k[j, i]
                xs[i] = acc
                gk[i] = g
            if st == 0:
                for i in range(n):
                    ftmp[i] = f0[i]
            else:
                loop_rhs(kind, xs, u, load, p, null, ftmp)
            for i in range(n):
                acc = ftmp[i]
                if st > 0:
                    for j in range(n):
                        acc += jac[i, j] * gk[j]
                k[st, i] = h_step * acc
            _lu_solve(w, piv, k[st])
        err = 0.0
        finite = True
        for i in range(n):
            acc = x[i]
            e = 0.0
            for st in range(_STAGES):
                acc += _B[st] * k[st, i]
                e += _E[st] * k[st, i]
            xn[i] = acc
            e = abs(e) / (tol * scale[i])
            if not math.isfinite(acc) or not math.isfinite(e):
                finite = False
            elif e > err:
                err = e
        steps += 1
        if finite and err <= 1.0:
            t += h_step
            for i in range(n):
                x[i] = xn[i]
            loop_rhs(kind, x, u, load, p, null, f0)
            jac_fresh = False
            fac = 5.0 if err == 0.0 else min(5.0, max(0.2, 0.8 * err ** (-1.0 / 3.0)))
            if h_step < h:
                # a step cut short to land on the sample time says little about h
                if fac < 1.0:
                    h = min(h, h_step * fac)
            else:
                h = min(h_step * fac, duration)
        else:
            if not jac_fresh:
                # retry with the Jacobian at this state before cutting the step
                need_jac = True
                continue
            fac = 0.2 if not finite else max(0.2, 0.8 * err ** (-1.0 / 3.0))
            h = h_step * fac
            if h < h_min:
                return STATUS_DIVERGED, h, steps
    return STATUS_OK, h, steps


@njit(cache=True)
def closed_loop(
    plant_kind: int,
    p: np.ndarray,
    null: float,
    x0: np.ndarray,
    ctrl_kind: int,
    cp: np.ndarray,
    cs: np.ndarray,
    ref: np.ndarray,
    load: np.ndarray,
    dt: float,
    sensor_index: int,
    sensor_offset: float,
    sensor_gain: float,
    act_gain: float,
    act_lo: float,
    act_hi: float,
    tol: float,
    scale: np.ndarray,
    typical: np.ndarray,
    states: np.ndarray,
    command: np.ndarray,
    actuator: np.ndarray,
    saturated: np.ndarray,
) -> tuple[int, int, int]:
    """Run the sampled loop over ``ref.size`` control intervals of ``dt`` seconds.

    At sample k: measure ``y = offset + gain·x[sensor_index]``, compute
    ``u = controller(r_k, y)``, apply ``a = clip(act_gain·u, act_lo, act_hi)`` held
    constant (zero-order hold) while the plant is integrated to the next sample.
    ``x0`` carries one more state than the plant when ``valve_lag`` is on: the spool,
    which starts where the first command puts it. ``actuator`` records the value the
    controller commanded, before the input effects.
    Fills ``states[k]``, ``command[k]``, ``actuator[k]``, ``saturated[k]`` and returns
    ``(status, sample of the first problem or -1, integration steps)``. After a
    failure the remaining samples are NaN.
    """
    n = ref.size
    x = x0.copy()
    work, mats, piv = workspace(x.size)
    h = dt * 1e-3
    status = STATUS_OK
    where = -1
    total = 0
    hi_edge = act_hi - 1e-9 * abs(act_hi)
    lo_edge = act_lo + 1e-9 * abs(act_lo)
    lag = p[E_LAG] > 0.0
    n_plant = x.size - 1 if lag else x.size
    delay = p[E_DELAY] / dt
    whole = int(delay)
    part = delay - whole
    if part < 1e-9:
        part = 0.0
    elif part > 1.0 - 1e-9:
        whole += 1
        part = 0.0
    for k in range(n):
        for i in range(x.size):
            states[k, i] = x[i]
        y = sensor_offset + sensor_gain * x[sensor_index]
        u = controller_step(ctrl_kind, cp, cs, ref[k], y)
        a = act_gain * u
        if a > act_hi:
            a = act_hi
        elif a < act_lo:
            a = act_lo
        command[k] = u
        actuator[k] = a
        saturated[k] = a >= hi_edge or a <= lo_edge
        if not math.isfinite(a):
            status = STATUS_DIVERGED
            where = k
            break
        if k == 0 and lag:
            x[x.size - 1] = a + p[E_BIAS]
            states[0, x.size - 1] = x[x.size - 1]
        # transport_delay: the held value of sample k - whole - 1, then of k - whole
        a_now = actuator[max(k - whole, 0)]
        code = STATUS_OK
        if part > 0.0:
            a_before = actuator[max(k - whole - 1, 0)]
            code, h, steps = integrate_interval(
                plant_kind, p, null, x, a_before, load[k], part * dt, h, tol, scale, typical,
                work, mats, piv,
            )  # fmt: skip
            total += steps
        if code == STATUS_OK:
            code, h, steps = integrate_interval(
                plant_kind, p, null, x, a_now, load[k], (1.0 - part) * dt, h, tol, scale,
                typical, work, mats, piv,
            )  # fmt: skip
            total += steps
        if code != STATUS_OK:
            status = code
            where = k
            break
        if status == STATUS_OK and plant_in_end_stop(plant_kind, x[:n_plant], p):
            status = STATUS_END_STOP
            where = k + 1
    if status == STATUS_DIVERGED or status == STATUS_STEP_FAILURE:
        for k in range(where + 1, n):
            for i in range(x.size):
                states[k, i] = np.nan
            command[k] = np.nan
            actuator[k] = np.nan
            saturated[k] = False
    return status, where, total
