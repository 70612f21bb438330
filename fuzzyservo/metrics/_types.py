"""The records step metrics are returned in, the metric names and their one-line definitions."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

#: Aggregate metric names, in the order reports and the CLI list them.
METRIC_NAMES: tuple[str, ...] = (
    "rise_time_s",
    "settling_time_s",
    "overshoot_pct",
    "sse_abs",
    "sse_pct",
    "saturation_time_s",
    "iae",
    "ise",
    "itae",
    "peak_command",
    "command_tv",
)

#: One line per metric: formula, unit, and how the aggregate combines the steps.
METRIC_DOCS: dict[str, str] = {
    "rise_time_s": (
        "t(90 %) - t(10 %) of y_final - y_init, first crossings, linear interpolation [s]; "
        "worst step"
    ),
    "settling_time_s": (
        "time after the step from which |y - y_final| <= band |y_final - y_init| (band 2 %) "
        "to the step's end, interpolated [s]; worst step"
    ),
    "overshoot_pct": (
        "100 max(0, peak beyond y_final in the step direction) / |y_final - y_init| [%]; worst step"
    ),
    "sse_abs": "|r1 - y_final|, y_final = mean of the step's last 5 % [output SI unit]; worst step",
    "sse_pct": "100 |r1 - y_final| / |r1 - r0| [%]; worst step",
    "saturation_time_s": "number of samples with the actuator at a limit x sample time [s]; sum",
    "iae": "sum |r - y| dt, rectangle rule [output unit x s]; sum over samples",
    "ise": "sum (r - y)^2 dt, rectangle rule [output unit^2 x s]; sum over samples",
    "itae": "sum (t - t_step) |r - y| dt, rectangle rule [output unit x s^2]; sum over samples",
    "peak_command": "max |u| [V]; worst step",
    "command_tv": (
        "chatter: total variation of the command sum |u[k] - u[k-1]| / scored duration [V/s]; "
        "over every scored sample"
    ),
}


def _json_number(value: float) -> float | None:
    """A float for JSON: NaN and infinities become ``None``."""
    value = float(value)
    return value if math.isfinite(value) else None


@dataclass(frozen=True)
class StepMetrics:
    """Metrics of one reference step, from the step sample to the next reference change.

    ``t_step_s`` is the time of the first sample with the new reference ``r1``; ``r0`` is
    the reference before it. ``r0``, ``r1``, ``y_init``, ``y_final`` and ``sse_abs`` are in
    the output's SI unit. The other fields are documented in :data:`METRIC_DOCS`; a
    quantity the step does not define (e.g. a rise time when ``y_final == y_init``) is NaN.
    """

    t_step_s: float
    r0: float
    r1: float
    y_init: float
    y_final: float
    rise_time_s: float
    settling_time_s: float
    overshoot_pct: float
    sse_abs: float
    sse_pct: float
    saturation_time_s: float
    iae: float
    ise: float
    itae: float
    peak_command: float

    def to_dict(self) -> dict[str, float | None]:
        """JSON-friendly copy: plain floats, NaN as ``None``."""
        return {f.name: _json_number(getattr(self, f.name)) for f in dataclasses.fields(self)}


@dataclass(frozen=True)
class Metrics:
    """Step metrics of a run: ``aggregate`` (one value per :data:`METRIC_NAMES`) and ``steps``.

    ``steps`` lists the scored reference steps in time order; ``aggregate`` is the worst
    step for the step metrics and a sum for the integrals and the saturation time (see
    :func:`fuzzyservo.metrics.step_metrics`).
    """

    aggregate: dict[str, float]
    steps: list[StepMetrics]

    def to_dict(self) -> dict[str, object]:
        """``{"metrics": {name: value}, "steps": [{...}, ...]}`` with NaN as ``None``."""
        return {
            "metrics": {name: _json_number(self.aggregate[name]) for name in METRIC_NAMES},
            "steps": [step.to_dict() for step in self.steps],
        }
