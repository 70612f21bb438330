"""The loop with a controller that is not compiled (an FMU): sample by sample in Python.

Each sample does what the compiled loop (``_plant_loop.closed_loop``) does, with the
same compiled pieces: the feedback reading (:func:`_loop.sample` of a pass-through
controller, so sensor noise, ADC and actuator mapping are the loop's own), the command
from the controller's :meth:`step`, the limit and the actuator, and the plant
integrated over the interval by the plant loop's compiled Rosenbrock integrator behind
the same delays. A native controller run this way gives the compiled loop's numbers.
"""

from __future__ import annotations

import math

import numpy as np

from fuzzyservo.components.effects import E
from fuzzyservo.controllers.base import Controller
from fuzzyservo.controllers.classical import OpenLoop
from fuzzyservo.rig import Rig, Scenario
from fuzzyservo.simulation import _loop
from fuzzyservo.simulation.closed_loop import (
    _STATUS,
    DEFAULT_TOL,
    assemble,
    loop_settings,
    prepare,
)
from fuzzyservo.simulation.result import SimResult

__all__ = ["simulate_stepped"]


def simulate_stepped(
    rig: Rig,
    controller: Controller,
    scenario: str | Scenario | None = None,
    *,
    duration_s: float | None = None,
    tol: float = DEFAULT_TOL,
    noise: bool | None = None,
    noise_seed: int = 0,
) -> SimResult:
    """:func:`~fuzzyservo.simulation.simulate` with ``controller.step`` called from Python
    at every sample (its state from ``controller.init``)."""
    prep = prepare(rig, controller, scenario, duration_s, noise=noise, noise_seed=noise_seed)
    c = prep.controller
    loop, p, settings = rig.plant.loop, prep.p, loop_settings(rig, tol)
    dt = rig.sample_time_s
    n, x = prep.t.size, prep.x0.copy()
    states = np.full((n, x.size), np.nan)
    measured, command, actuator = np.full(n, np.nan), np.full(n, np.nan), np.full(n, np.nan)
    saturated = np.zeros(n, dtype=np.bool_)
    work, mats, piv = _loop.workspace(x.size)
    # a pass-through (u = r) inside the controller's limits: the loop's own sample stage
    cp, cs = OpenLoop(gain=1.0, u_min=c.u_min, u_max=c.u_max).init(dt)
    state = c.init(dt)
    h, status, where, total = dt * 1e-3, _loop.STATUS_OK, -1, 0
    lag = p[E.valve_lag_s] > 0.0
    whole, part = _loop.delay_split(p, settings)
    try:
        for k in range(n):
            states[k] = x
            y = _loop.sample(OpenLoop.kind, cp, cs, 0.0, x, settings, prep.noise[k])[0]
            u, state = c.step(state, prep.ref[k], y)
            y, u, a, sat = _loop.sample(OpenLoop.kind, cp, cs, u, x, settings, prep.noise[k])
            measured[k], command[k], actuator[k], saturated[k] = y, u, a, sat
            if not math.isfinite(a):
                status, where = _loop.STATUS_DIVERGED, k
                break
            if k == 0 and lag:
                x[-1] = states[0, -1] = _loop.spool_start(p, a)
            a_before, a_now = _loop.held_inputs(actuator, k, whole)
            code = _loop.STATUS_OK
            for held, span in ((a_before, part * dt), (a_now, (1.0 - part) * dt)):
                if span > 0.0 and code == _loop.STATUS_OK:
                    code, h, steps = loop.integrate_interval(
                        p, prep.null, x, held, prep.load[k], span, h, settings.tol,
                        prep.scale, prep.typical, work, mats, piv,
                    )  # fmt: skip
                    total += steps
            if code != _loop.STATUS_OK:
                status, where = code, k
                break
            if status == _loop.STATUS_OK and loop.in_end_stop(x, p):
                status, where = _loop.STATUS_END_STOP, k + 1
    finally:
        close = getattr(state, "close", None)
        if close is not None:
            close()
    if status in (_loop.STATUS_DIVERGED, _loop.STATUS_STEP_FAILURE):
        states[where + 1 :] = np.nan
        measured[where + 1 :] = command[where + 1 :] = actuator[where + 1 :] = np.nan
        saturated[where + 1 :] = False
    return assemble(prep, states, measured, command, actuator, saturated, _STATUS[status],
                    where, total)  # fmt: skip
