"""The compiled closed loop, compiled once per install for every plant: it calls the
plant's kernels through the addresses in its kernel table ``fn`` (:mod:`._calls`;
:mod:`.binding` compiles a plant's kernels and makes the table).

The plant is integrated between samples by an adaptive linearly implicit
Rosenbrock-W method, ROS34PW2 (order 3, embedded order 2), with a finite-difference
Jacobian (:func:`loop_jacobian`) evaluated at the start of each control interval and
refreshed when a step is rejected (tableau, in transformed variables, and linear algebra in
:mod:`fuzzyservo.simulation._loop`). It is
L-stable, so the stiff valve-chamber modes of seed 002 (β/V·K/√p_lam up to ~1e6 1/s,
docs/modelling.md "Stiffness") cost no step-size restriction. Nothing in here raises: a
failure ends the run with a status code the caller turns into a result.
"""

from __future__ import annotations

import math

import numpy as np
from numba import prange

from fuzzyservo._jit import njit
from fuzzyservo.components.effects import E
from fuzzyservo.simulation._calls import (
    ADVANCE,
    END_STOP,
    JACOBIAN,
    RHS,
    SIGNALS,
    call_advance,
    call_end_stop,
    call_jacobian,
    call_rhs,
    call_signals,
)
from fuzzyservo.simulation._loop import (
    _A_U,
    _C_U,
    _E_U,
    _GAMMA,
    _M_U,
    _MAX_STEPS_PER_INTERVAL,
    _STAGES,
    STATUS_DIVERGED,
    STATUS_END_STOP,
    STATUS_OK,
    STATUS_STEP_FAILURE,
    LoopSettings,
    _lu_factor,
    _lu_solve,
    delay_split,
    held_inputs,
    input_stage,
    plant_states,
    sample,
    spool_start,
    workspace,
)


@njit(cache=True)
def plant_jacobian(
    fn: np.ndarray,
    x: np.ndarray,
    u: float,
    load: float,
    p: np.ndarray,
    f0: np.ndarray,
    typical: np.ndarray,
    jac: np.ndarray,
    ftmp: np.ndarray,
) -> None:
    """``f0 = f(x)`` and ``jac[i, j] = (f_i(x + δ_j·e_j) − f0_i)/δ_j`` of the plant's
    right-hand side ``f``, ``δ_j = √ε·max(|x_j|, typical_j)``: the plant's own Jacobian
    kernel where it has one (a composition's re-runs only the statements each state
    reaches and gives the same numbers, plants/_jacobian.py), else one whole ``f`` per
    column."""
    if fn[JACOBIAN] != 0:
        call_jacobian(fn[JACOBIAN], x, u, load, p, f0, typical, jac, ftmp)
        return
    n = x.size
    call_rhs(fn[RHS], x, u, load, p, f0)
    for j in range(n):
        xj = x[j]
        dj = 1.4901161193847656e-08 * max(abs(xj), typical[j])
        x[j] = xj + dj
        call_rhs(fn[RHS], x, u, load, p, ftmp)
        x[j] = xj
        for i in range(n):
            jac[i, j] = (ftmp[i] - f0[i]) / dj


@njit(cache=True)
def loop_rhs(
    fn: np.ndarray, x: np.ndarray, a: float, load: float, p: np.ndarray, null: float, dx: np.ndarray
) -> None:
    """dx/dt of the plant behind the input effects (:func:`_loop.input_stage`), for held
    actuator value ``a``. The plant reads and writes the leading entries of ``x`` and
    ``dx``, its own states (the input stage's spool follows them), so it gets the whole
    arrays: a view of each, made on every call, costs as much as a tenth of a step."""
    u = input_stage(x, a, p, null, dx)
    call_rhs(fn[RHS], x, u, load, p, dx)


