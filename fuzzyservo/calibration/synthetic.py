"""Measured-like data from the project's own models: a run with chosen effects switched
on, sampled at the controller's rate, with white measurement noise on the recorded
channels. For tests, the benchmark and trying calibration before a rig is built."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from fuzzyservo.controllers.base import Controller
from fuzzyservo.measured import Measured
from fuzzyservo.rig import Rig, Scenario
from fuzzyservo.simulation import simulate


def synthetic_run(
    rig: Rig,
    controller: Controller,
    scenario: str | Scenario | None,
    effects: Mapping[str, Mapping[str, float]],
    noise: Mapping[str, float],
    *,
    seed: int = 0,
    duration_s: float | None = None,
    in_loop: bool = False,
) -> Measured:
    """Simulate ``rig`` with ``effects`` (name -> parameter key -> SI value) and record
    ``ref`` (in the sensed signal's unit), the plant input (``i`` for a current,
    else ``u``) and every channel of ``noise`` (signal -> standard deviation, SI) with
    that noise added. Raises ValueError if the run does not finish.

    ``in_loop``: the feedback sensor's own noise (the rig's ``feedback.noise``, seeded
    by ``seed``) is in the loop, as on a rig, and the feedback channel records what the
    controller read (noisy and quantised; its entry in ``noise`` adds nothing). Else the
    loop runs noise-free and the noise goes on the records only."""
    for name, values in effects.items():
        rig = rig.with_effect(name, **values)
    # the loop's noise from a stream of its own (the records' noise takes ``seed``'s)
    loop_seed = int(np.random.SeedSequence([seed, 1]).generate_state(1)[0])
    res = simulate(rig, controller, scenario, duration_s=duration_s, noise=in_loop,
                   noise_seed=loop_seed)  # fmt: skip
    if not res.ok:
        raise ValueError(f"synthetic run failed: {res.message}")
    rng = np.random.default_rng(seed)
    fb = rig.feedback
    # the reference in the unit of the sensed signal (m, rad/s), as a logger records it
    signals = {"ref": np.asarray(fb.invert(res.reference), dtype=float)}
    units = {"ref": rig.plant.signal_units[fb.signal]}
    _, input_unit = rig.plant.input
    key = "i" if input_unit == "A" else "u"
    signals[key], units[key] = res.actuator, input_unit
    if scenario is not None and not isinstance(scenario, str):
        load = np.asarray(scenario.load.sample(res.t), dtype=float)
        if np.any(load != 0.0):  # an experiment under a load records it
            signals["load"], units["load"] = load, rig.plant.mechanics["force"]
    for name, sigma in noise.items():
        signal = rig.output if name == "y" else name
        if in_loop and signal == fb.signal:  # what the controller read, in its unit
            signals[name] = np.asarray(fb.invert(res.signal("measured")), dtype=float)
        else:
            signals[name] = res.signals[signal] + rng.normal(0.0, sigma, res.t.size)
        units[name] = rig.plant.signal_units[signal]
    return Measured(
        t=res.t,
        signals=signals,
        units=units,
        source=f"synthetic {rig.name} {', '.join(effects) or 'no effect'}",
        sample_period_s=res.sample_time_s,
    )
