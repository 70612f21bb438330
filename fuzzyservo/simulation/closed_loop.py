"""Closed-loop simulation entry point: rig + controller + scenario -> :class:`SimResult`."""

from __future__ import annotations

import math
import threading
import weakref
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from fuzzyservo.components.effects import E
from fuzzyservo.controllers.base import Controller
from fuzzyservo.controllers.classical import OpenLoop
from fuzzyservo.plants import PlantModel
from fuzzyservo.rig import Rig, Scenario
from fuzzyservo.simulation import _loop
from fuzzyservo.simulation.binding import bind, controller_entry
from fuzzyservo.simulation.result import SimResult
from fuzzyservo.simulation.validity import (
    STATUS_CAVITATION,
    entrained_air,
    pressure_violation,
)

# Local-error tolerance, in units of each plant's state_scale (seed 002: 0.5 µm and
# 0.5 kPa per step). Measured against the rtol 1e-9 reference on the seed-002 rig with
# P K=10: tol 1 leaves up to 0.49 bar in p3 after the fast moves, tol 0.5 keeps every
# pressure within 0.31 bar and the position within 0.001 mm (`fuzzyservo bench`).
DEFAULT_TOL = 0.5

_STATUS = {
    _loop.STATUS_OK: "ok",
    _loop.STATUS_DIVERGED: "diverged",
    _loop.STATUS_END_STOP: "end_stop",
    _loop.STATUS_STEP_FAILURE: "step_failure",
}