@njit(cache=True)
def loop_jacobian(
    fn: np.ndarray,
    x: np.ndarray,
    a: float,
    load: float,
    p: np.ndarray,
    null: float,
    f0: np.ndarray,
    typical: np.ndarray,
    jac: np.ndarray,
    ftmp: np.ndarray,
) -> None:
    """:func:`loop_rhs` at ``x`` into ``f0``, and its forward-difference Jacobian there,
    column ``j`` with the increment ``δ_j = √ε·max(|x_j|, typical_j)``.

    A plant state does not reach the input stage, so the plant's block is
    :func:`plant_jacobian` at the input that stage gives, and the spool's row there
    (``valve_lag``) is ``(f0 − f0)/δ_j``: the zero (or NaN) its difference gives. The
    spool's own column takes a whole :func:`loop_rhs`.
    """
    n = plant_states(x, p)
    v = input_stage(x, a, p, null, f0)
    plant_jacobian(fn, x[:n], v, load, p, f0, typical, jac, ftmp)
    for j in range(n):
        dj = 1.4901161193847656e-08 * max(abs(x[j]), typical[j])
        for i in range(n, x.size):
            jac[i, j] = (f0[i] - f0[i]) / dj
    for j in range(n, x.size):
        xj = x[j]
        dj = 1.4901161193847656e-08 * max(abs(xj), typical[j])
        x[j] = xj + dj
        loop_rhs(fn, x, a, load, p, null, ftmp)
        x[j] = xj
        for i in range(x.size):
            jac[i, j] = (ftmp[i] - f0[i]) / dj


