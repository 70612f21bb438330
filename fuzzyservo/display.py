"""How signals and metrics are shown: display units, tables, axis labels, colours, saturated spans.

SI in, an engineer's units out (mm, bar, mA, l/min, s, % unless the rig says otherwise).
The one place a number gets its display unit: shared by the console tables (``compare``,
``tune``, ``robustness``, calibration), the tuning report, the matplotlib figures
(:mod:`fuzzyservo.plots`) and the designer's browser plots, so all show a quantity the
same way; nothing here draws. JSON stays SI (units schema:
:data:`fuzzyservo.metrics.METRIC_UNITS`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from fuzzyservo.metrics import (
    METRIC_NAMES,
    METRIC_UNITS,
    NOT_MOVED,
    Metrics,
    format_value,
    metric_unit,
)
from fuzzyservo.simulation.result import SimResult
from fuzzyservo.units import parse_unit, to_si

# The unit a quantity is read in on a test bench, by its SI dimension (a rig's
# ``display_units`` overrides these per signal); time stays in s, ratios in %.
_PREFERRED = ("mm", "mm/s", "bar", "mA", "l/min")

# Words for the axis labels; any other signal is labelled by its name alone.
_QUANTITY = {
    "y": "position",
    "v": "velocity",
    "w": "speed",
    "theta": "angle",
    "i": "valve current",
    "u_c": "valve input",
}

# Controllers are told apart by colour. Green is left to the reference (the command is
# green in seed 002 Fig. 6.a), red and magenta to p_b and p_a (p4, p3) of panel (c); black is the
# simulated current of Fig. 6.b.
CONTROLLER_COLOURS = (
    "tab:blue",
    "black",
    "tab:orange",
    "tab:brown",
    "tab:purple",
    "tab:cyan",
    "tab:olive",
)


def controller_colour(k: int) -> str:
    return CONTROLLER_COLOURS[k % len(CONTROLLER_COLOURS)]


def display_unit(result: SimResult, name: str, si_unit: str) -> str:
    """The unit signal ``name`` is shown in: the rig's choice, else :func:`preferred_unit`."""
    return result.display_units.get(name) or preferred_unit(si_unit)


def preferred_unit(si_unit: str) -> str:
    """The bench unit of a quantity in ``si_unit``: mm, mm/s, bar, mA or l/min by its
    dimension, else ``si_unit`` itself (s, V, rad, %, or a unit this module cannot read)."""
    try:
        dims = parse_unit(si_unit).dims
    except ValueError:
        return si_unit
    for unit in _PREFERRED:
        if parse_unit(unit).dims == dims:
            return unit
    return si_unit


def display_scale(si_unit: str) -> tuple[str, float]:
    """``(display unit, factor)``: a value in ``si_unit`` times ``factor`` is in the
    display unit (:func:`preferred_unit`)."""
    unit = preferred_unit(si_unit)
    return unit, 1.0 if unit == si_unit else 1.0 / to_si(1.0, unit, si_unit)


def signal_unit(result: SimResult, name: str) -> str:
    """The SI unit of a plant signal or of the actuator ("" when unknown)."""
    if name in result.units:
        return result.units[name]
    return result.actuator_unit if name == result.actuator_name else ""


def to_display(result: SimResult, name: str, values: np.ndarray) -> tuple[np.ndarray, str]:
    """``values`` of signal ``name`` (SI) in its display unit, and that unit."""
    si_unit = signal_unit(result, name)
    if not si_unit:
        return np.asarray(values, dtype=float), ""
    unit = display_unit(result, name, si_unit)
    factor = to_si(1.0, unit, si_unit)
    return np.asarray(values, dtype=float) / factor, unit


