"""The compiled closed loop: a sampled controller with zero-order hold against a stiff plant.

The plant is integrated between samples by an adaptive linearly implicit
Rosenbrock method, the 2(3) pair of MATLAB's ``ode23s`` (Shampine & Reichelt, "The
MATLAB ODE Suite", SIAM J. Sci. Comput. 18, 1997, §3.1), with a finite-difference
Jacobian. It is L-stable, so the stiff valve-chamber modes of seed 002 (β/V·K/√p_lam
up to ~1e6 1/s, MODELLING.md "Stiffness") cost no step-size restriction, and the
error estimate keeps the slow piston motion accurate. Nothing in here raises: a
failure ends the run with a status code the caller turns into a result.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from fuzzyservo.controllers.kernels import controller_step
from fuzzyservo.plants.kernels import plant_in_end_stop, plant_rhs

STATUS_OK = 0
STATUS_DIVERGED = 1
STATUS_END_STOP = 2
STATUS_STEP_FAILURE = 3

_D = 1.0 / (2.0 + math.sqrt(2.0))
_E32 = 6.0 + math.sqrt(2.0)
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


@njit(cache=True)
def integrate_interval(
    kind: int,
    p: np.ndarray,
    x: np.ndarray,
    u: float,
    load: float,
    duration: float,
    h: float,
    tol: float,
    scale: np.ndarray,
    typical: np.ndarray,
) -> tuple[int, float, int]:
    """Advance ``x`` in place over ``duration`` seconds with constant input ``u`` and load.

    Returns ``(status, h_next, steps)``; ``h`` is the proposed first step. The local
    error of each state is kept below ``tol·scale[i]`` (absolute units per state).
    """
    n = x.size
    f0 = np.empty(n)
    f1 = np.empty(n)
    f2 = np.empty(n)
    k1 = np.empty(n)
    k2 = np.empty(n)
    k3 = np.empty(n)
    xs = np.empty(n)
    xn = np.empty(n)
    ftmp = np.empty(n)
    jac = np.empty((n, n))
    w = np.empty((n, n))
    piv = np.empty(n, dtype=np.int64)

    t = 0.0
    steps = 0
    h = min(h, duration)
    h_min = 1e-14 * duration
    plant_rhs(kind, x, u, load, p, f0)
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
                plant_rhs(kind, x, u, load, p, ftmp)
                x[j] = xj
                for i in range(n):
                    jac[i, j] = (ftmp[i] - f0[i]) / dj
            need_jac = False
            jac_fresh = True
        hd = h_step * _D
        for i in range(n):
            for j in range(n):
                w[i, j] = -hd * jac[i, j]
            w[i, i] += 1.0
        if not _lu_factor(w, piv):
            return STATUS_DIVERGED, h, steps
        for i in range(n):
            k1[i] = f0[i]
        _lu_solve(w, piv, k1)
        for i in range(n):
            xs[i] = x[i] + 0.5 * h_step * k1[i]
        plant_rhs(kind, xs, u, load, p, f1)
        for i in range(n):
            k2[i] = f1[i] - k1[i]
        _lu_solve(w, piv, k2)
        for i in range(n):
            k2[i] += k1[i]
            xn[i] = x[i] + h_step * k2[i]
        plant_rhs(kind, xn, u, load, p, f2)
        for i in range(n):
            k3[i] = f2[i] - _E32 * (k2[i] - f1[i]) - 2.0 * (k1[i] - f0[i])
        _lu_solve(w, piv, k3)
        err = 0.0
        finite = True
        for i in range(n):
            e = abs(h_step / 6.0 * (k1[i] - 2.0 * k2[i] + k3[i])) / (tol * scale[i])
            if not math.isfinite(xn[i]) or not math.isfinite(e):
                finite = False
            elif e > err:
                err = e
        steps += 1
        if finite and err <= 1.0:
            t += h_step
            for i in range(n):
                x[i] = xn[i]
                f0[i] = f2[i]
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
    Fills ``states[k]``, ``command[k]``, ``actuator[k]``, ``saturated[k]`` and returns
    ``(status, sample of the first problem or -1, integration steps)``. After a
    failure the remaining samples are NaN.
    """
    n = ref.size
    x = x0.copy()
    h = dt * 1e-3
    status = STATUS_OK
    where = -1
    total = 0
    hi_edge = act_hi - 1e-9 * abs(act_hi)
    lo_edge = act_lo + 1e-9 * abs(act_lo)
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
        code, h, steps = integrate_interval(
            plant_kind, p, x, a, load[k], dt, h, tol, scale, typical
        )
        total += steps
        if code != STATUS_OK:
            status = code
            where = k
            break
        if status == STATUS_OK and plant_in_end_stop(plant_kind, x, p):
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