@njit(cache=True)
def integrate_interval(
    fn: np.ndarray,
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
    null input ``null``). Returns ``(status, h_next, steps)``; ``h`` is the proposed first step,
    ``h_next`` the one for the next interval: the step proposed after this interval's first. The local
    error of each state is kept below ``tol·scale[i]`` (absolute units per state).
    ``work``, ``mats`` and ``piv`` are scratch space from :func:`workspace`, allocated
    once per run rather than once per interval.

    Stage equations in transformed variables ``u_i = Σ_j γ_ij·k_j`` (Hairer & Wanner,
    Solving ODEs II, §IV.7, eq. 7.25, autonomous form; constants in :mod:`_loop`):
    ``(I/(hγ) − J)·u_i = f(x + Σ_j a_ij·u_j) + Σ_j c_ij·u_j / h``, ``x1 = x + Σ m_i·u_i``.

    A plant with its own solver (a co-simulation FMU: its table's ``ADVANCE`` slot) is
    stepped instead, one step: 1 when done, 0 when it failed.
    """
    if fn[ADVANCE] != 0:
        v = input_stage(x, u, p, null, work[_STAGES])
        stepped = call_advance(fn[ADVANCE], x, v, load, p, duration)
        return (STATUS_OK if stepped == 1 else STATUS_STEP_FAILURE), h, 1
    n = x.size
    u_st = work[:_STAGES]
    f0 = work[_STAGES]
    xs = work[_STAGES + 1]
    xn = work[_STAGES + 2]
    ftmp = work[_STAGES + 3]
    jac = mats[0]
    w = mats[1]

    t = 0.0
    steps = 0
    h = min(h, duration)
    h_min = 1e-14 * duration
    # f0 = f(x) and J at x together: the Jacobian's first pass is f(x)
    loop_jacobian(fn, x, u, load, p, null, f0, typical, jac, ftmp)
    need_jac = False
    jac_fresh = True
    h_first = 0.0
    while t < duration * (1.0 - 1e-12):
        if steps >= _MAX_STEPS_PER_INTERVAL:
            return STATUS_STEP_FAILURE, h, steps
        h_step = min(h, duration - t)
        if need_jac:
            loop_jacobian(fn, x, u, load, p, null, f0, typical, jac, ftmp)
            need_jac = False
            jac_fresh = True
        h_inv = 1.0 / h_step
        diag = h_inv / _GAMMA
        for i in range(n):
            for j in range(n):
                w[i, j] = -jac[i, j]
            w[i, i] += diag
        if not _lu_factor(w, piv):
            return STATUS_DIVERGED, h, steps
        for i in range(n):
            u_st[0, i] = f0[i]
        _lu_solve(w, piv, u_st[0])
        for st in range(1, _STAGES):
            for i in range(n):
                acc = x[i]
                for j in range(st):
                    acc += _A_U[st, j] * u_st[j, i]
                xs[i] = acc
            loop_rhs(fn, xs, u, load, p, null, ftmp)
            for i in range(n):
                acc = 0.0
                for j in range(st):
                    acc += _C_U[st, j] * u_st[j, i]
                u_st[st, i] = ftmp[i] + acc * h_inv
            _lu_solve(w, piv, u_st[st])
        err = 0.0
        finite = True
        for i in range(n):
            acc = x[i]
            e = 0.0
            for st in range(_STAGES):
                acc += _M_U[st] * u_st[st, i]
                e += _E_U[st] * u_st[st, i]
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
            if t < duration * (1.0 - 1e-12):
                # f at the next step's start (none after the last: the next interval
                # starts from its own input)
                loop_rhs(fn, x, u, load, p, null, f0)
            jac_fresh = False
            fac = 5.0 if err == 0.0 else min(5.0, max(0.2, 0.8 * err ** (-1.0 / 3.0)))
            if h_step < h:
                # a step cut short to land on the sample time says little about h
                if fac < 1.0:
                    h = min(h, h_step * fac)
            else:
                h = min(h_step * fac, duration)
            if h_first == 0.0:
                # the next interval starts after a command jump too: it begins with the
                # step this one proposed after its first, not the one its end settled on
                h_first = h
        else:
            if not jac_fresh:
                # retry with the Jacobian at this state before cutting the step
                need_jac = True
                continue
            fac = 0.2 if not finite else max(0.2, 0.8 * err ** (-1.0 / 3.0))
            h = h_step * fac
            if h < h_min:
                return STATUS_DIVERGED, h, steps
    return STATUS_OK, h_first if h_first > 0.0 else h, steps


@njit(cache=True, nogil=True)
def closed_loop(
    fn: np.ndarray,
    p: np.ndarray,
    null: float,
    x0: np.ndarray,
    ctrl: int,
    cp: np.ndarray,
    cs: np.ndarray,
    ref: np.ndarray,
    load: np.ndarray,
    noise: np.ndarray,
    s: LoopSettings,
    scale: np.ndarray,
    typical: np.ndarray,
    states: np.ndarray,
    measured: np.ndarray,
    command: np.ndarray,
    actuator: np.ndarray,
    saturated: np.ndarray,
    reset_at: np.ndarray,
    reset_idx: np.ndarray,
    reset_val: np.ndarray,
) -> tuple[int, int, int]:
    """Run the sampled loop over ``ref.size`` control intervals of ``s.dt`` seconds.

    At sample k: :func:`_loop.sample` (measure with ``noise[k]`` added, control,
    limit; the reading goes to ``measured[k]``), then the held value
    is applied (zero-order hold, behind ``transport_delay``) while the plant is
    integrated to the next sample. ``x0`` carries one more state than the plant when
    ``valve_lag`` is on: the spool, which starts where the first command puts it.
    ``actuator`` records the value the controller commanded, before the input effects.
    Fills ``states[k]``, ``command[k]``, ``actuator[k]``, ``saturated[k]`` and returns
    ``(status, sample of the first problem or -1, integration steps)``. After a
    failure the remaining samples are NaN. It releases the GIL, so runs in Python
    threads go side by side (:func:`fuzzyservo.analysis.margins.margins`).

    Resets (a segmented replay, calibration/segments.py): before sample
    ``reset_at[m]`` (increasing), state ``reset_idx[j]`` is set to ``reset_val[m, j]``
    where that is finite; the other states run on from where the loop has them.
    """
    n = ref.size
    x = x0.copy()
    work, mats, piv = workspace(x.size)
    dt = s.dt
    h = dt * 1e-3
    status = STATUS_OK
    where = -1
    total = 0
    lag = p[E.valve_lag_s] > 0.0
    n_plant = plant_states(x, p)
    whole, part = delay_split(p, s)
    next_reset = 0
    for k in range(n):
        if next_reset < reset_at.size and reset_at[next_reset] == k:
            for j in range(reset_idx.size):
                if math.isfinite(reset_val[next_reset, j]):
                    x[reset_idx[j]] = reset_val[next_reset, j]
            next_reset += 1
        for i in range(x.size):
            states[k, i] = x[i]
        y, u, a, sat = sample(ctrl, cp, cs, ref[k], x, s, noise[k])
        measured[k] = y
        command[k] = u
        actuator[k] = a
        saturated[k] = sat
        if not math.isfinite(a):
            status = STATUS_DIVERGED
            where = k
            break
        if k == 0 and lag:
            x[n_plant] = spool_start(p, a)
            states[0, n_plant] = x[n_plant]
        a_before, a_now = held_inputs(actuator, k, whole)
        code = STATUS_OK
        if part > 0.0:
            code, h, steps = integrate_interval(
                fn, p, null, x, a_before, load[k], part * dt, h, s.tol, scale, typical,
                work, mats, piv,
            )  # fmt: skip
            total += steps
        if code == STATUS_OK:
            code, h, steps = integrate_interval(
                fn, p, null, x, a_now, load[k], (1.0 - part) * dt, h, s.tol, scale,
                typical, work, mats, piv,
            )  # fmt: skip
            total += steps
        if code != STATUS_OK:
            status = code
            where = k
            break
        if status == STATUS_OK and call_end_stop(fn[END_STOP], x[:n_plant], p) != 0:
            status = STATUS_END_STOP
            where = k + 1
    if status == STATUS_DIVERGED or status == STATUS_STEP_FAILURE:
        for k in range(where + 1, n):
            for i in range(x.size):
                states[k, i] = np.nan
            measured[k] = np.nan
            command[k] = np.nan
            actuator[k] = np.nan
            saturated[k] = False
    return status, where, total


@njit(cache=True, parallel=True)
def closed_loop_batch(
    fn: np.ndarray,
    p: np.ndarray,
    null: np.ndarray,
    x0: np.ndarray,
    ctrl: int,
    cp: np.ndarray,
    cs: np.ndarray,
    ref: np.ndarray,
    load: np.ndarray,
    noise: np.ndarray,
    settings: list[LoopSettings],
    scale: np.ndarray,
    typical: np.ndarray,
    states: np.ndarray,
    measured: np.ndarray,
    command: np.ndarray,
    actuator: np.ndarray,
    saturated: np.ndarray,
    out: np.ndarray,
) -> None:
    """:func:`closed_loop` of one controller on many plants at once: row ``b`` of every
    array but ``cp``, ``ref`` and ``load`` (shared) is plant sample ``b`` (its packed
    parameters, null, start, controller state, noise, tolerances and the recorded
    signals), ``settings[b]`` its loop settings (a sampled I/O delay, a scaled actuator);
    ``out[b]`` gets its ``(status, where, steps)``. The samples run in parallel over the
    cores (numba ``prange``), each exactly as :func:`closed_loop` runs it alone."""
    no_resets = np.empty(0, dtype=np.int64)
    no_values = np.empty((0, 0))
    for b in prange(p.shape[0]):
        s = settings[np.int64(b)]  # prange counts unsigned; a typed list wants a signed index
        status, where, steps = closed_loop(
            fn, p[b], null[b], x0[b], ctrl, cp, cs[b], ref, load, noise[b], s,
            scale[b], typical[b], states[b], measured[b], command[b], actuator[b],
            saturated[b], no_resets, no_resets, no_values,
        )  # fmt: skip
        out[b, 0] = status
        out[b, 1] = where
        out[b, 2] = steps


@njit(cache=True)
def signal_table(
    fn: np.ndarray,
    states: np.ndarray,
    inputs: np.ndarray,
    loads: np.ndarray,
    p: np.ndarray,
    out: np.ndarray,
) -> None:
    """Signals of every recorded sample (rows of ``states``); rows with a NaN state stay NaN."""
    row = np.empty(out.shape[1])
    for k in range(states.shape[0]):
        finite = True
        for i in range(states.shape[1]):
            if not math.isfinite(states[k, i]):
                finite = False
        if finite:
            call_signals(fn[SIGNALS], states[k], inputs[k], loads[k], p, row)
        for j in range(out.shape[1]):  # by element: a slice assignment compiles 2 s more
            out[k, j] = row[j] if finite else np.nan


@njit(cache=True)
def rhs_with_inputs(
    fn: np.ndarray, x: np.ndarray, a: float, load: float, p: np.ndarray, null: float
) -> np.ndarray:
    """:func:`loop_rhs` as a function (the reference path's right-hand side)."""
    dx = np.empty(x.size)
    loop_rhs(fn, x, a, load, p, null, dx)
    return dx


@njit(cache=True)
def in_end_stop(fn: np.ndarray, x: np.ndarray, p: np.ndarray) -> bool:
    """True when the plant part of ``x`` sits beyond a mechanical end stop."""
    return call_end_stop(fn[END_STOP], x[: plant_states(x, p)], p) != 0
