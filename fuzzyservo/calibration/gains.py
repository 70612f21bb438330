"""Controller gains as calibration unknowns.

An outside rig runs under its own controller (an MTS or PLC PIDF, a P loop) whose gains
are often not written down. A controller file declares such a gain unknown
(``kp: {fit: [lo, hi]}``); in a closed-loop replay the gain is then fitted together
with the rig's unknowns. When the record logs the controller's output ``u``, :func:`fit_from_log` fits the gains
on it directly (the controller stepped on the recorded reference and measurement) and
they are then held. Otherwise gains are named ``controller.<field>`` so they share the
search space with plant parameter fields without clashing with them.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np

from fuzzyservo.controllers.base import Controller

PREFIX = "controller."


def gain_unknowns(controller: Controller, closed_loop: bool) -> dict[str, tuple[float, float]]:
    """``controller.<field>`` -> (lower, upper) of the gains to fit; none in open loop,
    where the recorded command replaces the controller."""
    if not closed_loop:
        return {}
    return {PREFIX + name: bounds for name, bounds in controller.gain_bounds().items()}


def is_gain(name: str) -> bool:
    return name.startswith(PREFIX)


def gain_value(controller: Controller, name: str) -> float:
    """The current value of gain ``controller.<field>``."""
    return float(getattr(controller, name[len(PREFIX) :]))


def with_gains(controller: Controller, values: Mapping[str, float]) -> Controller:
    """``controller`` with every ``controller.<field>`` of ``values`` set (others ignored)."""
    gains = {k[len(PREFIX) :]: float(v) for k, v in values.items() if is_gain(k)}
    return controller.with_gains(**gains) if gains else controller


def fit_from_log(
    controller: Controller,
    reference: np.ndarray,
    reading: np.ndarray,
    command: np.ndarray,
    sample_time_s: float,
    split: int,
) -> tuple[Controller, dict[str, tuple[float, float, float]], float]:
    """The unknown gains that make ``controller``, stepped on the recorded reference and
    feedback reading (both in the feedback unit, one sample per controller period), give
    the recorded command ``u`` [V]: bounded least squares on the first ``split`` samples.

    When a rig logs its controller's output, this pins the gains directly; a closed-loop
    fit of the output alone sees only the product of the controller gain and the plant's
    flow gain. Returns the controller with the gains set and none left unknown, gain ->
    (value, lower, upper), and the fit % of ``u`` on the samples from ``split`` on.
    """
    from scipy.optimize import least_squares

    from fuzzyservo.calibration.residuals import fit_percent

    bounds = controller.gain_bounds()
    names = list(bounds)
    lo = np.array([bounds[n][0] for n in names])
    hi = np.array([bounds[n][1] for n in names])
    span = np.where(hi > lo, hi - lo, 1.0)

    def commands(z: np.ndarray) -> np.ndarray:
        c = controller.with_gains(
            **{n: float(v) for n, v in zip(names, lo + span * z, strict=True)}
        )
        cp, cs = c.init(sample_time_s)
        out = np.empty(reference.size)
        for k in range(reference.size):
            out[k] = c.kernel(cp, cs, float(reference[k]), float(reading[k]))
        return out

    z0 = np.array([(getattr(controller, n) - lo[j]) / span[j] for j, n in enumerate(names)])
    sol = least_squares(
        lambda z: (commands(z) - command)[:split],
        np.clip(z0, 0.0, 1.0),
        bounds=(0.0, 1.0),
        diff_step=1e-3,
        xtol=1e-8,
        ftol=1e-8,
    )
    values = {n: float(v) for n, v in zip(names, lo + span * sol.x, strict=True)}
    fitted = dataclasses.replace(controller.with_gains(**values), unknowns=())
    fit = fit_percent(command[split:], commands(sol.x)[split:])
    return fitted, {n: (values[n], *bounds[n]) for n in names}, fit
