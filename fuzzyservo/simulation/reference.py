"""The reference path: the same plant and controller, integrated by scipy's ``solve_ivp``.

Each control interval is a separate initial-value problem with the held input, solved
by LSODA or Radau. At ``rtol = 1e-6`` it is the benchmark's denominator (what a user
would write with scipy alone); at ``rtol = 1e-9`` it is the accuracy reference for the
tests and the benchmark's error figures. The sample logic (limits, saturation, input
effects, transport delay) is the compiled loop's own (:mod:`fuzzyservo.simulation._loop`);
only the integrator differs; the sensor noise is drawn once, in :func:`prepare`.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

from fuzzyservo.controllers.base import Controller
from fuzzyservo.errors import ConfigError
from fuzzyservo.rig import Rig, Scenario
from fuzzyservo.simulation._loop import delay_split, held_inputs, sample, spool_start
from fuzzyservo.simulation.binding import bind, controller_entry
from fuzzyservo.simulation.closed_loop import assemble, loop_settings, prepare
from fuzzyservo.simulation.result import SimResult


def simulate_reference(
    rig: Rig,
    controller: Controller,
    scenario: str | Scenario | None = None,
    *,
    duration_s: float | None = None,
    rtol: float = 1e-9,
    method: str = "LSODA",
    noise: bool | None = None,
    noise_seed: int = 0,
) -> SimResult:
    """Simulate like :func:`~fuzzyservo.simulation.simulate`, with ``solve_ivp`` per interval
    (the same sensor noise sequence for the same ``noise`` and ``noise_seed``).

    Absolute tolerances are ``rtol`` times each state's scale of 1 kPa (or its
    equivalent: ``state_scale`` times 1e3). A plant stepped by its own solver (a
    co-simulation FMU) has no right-hand side to integrate: :class:`ConfigError`.
    """
    if rig.plant.stepped:
        raise ConfigError(
            f"{rig.plant.description} is stepped by its own solver: there is no reference "
            "path to integrate; use the FMU's model-exchange interface"
        )
    prep = prepare(rig, controller, scenario, duration_s, noise=noise, noise_seed=noise_seed)
    loop = bind(prep.plant)
    ctrl = controller_entry(prep.controller)
    p = prep.p
    n = prep.t.size
    x = prep.x0.copy()
    states = np.full((n, x.size), np.nan)
    measured = np.full(n, np.nan)
    command = np.full(n, np.nan)
    actuator = np.full(n, np.nan)
    saturated = np.zeros(n, dtype=bool)
    cp, cs = prep.controller.init(rig.sample_time_s)
    settings = loop_settings(rig)
    atol = rtol * 1e3 * prep.scale
    null = prep.null
    lag = prep.params.valve_lag_s > 0
    dt = rig.sample_time_s
    whole, part = delay_split(p, settings)
    status, where, steps = "ok", -1, 0
    for k in range(n):
        states[k] = x
        y, u, a, sat = sample(ctrl, cp, cs, prep.ref[k], x, settings, prep.noise[k])
        measured[k], command[k], actuator[k], saturated[k] = y, u, a, sat
        if not np.isfinite(a):
            status, where = "diverged", k
            break
        if k == 0 and lag:
            spool = prep.plant_states  # the spool's position, after the plant's states
            x[spool] = states[0, spool] = spool_start(p, a)
        a_before, a_now = held_inputs(actuator, k, whole)
        load = prep.load[k]
        for held, span in ((a_before, part * dt), (a_now, (1.0 - part) * dt)):
            if span <= 0.0:
                continue

            def f(_t: float, xx: np.ndarray, a: float = held, load: float = load) -> np.ndarray:
                return loop.rhs_with_inputs(xx, a, load, p, null)

            sol = solve_ivp(f, (0.0, span), x, method=method, rtol=rtol, atol=atol)
            steps += int(sol.t.size - 1)
            if not sol.success or not np.isfinite(sol.y[:, -1]).all():
                status, where = "diverged", k
                break
            x = np.ascontiguousarray(sol.y[:, -1])
        if status == "diverged":
            break
        if status == "ok" and loop.in_end_stop(x, p):
            status, where = "end_stop", k + 1
    return assemble(prep, states, measured, command, actuator, saturated, status, where, steps)
