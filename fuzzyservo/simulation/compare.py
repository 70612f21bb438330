"""Several controllers on one rig and scenario: the runs side by side."""

from __future__ import annotations

from collections.abc import Sequence

from fuzzyservo.controllers.base import Controller
from fuzzyservo.rig import Rig, Scenario
from fuzzyservo.simulation.closed_loop import simulate
from fuzzyservo.simulation.result import SimResult


def compare(
    rig: Rig,
    controllers: Sequence[Controller],
    scenario: str | Scenario | None = None,
    *,
    duration_s: float | None = None,
) -> dict[str, SimResult]:
    """Simulate each controller on ``rig``; results by controller name, in the given order.

    Raises ``ValueError`` when two controllers share a name (their results would collide).
    """
    names = [c.name for c in controllers]
    if len(set(names)) != len(names):
        raise ValueError(f"controllers: two share a name ({names}); give each a distinct name")
    return {c.name: simulate(rig, c, scenario, duration_s=duration_s) for c in controllers}