@dataclass(frozen=True)
class MetricUnits:
    """How a rig's metrics are shown: each metric's SI unit (:func:`metric_unit`, what
    JSON holds) and its display unit, the judged output (``{y}`` of the units schema) in
    the rig's display unit ``output``, e.g. ``sse_abs`` in mm and ``ise`` in mm²·s.

    Built by :func:`metric_units` (from a rig or a run); the default is a position in m
    shown in mm.
    """

    output_si: str = "m"
    output: str = "mm"

    def si(self, metric: str) -> str:
        """The SI unit of ``metric`` (``summary.json`` and every JSON)."""
        return metric_unit(metric, self.output_si)

    def unit(self, metric: str) -> str:
        """The display unit of ``metric`` ("" for a pure number such as the gain margin)."""
        unit = metric_unit(metric, self.output)
        return "" if unit == "1" else unit

    def factor(self, metric: str) -> float:
        """Display value per SI value of ``metric``."""
        unit = self.unit(metric)
        return 1.0 / to_si(1.0, unit, self.si(metric)) if unit else 1.0

    def value(self, metric: str, si_value: float | None) -> float:
        """``si_value`` of ``metric`` in its display unit (NaN for a missing value)."""
        if si_value is None:
            return math.nan
        return float(si_value) * self.factor(metric)

    def label(self, metric: str) -> str:
        """``metric [unit]``, the row or column head of ``metric`` everywhere."""
        unit = self.unit(metric)
        return f"{metric} [{unit}]" if unit else metric

    def text(self, metric: str, si_value: float | None, missing: str = "n/a") -> str:
        """``si_value`` of ``metric`` with its display unit, e.g. ``0.41 mm``."""
        value = self.value(metric, si_value)
        if not math.isfinite(value):
            return missing
        unit = self.unit(metric)
        return format_value(value) + (f" {unit}" if unit else "")

    def si_units(self, metrics: Iterable[str] = METRIC_UNITS) -> dict[str, str]:
        """``{metric: SI unit}`` of ``metrics`` (default: the whole units schema, resolved
        for this output): the ``units`` a JSON file carries beside its SI numbers."""
        return {m: self.si(m) for m in metrics}


def metric_units(source: SimResult | object) -> MetricUnits:
    """The :class:`MetricUnits` of a run (:class:`SimResult`) or a rig
    (:class:`~fuzzyservo.rig.Rig`): its judged output's SI unit and display unit."""
    if isinstance(source, SimResult):
        si = source.output_unit
        return MetricUnits(si, display_unit(source, source.output_name, si))
    name = source.output  # a Rig (rig.py sits below this module's layer)
    si = source.plant.signal_units[name]
    return MetricUnits(si, source.display_units.get(name) or preferred_unit(si))


#: every aggregate metric is a cost: the lower value is the better one
LOWER_IS_BETTER = "lower is better for every metric"


def elapsed_text(seconds: float) -> str:
    """A duration as a person reads it: ``4.6 s``, ``1.5 min``."""
    return f"{seconds / 60:.1f} min" if seconds >= 120 else f"{seconds:.3g} s"


def change_text(before: float | None, after: float | None) -> str:
    """``after`` against ``before`` (SI values of one metric) as a signed percentage with
    the better direction named: ``-75.3 % better``; ``n/a`` when either is undefined or
    ``before`` is zero (no ratio), ``same`` when both are rounding noise."""
    b = math.nan if before is None else before
    a = math.nan if after is None else after
    if not (math.isfinite(b) and math.isfinite(a)):
        return "n/a"
    if abs(b) < 1e-9 and abs(a) < 1e-9:
        return "same"
    if abs(b) < 1e-9 or abs(a) > 1e6 * abs(b):
        # e.g. an overshoot of 1e-13 % (rounding noise) against a real one: no ratio to show
        return "worse (from 0)" if a > b else "n/a"
    pct = 100.0 * (a - b) / abs(b)
    if abs(pct) < 0.05:  # prints as +0.0 %
        return "same"
    return f"{pct:+.1f} % {'better' if a < b else 'worse'}"


