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
    "sse_abs": "|r1 - y_final|, y_final = mean of the step's last 5 % [output unit]; worst step",
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


#: The units schema: the SI unit of every number the metrics (and the margin checks the
#: tuning constraints bound) are reported in, in ``summary.json`` and every other JSON.
#: ``{y}`` stands for the judged output's SI unit (``m``, ``rad``, ``rad/s``: the rig's
#: ``output`` signal); the command ``u`` is the controller output in V. The screen shows
#: each in its display unit (:class:`fuzzyservo.display.MetricUnits`).
METRIC_UNITS: dict[str, str] = {
    "rise_time_s": "s",
    "settling_time_s": "s",
    "overshoot_pct": "%",
    "sse_abs": "{y}",
    "sse_pct": "%",
    "saturation_time_s": "s",
    "iae": "{y}·s",
    "ise": "{y}²·s",
    "itae": "{y}·s²",
    "peak_command": "V",
    "command_tv": "V/s",
    # heave compensation (compensation_pct)
    "compensation_pct": "%",
    # one step's record (StepMetrics)
    "t_step_s": "s",
    "r0": "{y}",
    "r1": "{y}",
    "y_init": "{y}",
    "y_final": "{y}",
    # whether the output moved (Metrics.motion, Metrics.resolution)
    "motion": "{y}",
    "resolution": "{y}",
    # the margins a constraint may bound (analysis/margins.py)
    "gain_margin": "1",
    "delay_margin_s": "s",
}


def metric_unit(metric: str, output_unit: str) -> str:
    """``metric``'s SI unit (:data:`METRIC_UNITS`) for a judged output in ``output_unit``;
    a compound output unit is bracketed before it is raised to a power (``(rad/s)²·s``).

    Raises ``ValueError`` for a metric the schema does not list.
    """
    if metric not in METRIC_UNITS:
        raise ValueError(
            f"metric {metric!r} has no unit in METRIC_UNITS; add it there (known: "
            f"{', '.join(METRIC_UNITS)})"
        )
    template = METRIC_UNITS[metric]
    compound = any(c in output_unit for c in "/·* ")
    if compound and "{y}²" in template:
        template = template.replace("{y}²", "({y})²")
    return template.replace("{y}", output_unit)


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


def moves(motion: float, resolution: float) -> bool:
    """Did an output that moved ``motion`` (peak to peak) move, for a sensor resolving
    ``resolution``? NaN counts as moved: a run that failed says so by its status."""
    return not motion < resolution


@dataclass(frozen=True)
class Metrics:
    """Step metrics of a run: ``aggregate`` (one value per :data:`METRIC_NAMES`) and ``steps``.

    ``steps`` lists the scored reference steps in time order; ``aggregate`` is the worst
    step for the step metrics and a sum for the integrals and the saturation time (see
    :func:`fuzzyservo.metrics.step_metrics`).

    ``motion`` is the output's peak-to-peak over the scored samples, ``resolution`` the
    smallest motion that counts (output unit) and ``resolution_source`` what set it; a
    run with ``motion < resolution`` did not move (:attr:`moved`), and its rise time,
    settling time and overshoot (:data:`NOT_MOVED`) are NaN.
    """

    aggregate: dict[str, float]
    steps: list[StepMetrics]
    motion: float = math.nan
    resolution: float = math.nan
    resolution_source: str = ""

    @property
    def moved(self) -> bool:
        """False when the output moved by less than the resolution (:func:`moves`)."""
        return moves(self.motion, self.resolution)

    def to_dict(self) -> dict[str, object]:
        """``{"metrics": {name: value}, "steps": [{...}, ...], "moved": ..., "motion": ...,
        "resolution": ..., "resolution_source": ...}`` with NaN as ``None``."""
        return {
            "metrics": {name: _json_number(self.aggregate[name]) for name in METRIC_NAMES},
            "steps": [step.to_dict() for step in self.steps],
            "moved": self.moved,
            "motion": _json_number(self.motion),
            "resolution": _json_number(self.resolution),
            "resolution_source": self.resolution_source,
        }


#: the metrics a run that did not move leaves undefined (they measure the shape of a
#: motion; the errors, integrals and the command stay defined)
NOT_MOVED: tuple[str, ...] = ("rise_time_s", "settling_time_s", "overshoot_pct")
