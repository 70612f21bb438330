"""Cylinder geometry shared by the plants: pure maps, compiled and callable from Python."""

from __future__ import annotations

import math

from fuzzyservo._jit import njit

_QUARTER_PI = math.pi / 4.0


@njit(cache=True, inline="always")
def circle_area(diameter: float) -> float:
    """Area of a circle ``π·d²/4`` [m²] for a diameter ``d`` [m] (piston or rod)."""
    return _QUARTER_PI * diameter * diameter
