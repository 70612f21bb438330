"""The reference path: the same plant and controller, integrated by scipy's ``solve_ivp``.

Each control interval is a separate initial-value problem with the held input, solved
by LSODA or Radau. At ``rtol = 1e-6`` it is the benchmark's denominator (what a user
would write with scipy alone); at ``rtol = 1e-9`` it is the accuracy reference for the
tests and the benchmark's error figures.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

from fuzzyservo.controllers.base import Controller
from fuzzyservo.plants.kernels import plant_in_end_stop
from fuzzyservo.rig import Rig, Scenario
from fuzzyservo.simulation._loop import loop_rhs
from fuzzyservo.simulation.closed_loop import assemble, prepare
from fuzzyservo.simulation.result import SimResult


def simulate_reference(
    rig: Rig,
    controller: Controller,
    scenario: str | Scenario | None = None,
    *,
    duration_s: float | None = None,
    rtol: float = 1e-9,
    method: str = "LSODA",
) -> SimResult:
    """Simulate like :func:`~fuzzyservo.simulation.simulate`, with ``solve_ivp`` per interval.

    Absolute tolerances are ``rtol`` times each state's typical magnitude, except the
    liquid volumes, whose absolute tolerance is ``rtol`` times their scale of 1 kPa.
    """
    prep = prepare(rig, controller, scenario, duration_s)
    if prep.params.transport_delay_s > 0:
        raise ValueError(
            "simulate_reference: transport_delay is not supported on the reference path; "
            "use simulate"
        )
    plant = rig.plant
    kind, p = plant.kind, prep.p
    n = prep.t.size
    x = prep.x0.copy()
    states = np.full((n, x.size), np.nan)
    command = np.full(n, np.nan)
    actuator = np.full(n, np.nan)
    saturated = np.zeros(n, dtype=bool)
    state = prep.controller.init(rig.sample_time_s)
    fb = rig.feedback
    act = rig.actuator
    sensor_index = plant.states.index(fb.signal)
    atol = rtol * 1e3 * prep.scale
    null = prep.null
    lag = prep.params.valve_lag_s > 0
    dt = rig.sample_time_s
    status, where, steps = "ok", -1, 0
    for k in range(n):
        states[k] = x
        y = fb.read(x[sensor_index])
        u, state = prep.controller.step(state, prep.ref[k], y)
        a = min(max(act.gain * u, act.lower), act.upper)
        command[k], actuator[k] = u, a
        saturated[k] = a >= act.upper * (1 - 1e-9) or a <= act.lower * (1 + 1e-9)
        load = prep.load[k]
        if k == 0 and lag:
            x[-1] = states[0, -1] = a + prep.params.valve_bias_si

        def f(_t: float, xx: np.ndarray, a: float = a, load: float = load) -> np.ndarray:
            dx = np.empty_like(xx)
            loop_rhs(kind, xx, a, load, p, null, dx)
            return dx

        sol = solve_ivp(f, (0.0, dt), x, method=method, rtol=rtol, atol=atol)
        steps += int(sol.t.size - 1)
        if not sol.success or not np.isfinite(sol.y[:, -1]).all():
            status, where = "diverged", k
            break
        x = np.ascontiguousarray(sol.y[:, -1])
        if status == "ok" and plant_in_end_stop(kind, x[: prep.plant_states], p):
            status, where = "end_stop", k + 1
    return assemble(prep, states, command, actuator, saturated, status, where, steps)
