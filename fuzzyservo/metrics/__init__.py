"""Step and tracking metrics of a run: pure functions of sampled arrays.

:func:`step_metrics` scores every reference step after the warm-up (rise and settling
time, overshoot, steady-state error, saturation time, IAE/ISE/ITAE, peak command) with
MATLAB ``stepinfo`` conventions; :func:`result_metrics` applies it to a
:class:`~fuzzyservo.simulation.result.SimResult`. :data:`METRIC_NAMES` lists the
aggregate metrics in report order, :data:`METRIC_DOCS` gives each one's formula and unit.
:func:`compensation_pct` scores a heave-compensation run (:func:`heave_metrics` on a result);
:func:`metrics_table` lays runs side by side as text.
"""

from fuzzyservo.metrics._heave import compensation_pct, heave_metrics
from fuzzyservo.metrics._step import (
    applicable_metrics,
    command_tv,
    result_metrics,
    step_metrics,
)
from fuzzyservo.metrics._table import format_value, metrics_table, unit_notes
from fuzzyservo.metrics._types import METRIC_DOCS, METRIC_NAMES, Metrics, StepMetrics

__all__ = [
    "METRIC_DOCS",
    "METRIC_NAMES",
    "Metrics",
    "StepMetrics",
    "applicable_metrics",
    "command_tv",
    "compensation_pct",
    "format_value",
    "heave_metrics",
    "metrics_table",
    "result_metrics",
    "step_metrics",
    "unit_notes",
]
