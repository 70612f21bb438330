"""Metrics as text: one number formatted for a table, and the table of several runs."""

from __future__ import annotations

import math
from collections.abc import Sequence

from fuzzyservo.metrics._types import METRIC_NAMES


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


def unit_notes(unit: str) -> dict[str, str]:
    """The units of the error integrals for a feedback in ``unit``, as table suffixes
    (a compound unit is bracketed before it is squared: ``(rad/s)²·s``)."""
    squared = f"({unit})²" if any(c in unit for c in "/·* ") else f"{unit}²"
    return {"sse_abs": f" [{unit}]", "iae": f" [{unit}·s]", "ise": f" [{squared}·s]", "itae": f" [{unit}·s²]",
            "peak_command": " [V]"}  # fmt: skip


def metrics_table(
    names: Sequence[str],
    rows: Sequence[dict[str, float]],
    notes: dict[str, str],
    metrics: Sequence[str] | None = None,
) -> str:
    """A plain-text table: one row per metric (``metrics``, default all), one column per
    run; ``notes`` are suffixes of the metric names (units)."""
    header = ["metric", *names]
    shown = METRIC_NAMES if metrics is None else metrics
    lines = [[f"{m}{notes.get(m, '')}", *(format_value(r.get(m)) for r in rows)] for m in shown]
    widths = [max(len(row[i]) for row in [header, *lines]) for i in range(len(header))]
    out = ["  ".join(h.ljust(w) for h, w in zip(header, widths, strict=True))]
    out.append("  ".join("-" * w for w in widths))
    out += ["  ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)) for row in lines]
    return "\n".join(out)
