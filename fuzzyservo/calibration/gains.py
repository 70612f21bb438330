"""Controller gains as calibration unknowns.

An outside rig runs under its own controller (an MTS or PLC PIDF, a P loop) whose gains
are often not written down. A controller file declares such a gain unknown
(``kp: {fit: [lo, hi]}``); in a closed-loop replay the gain is then fitted together
with the rig's unknowns. Here gains are named ``controller.<field>`` so they share the
search space with plant parameter fields without clashing with them.
"""

from __future__ import annotations

from collections.abc import Mapping

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
