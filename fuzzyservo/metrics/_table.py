"""One metric value as text (its display unit and the tables: :mod:`fuzzyservo.display`)."""

from __future__ import annotations

import math


def format_value(value: float | None) -> str:
    """Four significant digits; ``n/a`` for a missing or undefined value, ``0`` for
    rounding noise (e.g. 1e-14 % overshoot of a creeping response)."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "n/a"
    if abs(value) < 1e-9:
        return "0"
    mag = abs(value)
    if 1e-3 <= mag < 1e5:
        return f"{value:.4g}"
    return f"{value:.3e}"
