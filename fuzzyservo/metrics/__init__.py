"""Step and tracking metrics of a run: pure functions of sampled arrays.

:func:`step_metrics` scores every reference step after the warm-up (rise and settling
time, overshoot, steady-state error, saturation time, IAE/ISE/ITAE, peak command) with
MATLAB ``stepinfo`` conventions; :func:`result_metrics` applies it to a
:class:`~fuzzyservo.simulation.result.SimResult`. :data:`METRIC_NAMES` lists the
aggregate metrics in report order, :data:`METRIC_DOCS` gives each one's formula and unit.
:data:`METRIC_UNITS` is the units schema (each metric's SI unit, as JSON holds it).
:func:`compensation_pct` scores a heave-compensation run (:func:`heave_metrics` on a result);
:mod:`fuzzyservo.display` shows them in display units.
"""

from fuzzyservo.metrics._heave import compensation_pct, heave_metrics
from fuzzyservo.metrics._step import (
    applicable_metrics,
    command_tv,
    result_metrics,
    step_metrics,
)
from fuzzyservo.metrics._table import format_value
from fuzzyservo.metrics._types import (
    METRIC_DOCS,
    METRIC_NAMES,
    METRIC_UNITS,
    Metrics,
    StepMetrics,
    metric_unit,
)

__all__ = [
    "METRIC_DOCS",
    "METRIC_NAMES",
    "METRIC_UNITS",
    "Metrics",
    "StepMetrics",
    "applicable_metrics",
    "command_tv",
    "compensation_pct",
    "format_value",
    "heave_metrics",
    "metric_unit",
    "result_metrics",
    "step_metrics",
]