@dataclass(frozen=True)
class Resets:
    """Plant states set from outside during a run (a segmented replay restarts each
    segment from the state a record shows, calibration/segments.py): before sample
    ``at[m]`` (increasing) the state named ``states[j]`` takes ``values[m, j]``; a NaN
    value leaves that state where the run has it."""

    at: np.ndarray
    states: tuple[str, ...]
    values: np.ndarray

    def arrays(self, plant: PlantModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(at, state indices, values)`` as the compiled loop reads them."""
        return (
            np.ascontiguousarray(self.at, dtype=np.int64),
            np.array([plant.states.index(name) for name in self.states], dtype=np.int64),
            np.ascontiguousarray(np.reshape(self.values, (len(self.at), len(self.states))),
                                 dtype=np.float64),
        )  # fmt: skip


NO_RESETS = Resets(np.empty(0, dtype=np.int64), (), np.empty((0, 0)))


@dataclass(frozen=True)
class Prepared:
    """Everything a run needs, as arrays: shared by the compiled and the reference path."""

    rig: Rig
    scenario: Scenario
    controller: Controller
    params: object
    plant: PlantModel  # the rig's plant in the form these parameters need (for_params)
    p: np.ndarray
    x0: np.ndarray
    t: np.ndarray
    ref: np.ndarray
    load: np.ndarray
    null: float  # the plant input of hydraulic null (valve_deadband is centred on it)
    scale: np.ndarray  # local-error unit per state (plant states, then the spool)
    typical: np.ndarray  # finite-difference increments per state
    noise: np.ndarray  # the feedback sensor's noise at each sample [reading unit]

    @property
    def plant_states(self) -> int:
        """How many of the states are the plant's (``valve_lag`` appends the spool)."""
        return len(self.plant.states)


def prepare(
    rig: Rig,
    controller: Controller,
    scenario: str | Scenario | None = None,
    duration_s: float | None = None,
    *,
    noise: bool | None = None,
    noise_seed: int = 0,
) -> Prepared:
    """Resolve the scenario, its parameters, the initial state and the sampled inputs.

    The feedback sensor's noise is
    drawn here, outside the compiled loop, from a generator seeded with ``noise_seed``
    (so both paths see the same sequence and runs reproduce); ``noise`` None follows
    the scenario's ``noise`` switch.
    """
    sc = scenario if isinstance(scenario, Scenario) else rig.scenario(scenario)
    params = rig.params_for(sc)
    duration = sc.duration_s if duration_s is None else float(duration_s)
    n = round(duration / rig.sample_time_s)
    t = np.arange(n) * rig.sample_time_s
    initial = {**rig.initial, **sc.initial}
    plant = rig.plant.for_params(params)
    x0 = np.asarray(plant.initial_state(params, **initial), dtype=np.float64)
    scale = np.asarray(plant.state_scale(params), dtype=np.float64)
    typical = np.asarray(plant.typical_state(params), dtype=np.float64)
    null = float(plant.null_input(params))
    if params.valve_lag_s > 0:
        # valve_lag: the spool state, in plant-input units (the loop sets its start), and
        # for a second-order spool its velocity (input units per s; at rest)
        rated = rig.actuator.rated
        x0 = np.append(x0, null)
        scale = np.append(scale, 1e-5 * rated)
        typical = np.append(typical, rated)
        if params.valve_lag2_s > 0:
            rate = rated / params.valve_lag_s
            x0 = np.append(x0, 0.0)
            scale = np.append(scale, 1e-5 * rate)
            typical = np.append(typical, rate)
    if not controller.has_limits:
        controller = controller.with_limits(*rig.actuator.command_limits)
    p = plant.packed(params)
    std = rig.feedback.noise_std if (sc.noise if noise is None else noise) else 0.0
    draws = np.random.default_rng(noise_seed).standard_normal(n) * std if std > 0 else np.zeros(n)
    return Prepared(
        rig=rig,
        scenario=sc,
        controller=controller,
        params=params,
        plant=plant,
        p=p,
        x0=x0,
        t=t,
        ref=np.ascontiguousarray(sc.reference.sample(t), dtype=np.float64),
        load=np.ascontiguousarray(sc.load.sample(t), dtype=np.float64),
        null=null,
        scale=scale,
        typical=typical,
        noise=draws,
    )


def simulate(
    rig: Rig,
    controller: Controller,
    scenario: str | Scenario | None = None,
    *,
    duration_s: float | None = None,
    tol: float = DEFAULT_TOL,
    noise: bool | None = None,
    noise_seed: int = 0,
    resets: Resets = NO_RESETS,
) -> SimResult:
    """Simulate ``controller`` on ``rig`` for a scenario (default: the rig's first).

    The controller runs every ``rig.sample_time_s`` with zero-order hold; the plant is
    integrated between samples by the compiled L-stable Rosenbrock loop. A controller
    without output limits gets the command range of the rig's actuator. The controller
    sees the feedback sensor's reading with its noise (seeded by ``noise_seed``; ``noise``
    False or True overrides the scenario's switch) and ADC quantisation, one I/O delay
    (``rig.io_delay_s``) before its command reaches the actuator. Never raises for a run
    that fails: the result's ``status`` and ``message`` say what happened. A controller
    that is not compiled (an FMU) runs sample by sample (:func:`simulate_stepped`).
    ``resets``: plant states set during the run (:class:`Resets`).
    """
    if getattr(controller, "stepped", False):
        return simulate_stepped(rig, controller, scenario, duration_s=duration_s, tol=tol,
                                noise=noise, noise_seed=noise_seed, resets=resets)  # fmt: skip
    prep = prepare(rig, controller, scenario, duration_s, noise=noise, noise_seed=noise_seed)
    n = prep.t.size
    nx = prep.x0.size
    states = np.empty((n, nx))
    measured = np.empty(n)
    command = np.empty(n)
    actuator = np.empty(n)
    saturated = np.zeros(n, dtype=np.bool_)
    cp, cs = _initial_state(prep.controller, rig.sample_time_s)
    status, where, steps = bind(prep.plant).closed_loop(
        prep.p,
        prep.null,
        prep.x0,
        controller_entry(prep.controller),
        cp,
        cs,
        prep.ref,
        prep.load,
        prep.noise,
        loop_settings(rig, tol),
        prep.scale,
        prep.typical,
        states,
        measured,
        command,
        actuator,
        saturated,
        *resets.arrays(prep.plant),
    )
    return assemble(
        prep, states, measured, command, actuator, saturated, _STATUS[status], where, steps
    )


def simulate_batch(
    rigs: Sequence[Rig],
    controller: Controller,
    scenario: str,
    noise_seeds: Sequence[int],
    *,
    tol: float = DEFAULT_TOL,
) -> list[SimResult]:
    """:func:`simulate` of one controller on many plants (``rigs``, each with its noise
    seed) in one compiled call, the plants in parallel over the cores. Each result is
    the one :func:`simulate` gives for that rig and seed. The rigs must share their plant
    model, sample time and scenario signals (sampled versions of one rig do, whatever
    their I/O delay or actuator gain); otherwise they run one by one, as do controllers
    stepped in Python (an FMU)."""
    from numba.typed import List

    if getattr(controller, "stepped", False) or any(r.plant.attach for r in rigs):
        return [simulate(r, controller, scenario, tol=tol, noise_seed=n)
                for r, n in zip(rigs, noise_seeds, strict=True)]  # fmt: skip
    preps = [prepare(r, controller, scenario, noise_seed=n) for r, n in zip(rigs, noise_seeds,
                                                                             strict=True)]  # fmt: skip
    if not preps:
        return []
    first = preps[0]
    dt = first.rig.sample_time_s
    cp, cs = _initial_state(first.controller, dt)
    if len(preps) == 1 or not all(
        bind(p.plant) is bind(first.plant)
        and p.rig.sample_time_s == dt
        and p.controller.kind == first.controller.kind
        and np.array_equal(_initial_state(p.controller, dt)[0], cp)
        and p.x0.size == first.x0.size
        and np.array_equal(p.ref, first.ref)
        and np.array_equal(p.load, first.load)
        for p in preps
    ):
        return [simulate(r, controller, scenario, tol=tol, noise_seed=n)
                for r, n in zip(rigs, noise_seeds, strict=True)]  # fmt: skip
    settings = List([loop_settings(p.rig, tol) for p in preps])
    b, n, nx = len(preps), first.t.size, first.x0.size
    states = np.empty((b, n, nx))
    measured = np.empty((b, n))
    command = np.empty((b, n))
    actuator = np.empty((b, n))
    saturated = np.zeros((b, n), dtype=np.bool_)
    out = np.zeros((b, 3), dtype=np.int64)
    bind(first.plant).closed_loop_batch(
        np.stack([p.p for p in preps]),
        np.array([p.null for p in preps]),
        np.stack([p.x0 for p in preps]),
        controller_entry(first.controller),
        cp,
        np.tile(cs, (b, 1)),
        first.ref,
        first.load,
        np.stack([p.noise for p in preps]),
        settings,
        np.stack([p.scale for p in preps]),
        np.stack([p.typical for p in preps]),
        states,
        measured,
        command,
        actuator,
        saturated,
        out,
    )
    return [
        assemble(prep, states[i], measured[i], command[i], actuator[i], saturated[i],
                 _STATUS[int(out[i, 0])], int(out[i, 1]), int(out[i, 2]))
        for i, prep in enumerate(preps)
    ]  # fmt: skip


#: the packed parameters and initial state of the controllers run last, by identity:
#: a robust trial runs one controller some 24 times, and packing a fuzzy controller
#: (its output set discretised) costs as much as a tenth of a run
_PACKED: dict[tuple[int, float], tuple[weakref.ref, np.ndarray, np.ndarray]] = {}
_PACKED_MAX = 8
_PACKED_LOCK = threading.Lock()


def _initial_state(controller: Controller, sample_time_s: float) -> tuple[np.ndarray, np.ndarray]:
    """``controller.init(sample_time_s)``, packed once per controller (controllers are
    immutable): the shared parameters, and a fresh copy of the initial state."""
    key = (id(controller), sample_time_s)
    with _PACKED_LOCK:  # runs may share it from threads (margins)
        hit = _PACKED.get(key)
        if hit is None or hit[0]() is not controller:
            cp, cs = controller.init(sample_time_s)
            if len(_PACKED) >= _PACKED_MAX:
                _PACKED.pop(next(iter(_PACKED)))
            hit = _PACKED[key] = (weakref.ref(controller), cp, cs)
    return hit[1], hit[2].copy()


def loop_settings(rig: Rig, tol: float = DEFAULT_TOL) -> _loop.LoopSettings:
    """The loop's scalars for ``rig``: every compiled parameter of :data:`_loop.LOOP_STAGES`
    read from the rig (feedback sensor and its ADC, sample time, actuator, I/O delay),
    then the integrator's tolerance."""
    values = [
        p.kind(p.read(rig)) for stage in _loop.LOOP_STAGES for p in stage.params if p.compiled
    ]
    return _loop.LoopSettings(*values, float(tol))


def assemble(
    prep: Prepared,
    states: np.ndarray,
    measured: np.ndarray,
    command: np.ndarray,
    actuator: np.ndarray,
    saturated: np.ndarray,
    status: str,
    where: int,
    steps: int,
) -> SimResult:
    """Compute every plant signal from the recorded states and build the result.

    ``feedback`` is the true reading of the feedback sensor, ``measured`` the noisy,
    quantised one the controller saw; extra sensors are recorded true (noise-free)."""
    rig, plant = prep.rig, prep.plant
    n = prep.t.size
    values = np.empty((n, len(plant.signals)))
    states = np.ascontiguousarray(states[:, : prep.plant_states])
    bind(plant).signal_table(states, actuator, prep.load, prep.p, values)
    signals = {name: values[:, j] for j, name in enumerate(plant.signals)}
    units = dict(plant.signal_units)
    for name, sensor in rig.sensors.items():
        sensed = (
            signals[sensor.signal]
            if sensor.signal in plant.signals
            else states[:, plant.states.index(sensor.signal)]
        )
        signals[name] = np.asarray(sensor.read(sensed))
        units[name] = sensor.unit
    for (name, unit), values in ((plant.load, prep.load), (plant.input, actuator)):
        signals[name] = values
        units[name] = unit
    fb = rig.feedback
    feedback = np.asarray(fb.read(states[:, plant.states.index(fb.signal)]))
    message = _message(status, where, prep)
    end_stop_s = where * rig.sample_time_s if status == "end_stop" else None
    resolution, resolution_source = fb.resolution if fb.signal == rig.output else (0.0, "")
    if status in ("ok", "end_stop"):
        # a run that finished is still unphysical if a chamber went below vapour pressure
        below = pressure_violation(prep.t, signals, plant.pressures, entrained_air(rig.params))
        if below:
            status, message = STATUS_CAVITATION, "; ".join(m for m in (below, message) if m)
    return SimResult(
        rig=rig.name,
        scenario=prep.scenario.name,
        controller=prep.controller.name,
        t=prep.t,
        reference=prep.ref,
        reference_output=np.asarray(fb.invert(prep.ref)),
        feedback=feedback,
        measured=measured,
        output=signals[rig.output],
        command=command,
        actuator=actuator,
        saturated=saturated,
        signals=signals,
        units=units,
        output_name=rig.output,
        actuator_name=plant.input[0],
        actuator_limits=(rig.actuator.lower, rig.actuator.upper),
        sample_time_s=rig.sample_time_s,
        warmup_s=prep.scenario.warmup_s,
        status=status,
        message=message,
        integration_steps=steps,
        display_units=dict(rig.display_units),
        actuator_unit=plant.input[1],
        end_stop_s=end_stop_s,
        resolution=resolution,
        resolution_source=resolution_source,
    )


def _message(status: str, where: int, prep: Prepared) -> str:
    t = where * prep.rig.sample_time_s
    if status == "ok":
        return ""
    if status == "end_stop":
        lo, hi = getattr(prep.params, "stroke_limits_m", (np.nan, np.nan))
        return f"the piston hit the end stop at t = {t:.3f} s (stroke {lo:.4g} .. {hi:.4g} m)"
    if status == "diverged":
        return f"the simulation diverged at t = {t:.3f} s (non-finite state or step size collapsed)"
    return f"the integrator needed too many steps in the interval at t = {t:.3f} s"


def simulate_stepped(
    rig: Rig,
    controller: Controller,
    scenario: str | Scenario | None = None,
    *,
    duration_s: float | None = None,
    tol: float = DEFAULT_TOL,
    noise: bool | None = None,
    noise_seed: int = 0,
    resets: Resets = NO_RESETS,
) -> SimResult:
    """:func:`simulate` with ``controller.step`` called from Python at every sample (its
    state from ``controller.init``), for a controller that is not compiled (an FMU).

    Each sample does what the compiled loop (``_plant_loop.closed_loop``) does, with the
    same compiled pieces: the feedback reading (:func:`_loop.sample` of a pass-through
    controller, so sensor noise, ADC and actuator mapping are the loop's own), the
    command from ``controller.step``, the limit and the actuator, and the plant integrated
    over the interval by the plant loop's compiled Rosenbrock integrator behind the same
    delays. A native controller run this way gives the compiled loop's numbers."""
    prep = prepare(rig, controller, scenario, duration_s, noise=noise, noise_seed=noise_seed)
    c = prep.controller
    loop, p, settings = bind(prep.plant), prep.p, loop_settings(rig, tol)
    dt = rig.sample_time_s
    n, x = prep.t.size, prep.x0.copy()
    states = np.full((n, x.size), np.nan)
    measured, command, actuator = np.full(n, np.nan), np.full(n, np.nan), np.full(n, np.nan)
    saturated = np.zeros(n, dtype=np.bool_)
    work, mats, piv = _loop.workspace(x.size)
    # a pass-through (u = r) inside the controller's limits: the loop's own sample stage
    cp, cs = OpenLoop(gain=1.0, u_min=c.u_min, u_max=c.u_max).init(dt)
    open_loop = controller_entry(OpenLoop)
    state = c.init(dt)
    h, status, where, total = dt * 1e-3, _loop.STATUS_OK, -1, 0
    lag = p[E.valve_lag_s] > 0.0
    spool = prep.plant_states  # the spool's position, after the plant's states
    whole, part = _loop.delay_split(p, settings)
    reset_at, reset_idx, reset_val = resets.arrays(prep.plant)
    next_reset = 0
    try:
        for k in range(n):
            if next_reset < reset_at.size and reset_at[next_reset] == k:
                row = reset_val[next_reset]
                keep = np.isfinite(row)
                x[reset_idx[keep]] = row[keep]
                next_reset += 1
            states[k] = x
            y = _loop.sample(open_loop, cp, cs, 0.0, x, settings, prep.noise[k])[0]
            u, state = c.step(state, prep.ref[k], y)
            y, u, a, sat = _loop.sample(open_loop, cp, cs, u, x, settings, prep.noise[k])
            measured[k], command[k], actuator[k], saturated[k] = y, u, a, sat
            if not math.isfinite(a):
                status, where = _loop.STATUS_DIVERGED, k
                break
            if k == 0 and lag:
                x[spool] = states[0, spool] = _loop.spool_start(p, a)
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