def metrics_table(
    names: Sequence[str],
    rows: Sequence[Mapping[str, float]],
    units: MetricUnits,
    metrics: Sequence[str] | None = None,
    change: bool = False,
) -> str:
    """A plain-text table: one row per metric (``metrics``, default all, labelled with
    its display unit), one column per run (``rows``: SI values by metric); with
    ``change``, a last column of the second run against the first (:func:`change_text`)."""
    header = ["metric", *names, *(["change"] if change else [])]
    shown = METRIC_NAMES if metrics is None else metrics
    lines = [
        [
            units.label(m),
            *(format_value(units.value(m, r.get(m))) for r in rows),
            *([change_text(rows[0].get(m), rows[1].get(m))] if change else []),
        ]
        for m in shown
    ]
    widths = [max(len(row[i]) for row in [header, *lines]) for i in range(len(header))]
    out = ["  ".join(h.ljust(w) for h, w in zip(header, widths, strict=True)).rstrip()]
    out.append("  ".join("-" * w for w in widths))
    out += [
        "  ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)).rstrip() for row in lines
    ]
    return "\n".join(out)


def undefined_note(shown: Sequence[str], rows: Sequence[Mapping[str, float | None]]) -> str:
    """Why a table's ``n/a`` metrics are undefined ("" when every shown value is defined):
    printed under every metrics table (``compare``, ``tune``, the tuning report)."""
    blank = [
        m
        for m in shown
        if any(v is None or not math.isfinite(v) for v in (row.get(m, math.nan) for row in rows))
    ]
    if not blank:
        return ""
    return (
        f"n/a ({', '.join(blank)}): undefined on this run; step metrics need a step in "
        "the reference (a constant reference has none: such a scenario, e.g. a brake, tests "
        "a disturbance: read iae/ise), settling needs a response that settles, rise, "
        "settling and overshoot need an output that moved, and a run that did not end ok "
        "has only its status"
    )


_PREFIXES = ((1e-15, "f"), (1e-12, "p"), (1e-9, "n"), (1e-6, "µ"), (1e-3, "m"), (1.0, ""))


def _si_prefix(mag: float) -> tuple[float, str]:
    """The first SI prefix (scale, symbol) under which ``mag`` prints below 1000 (999.5
    rounds to 1e+03)."""
    return next((sp for sp in _PREFIXES if mag / sp[0] < 999.5), (1.0, ""))


def prefixed(value: float, unit: str) -> str:
    """``value`` [``unit``, SI] with an SI prefix and three significant digits: a motion
    of 4.2e-15 m reads ``4.2 fm``, a resolution of 1.58e-5 m ``15.8 µm`` (values of 1 and
    more, or a unit of ``1``, keep the unit as it is)."""
    if not math.isfinite(value):
        return "n/a"
    if unit in ("", "1"):
        return f"{value:.3g}"
    mag = abs(value)
    if mag == 0.0 or mag >= 1.0:
        return f"{value:.3g} {unit}"
    scale, prefix = _si_prefix(mag)
    return f"{value / scale:.3g} {prefix}{unit}"


def unit_text(unit: str) -> str:
    """A unit as printed: ``m^3/(s*Pa)`` reads ``m³/(s·Pa)`` ("" for a ratio of 1)."""
    if unit in ("", "1"):
        return ""
    return unit.replace("^2", "²").replace("^3", "³").replace("*", "·")


def quantity_text(values: Sequence[float], si_unit: str, digits: int = 3) -> tuple[list[str], str]:
    """Values of one quantity [``si_unit``] printed alike in the unit a test engineer
    reads them in, and that unit: the bench unit (:func:`display_scale`: mm, bar, mA,
    l/min) where the largest prints between 0.01 and 1e5 in it, else an SI prefix on a
    simple unit (3.2 ms, 29.7 nA), else the SI unit; ``digits`` significant digits of the
    largest, the others to the same decimal place."""
    finite = [abs(v) for v in values if math.isfinite(v)]
    mag = max(finite, default=0.0)
    unit, k = display_scale(si_unit)
    if unit == si_unit or not 1e-2 <= mag * k < 1e5:
        unit, k = si_unit, 1.0
        simple = unit.isalpha() and unit not in ("1", "rad")
        if simple and 0.0 < mag < 1.0:
            scale, prefix = _si_prefix(mag)
            unit, k = prefix + unit, 1.0 / scale
    shown = mag * k
    if shown and 1e-3 <= shown < 1e6:  # fixed point, to the largest one's last digit
        form = f".{max(digits - 1 - math.floor(math.log10(shown)), 0)}f"
    else:
        form = f".{digits}g"

    def text(v: float) -> str:
        if not math.isfinite(v):
            return "n/a"
        out = format(v * k, form)
        return out[1:] if out.startswith("-") and float(out) == 0.0 else out  # no "-0.0"

    return [text(v) for v in values], unit_text(unit)


