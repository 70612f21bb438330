"""Time responses of one or several controllers on one rig, laid out as seed 002 Fig. 6."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from fuzzyservo.display import (
    PRESSURE_COLOURS,
    axis_label,
    controller_colour,
    saturated_spans,
    to_display,
)
from fuzzyservo.plots._display import label_span
from fuzzyservo.simulation.result import SimResult

_OTHER_COLOURS = ("tab:purple", "tab:brown", "tab:olive", "tab:cyan")
# With several controllers, the actuator chamber pressures (the ones that move the
# piston) are enough; every pressure per controller would not read.
_PRESSURES_COMPARED = ("p_a", "p_b")
_LINE_STYLES = ("-", "--", "-.", ":")
_REFERENCE_COLOUR = "tab:green"


def response_figure(results: Sequence[SimResult]) -> Figure:
    """Reference and output, actuator, and pressures of ``results`` against time.

    Three panels sharing the time axis, as seed 002 Fig. 6: (a) the reference (dashed,
    once) and every controller's output; (b) every actuator signal with the actuator
    limits (dotted) and the first result's saturated intervals shaded; (c) the
    pressures the rig records (every signal in Pa for one result, the actuator
    chambers ``p_a``/``p_b`` per controller when comparing). Signals are shown in the
    rig's display unit, else bar, mA and l/min, else SI. The warm-up (``t <
    warmup_s``) is shaded grey. All results must come from one rig and scenario.
    """
    results = list(results)
    _check(results)
    first = results[0]
    fig = Figure(figsize=(9.0, 9.0), layout="tight")
    ax_out, ax_act, ax_p = fig.subplots(3, 1, sharex=True)
    _output_panel(ax_out, results)
    _actuator_panel(ax_act, results)
    _pressure_panel(ax_p, results)

    warmup = max(r.warmup_s for r in results)
    t_start = min(float(r.t[0]) for r in results)
    t_end = max(float(r.t[-1]) for r in results)
    for ax in (ax_out, ax_act, ax_p):
        if warmup > t_start:
            ax.axvspan(t_start, warmup, color="0.92", zorder=0, lw=0)
        ax.grid(True, color="0.85", lw=0.6)
        ax.set_xlim(t_start, t_end)
    ax_p.set_xlabel("time [s]")
    if warmup > t_start:
        label_span(ax_out, t_start, warmup, "warm-up")
    fig.suptitle(f"{first.rig} — {first.scenario}")
    return fig


def _check(results: list[SimResult]) -> None:
    if not results:
        raise ValueError("response_figure needs at least one SimResult, got an empty list")
    empty = [r.controller for r in results if r.t.size == 0]
    if empty:
        raise ValueError(f"results of {empty} have no samples (t is empty); leave them out")
    cases = sorted({(r.rig, r.scenario) for r in results})
    if len(cases) > 1:
        raise ValueError(
            "response_figure compares controllers on one rig and scenario, but got "
            f"{cases}; draw one figure per (rig, scenario)"
        )


def _label(result: SimResult) -> str:
    return result.controller if result.status == "ok" else f"{result.controller} ({result.status})"


def _output_panel(ax: Axes, results: list[SimResult]) -> None:
    first = results[0]
    name = first.output_name
    ref, unit = to_display(first, name, first.reference_output)
    ax.plot(first.t, ref, color=_REFERENCE_COLOUR, ls="--", lw=1.2, label="reference")
    for k, r in enumerate(results):
        y, _ = to_display(r, name, r.output)
        ax.plot(r.t, y, color=controller_colour(k), lw=1.4, label=_label(r))
    ax.set_ylabel(axis_label(name, unit))
    ax.set_title("(a) reference and output", loc="left", fontsize=10)
    ax.legend(loc="best", fontsize=8)


def _actuator_panel(ax: Axes, results: list[SimResult]) -> None:
    first = results[0]
    name = first.actuator_name
    unit = ""
    for k, r in enumerate(results):
        u, unit = to_display(r, name, r.actuator)
        ax.plot(r.t, u, color=controller_colour(k), lw=1.2, label=_label(r))
    limits, _ = to_display(first, name, np.asarray(first.actuator_limits, dtype=float))
    for j, limit in enumerate(limits):
        if np.isfinite(limit):
            ax.axhline(limit, color="0.3", ls=":", lw=1.0, label="limits" if j == 0 else None)
    _shade_saturation(ax, first)
    ax.set_ylabel(axis_label(name, unit))
    ax.set_title("(b) actuator", loc="left", fontsize=10)
    ax.legend(loc="best", fontsize=8)


def _shade_saturation(ax: Axes, result: SimResult) -> None:
    """Shade the intervals where ``result``'s actuator sits at a limit (one sample wide each)."""
    spans = [(a, e - a) for a, e in saturated_spans(result)]
    if not spans:
        return
    ax.broken_barh(
        spans,
        (0.0, 1.0),
        transform=ax.get_xaxis_transform(),
        facecolor=controller_colour(0),
        alpha=0.12,
        lw=0,
        zorder=0,
        label=f"saturated ({result.controller})",
    )


def _pressure_panel(ax: Axes, results: list[SimResult]) -> None:
    ax.set_title("(c) pressures", loc="left", fontsize=10)
    first = results[0]
    recorded = [
        n
        for n in first.signals
        if first.units.get(n) == "Pa" and all(n in r.signals for r in results)
    ]
    colours = {
        n: PRESSURE_COLOURS.get(n, _OTHER_COLOURS[k % len(_OTHER_COLOURS)])
        for k, n in enumerate(recorded)
    }
    if len(results) > 1:
        if all(n in recorded for n in _PRESSURES_COMPARED):
            recorded = list(_PRESSURES_COMPARED)
    if not recorded:
        ax.text(0.5, 0.5, "no pressures recorded", transform=ax.transAxes, ha="center")
        ax.set_ylabel("pressure")
        return
    unit = ""
    for k, r in enumerate(results):
        style = _LINE_STYLES[k % len(_LINE_STYLES)]
        for name in recorded:
            p, unit = to_display(r, name, r.signals[name])
            if len(results) == 1:
                ax.plot(r.t, p, color=colours[name], lw=1.2, label=name)
            elif len(recorded) == 1:
                # One pressure: tell controllers apart by the colours of panels (a), (b).
                ax.plot(r.t, p, color=controller_colour(k), lw=1.2, label=_label(r))
            else:
                ax.plot(r.t, p, color=colours[name], ls=style, lw=1.2, label=f"{name} {_label(r)}")
    what = recorded[0] if len(recorded) == 1 else "pressure"
    ax.set_ylabel(axis_label(what, unit))
    ax.legend(loc="best", fontsize=8, ncol=2 if len(results) > 1 and len(recorded) > 1 else 1)
