"""Step and tracking metrics of a run: pure functions of sampled arrays.

:func:`step_metrics` scores every reference step after the warm-up (rise and settling
time, overshoot, steady-state error, saturation time, IAE/ISE/ITAE, peak command) with
MATLAB ``stepinfo`` conventions; :func:`result_metrics` applies it to a
:class:`~fuzzyservo.simulation.result.SimResult`. :data:`METRIC_NAMES` lists the
aggregate metrics in report order, :data:`METRIC_DOCS` gives each one's formula and unit.
:data:`METRIC_UNITS` is the units schema (each metric's SI unit, as JSON holds it).
:attr:`Metrics.moved` says whether the output moved by more than the sensor resolves (a run
that did not has no rise, settling or overshoot: :data:`NOT_MOVED`).
:func:`compensation_pct` scores a heave-compensation run (:func:`heave_metrics` on a result);
:mod:`fuzzyservo.display` shows them in display units.
"""

from fuzzyservo.metrics._heave import compensation_pct, heave_metrics
from fuzzyservo.metrics._step import (
    FALLBACK_RESOLUTION_SHARE,
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
    NOT_MOVED,
    Metrics,
    StepMetrics,
    metric_unit,
)

__all__ = [
    "FALLBACK_RESOLUTION_SHARE",
    "METRIC_DOCS",
    "METRIC_NAMES",
    "METRIC_UNITS",
    "NOT_MOVED",
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