def not_moved_note(metrics: Metrics, units: MetricUnits) -> str:
    """Why a run has no rise, settling or overshoot although its reference stepped: it
    did not move by what its sensor resolves ("" for a run that moved), e.g. ``did not
    move (4.2 fm peak to peak, below the 15.8 µm resolution: the feedback ADC's step,
    ...); rise_time_s, settling_time_s, overshoot_pct not computed``."""
    if metrics.moved:
        return ""
    unit = units.output_si
    return (
        f"did not move ({prefixed(metrics.motion, unit)} peak to peak, below the "
        f"{prefixed(metrics.resolution, unit)} resolution: {metrics.resolution_source}); "
        f"{', '.join(NOT_MOVED)} not computed"
    )


def trial_counts_text(asked: int, complete: int, pruned: int, failed: int) -> str:
    """A study's trials as every output prints them: ``300 asked: 21 complete, 279
    pruned, 0 failed`` (terms: :data:`TRIAL_COUNTS_NOTE`)."""
    return f"{asked} asked: {complete} complete, {pruned} pruned, {failed} failed"


#: what the words of :func:`trial_counts_text` mean, printed where the counts are
TRIAL_COUNTS_NOTE = (
    "asked: trials the sampler proposed; complete: scored on every scenario (and sampled "
    "plant), a diverged run included (it scores the penalty); pruned: stopped once its worst "
    "sample was worse than the best feasible trial; complete and pruned trials count towards "
    "the study's trials; failed: ended by an error or a killed worker, not counted"
)


def axis_label(name: str, unit: str) -> str:
    quantity = _QUANTITY.get(name)
    text = f"{quantity} {name}" if quantity else name
    return f"{text} [{unit}]" if unit else text


# Seed 002 Fig. 6.c: p1 green, p2 blue, p3 magenta, p4 red (the supply and return
# chambers p_s, p_t, the cylinder chambers p_a, p_b); other rigs' pressures (any signal
# in Pa) take the next colours of this cycle.
PRESSURE_COLOURS = {
    "p_s": "tab:green",
    "p_t": "tab:blue",
    "p_a": "magenta",
    "p_b": "tab:red",
}


def saturated_spans(result: SimResult) -> list[tuple[float, float]]:
    """``(start, end)`` times of the intervals where the actuator sits at a limit.

    Each sample holds until the next one (zero-order hold of the controller).
    """
    sat = np.asarray(result.saturated, dtype=bool)
    t = np.asarray(result.t, dtype=float)
    if not sat.any():
        return []
    edges = np.diff(np.concatenate(([0], sat.astype(np.int8), [0])))
    starts = np.flatnonzero(edges == 1)
    stops = np.flatnonzero(edges == -1)  # index one past each run's last sample
    t_ends = np.where(
        stops < t.size, t[np.minimum(stops, t.size - 1)], t[-1] + result.sample_time_s
    )
    return [(float(t[a]), float(e)) for a, e in zip(starts, t_ends, strict=True)]


__all__ = [
    "CONTROLLER_COLOURS",
    "LOWER_IS_BETTER",
    "PRESSURE_COLOURS",
    "TRIAL_COUNTS_NOTE",
    "MetricUnits",
    "axis_label",
    "change_text",
    "controller_colour",
    "display_scale",
    "display_unit",
    "elapsed_text",
    "metric_units",
    "metrics_table",
    "not_moved_note",
    "preferred_unit",
    "prefixed",
    "quantity_text",
    "saturated_spans",
    "signal_unit",
    "to_display",
    "trial_counts_text",
    "undefined_note",
    "unit_text",
]
