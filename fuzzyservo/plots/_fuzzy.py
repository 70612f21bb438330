"""Fuzzy controllers as MATLAB's Fuzzy Logic Designer shows them: terms, curve, surface.

Seed 002 Fig. 7 and 9 show each controller's membership functions beside its control
surface; these figures do the same from a :class:`FuzzyController`. Everything is drawn
in the loop's units: an input variable's universe ``x`` is shown at ``e = x/G_e``, the
output's at ``u = G_u·x``, so the membership panels and the curve share their axes.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from fuzzyservo.controllers.fuzzy.controller import FuzzyController
from fuzzyservo.controllers.fuzzy.system import Variable
from fuzzyservo.display import controller_colour

# Names the error rate goes by in controller files; shown as ė.
_RATE_NAMES = frozenset({"de", "edot", "e_dot", "dedt", "de_dt", "ce"})
_TERM_COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown",
                 "tab:pink", "tab:olive", "tab:cyan", "tab:gray")  # fmt: skip
_CURVE_POINTS = 801
# gensurf's default grid is 15×15; 41×41 resolves the kinks of triangular terms.
_SURFACE_POINTS = 41
# Term labels closer than this (fraction of the axis width) go on a second row.
_LABEL_GAP = 0.07
_PANEL_HEIGHT_IN = 2.3


def membership_figure(controller: FuzzyController) -> Figure:
    """One panel per input and one for the output, stacked: every term's membership.

    Each term is drawn from :meth:`Variable.table` (the sampled universe, which holds
    every breakpoint, so triangles and trapezoids are exact), its name written at its
    peak (the middle of a plateau), and the variable's range edges dashed, with the
    outside shaded: the inference never sees values there.
    """
    _check_fuzzy(controller, "membership_figure")
    n = len(controller.system.inputs) + 1
    fig = Figure(figsize=(7.0, 0.6 + _PANEL_HEIGHT_IN * n), layout="constrained")
    axes = fig.subplots(n, 1, squeeze=False)[:, 0]
    _membership_panels(list(axes), controller)
    fig.suptitle(f"{controller.name}: membership functions")
    return fig


def control_curve_figure(
    controller: FuzzyController, compare: Sequence[FuzzyController] | None = None
) -> Figure:
    """The static map ``G_u·F(G_e·e [, G_ė·ė])`` of ``controller`` (before output limits).

    One input: the control curve u(e) over the input range with the u = 0 and e = 0
    lines, the zero crossing marked (seed 002 §6 moves it to cancel the stationary
    error), and the one-input controllers in ``compare`` overlaid on their own ranges.
    Two inputs: the surface u(e, ė) on a 41×41 grid over both ranges, as MATLAB's
    ``gensurf``; ``compare`` must then be empty.
    """
    curves = _curve_set(controller, compare)
    if len(controller.system.inputs) == 2:
        fig = Figure(figsize=(7.5, 6.0), layout="constrained")
        ax = fig.add_subplot(projection="3d")
        _surface_panel(ax, controller)
        ax.set_title(f"{controller.name}: control surface")
        return fig
    fig = Figure(figsize=(7.0, 4.8), layout="constrained")
    ax = fig.subplots()
    _curve_panel(ax, curves)
    title = " vs ".join(c.name for c in curves)
    ax.set_title(f"{title}: control curve" + ("s" if len(curves) > 1 else ""))
    return fig


def fuzzy_overview_figure(controller: FuzzyController) -> Figure:
    """Membership functions (left, inputs then output) beside the curve or surface (right)."""
    _check_fuzzy(controller, "fuzzy_overview_figure")
    n = len(controller.system.inputs) + 1
    two_inputs = n == 3
    fig = Figure(figsize=(13.0, max(5.2, 0.6 + _PANEL_HEIGHT_IN * n)), layout="constrained")
    grid = fig.add_gridspec(n, 2, width_ratios=(1.0, 1.15 if two_inputs else 1.0))
    mf_axes = [fig.add_subplot(grid[k, 0]) for k in range(n)]
    _membership_panels(mf_axes, controller)
    if two_inputs:
        ax = fig.add_subplot(grid[:, 1], projection="3d")
        _surface_panel(ax, controller)
        ax.set_title("control surface", fontsize=10)
    else:
        ax = fig.add_subplot(grid[:, 1])
        _curve_panel(ax, [controller])
        ax.set_title("control curve", loc="left", fontsize=10)
    fig.suptitle(_overview_title(controller))
    return fig


# -- checks ---------------------------------------------------------------------------


def _check_fuzzy(controller: object, caller: str) -> None:
    if not isinstance(controller, FuzzyController):
        name = getattr(controller, "name", "?")
        raise TypeError(
            f"{caller} needs a FuzzyController, got {type(controller).__name__} ({name!r}); "
            "membership functions and control curves exist only for fuzzy controllers"
        )


def _curve_set(
    controller: FuzzyController, compare: Sequence[FuzzyController] | None
) -> list[FuzzyController]:
    _check_fuzzy(controller, "control_curve_figure")
    others = list(compare or [])
    for other in others:
        _check_fuzzy(other, "control_curve_figure (compare)")
    n_in = len(controller.system.inputs)
    if n_in == 2 and others:
        raise ValueError(
            f"{controller.name!r} has two inputs and is drawn as a surface, which cannot be "
            f"overlaid, but compare got {[c.name for c in others]}; draw one figure each"
        )
    curves = [controller, *others]
    if n_in == 2:
        return curves
    wrong = [c.name for c in curves if len(c.system.inputs) != 1]
    if wrong:
        raise ValueError(
            f"control curves compare one-input controllers, but {wrong} have two inputs; "
            "leave them out of compare"
        )
    integrating = {c.name: c.form == "pi" for c in curves}
    if len(set(integrating.values())) > 1:
        raise ValueError(
            "a 'pi' controller's curve is a rate u̇ [V/s], the others' a command u [V], "
            f"so they cannot share an axis (pi: {integrating}); compare like forms"
        )
    return curves


# -- labels ---------------------------------------------------------------------------


def _symbol(variable: Variable, role: str) -> str:
    if role == "rate" and variable.name.lower() in _RATE_NAMES:
        return "ė"
    return variable.name


def _roles(controller: FuzzyController) -> list[tuple[Variable, str, str, float]]:
    """(variable, role, axis label, factor from universe to loop units) per panel."""
    system = controller.system
    rows = [(system.inputs[0], "error", "V", 1.0 / controller.input_gain)]
    if len(system.inputs) == 2:
        rows.append((system.inputs[1], "rate", "V/s", 1.0 / controller.rate_gain))
    out_unit = "V/s" if controller.form == "pi" else "V"
    rows.append((system.output, "output", out_unit, controller.output_gain))
    out = []
    for var, role, unit, factor in rows:
        symbol = _symbol(var, role)
        if role == "output" and controller.form == "pi":
            symbol += "\u0307"  # the curve of an incremental PI is the rate u̇
        out.append((var, role, f"{symbol} [{unit}]", factor))
    return out


def _output_label(controller: FuzzyController) -> str:
    return _roles(controller)[-1][2]


def _input_labels(controller: FuzzyController) -> list[str]:
    return [label for _, role, label, _ in _roles(controller) if role != "output"]


def _overview_title(controller: FuzzyController) -> str:
    system = controller.system
    gains = [
        f"G_e = {controller.input_gain:g}",
        *([f"G_ė = {controller.rate_gain:g}"] if len(system.inputs) == 2 else []),
        f"G_u = {controller.output_gain:g}",
    ]
    methods = (
        f"{system.and_method}/{system.implication}/{system.aggregation}/{system.defuzzification}"
    )
    return (
        f"{controller.name} — form {controller.form}, {len(system.rules)} rules, "
        f"{methods}, {', '.join(gains)}"
    )


# -- panels ---------------------------------------------------------------------------


def _loop_range(var: Variable, factor: float) -> tuple[float, float]:
    a, b = var.low * factor, var.high * factor
    return (a, b) if a <= b else (b, a)


def _membership_panels(axes: list[Axes], controller: FuzzyController) -> None:
    for ax, (var, role, label, factor) in zip(axes, _roles(controller), strict=True):
        _membership_panel(ax, var, label, factor)
        kind = "output" if role == "output" else "input"
        gain_note = "" if factor == 1.0 else f" (universe × {factor:.4g})"
        ax.set_title(
            f"{kind} {label.split(' [')[0]}: {len(var.terms)} terms{gain_note}",
            loc="left",
            fontsize=10,
        )


def _membership_panel(ax: Axes, var: Variable, label: str, factor: float) -> None:
    universe, degrees = var.table()
    x = universe * factor
    low, high = _loop_range(var, factor)
    span = high - low
    pad = 0.04 * span
    for k, mu in enumerate(degrees):
        ax.plot(x, mu, color=_TERM_COLOURS[k % len(_TERM_COLOURS)], lw=1.6)
    _annotate_peaks(ax, var, x, degrees, low, span)
    for edge in (low, high):
        ax.axvline(edge, color="0.35", ls="--", lw=0.9)
    ax.axvspan(low - pad, low, color="0.9", lw=0, zorder=0)
    ax.axvspan(high, high + pad, color="0.9", lw=0, zorder=0)
    ax.set_xlim(low - pad, high + pad)
    ax.set_ylim(-0.03, 1.27)
    ax.set_yticks([0.0, 0.5, 1.0])
    ax.set_ylabel("membership μ")
    ax.set_xlabel(label)
    ax.grid(True, color="0.88", lw=0.6)
    ax.set_axisbelow(True)


def _annotate_peaks(
    ax: Axes, var: Variable, x: np.ndarray, degrees: np.ndarray, low: float, span: float
) -> None:
    """Write each term's name above its peak; crowded names alternate between two rows."""
    last_in_row = [-np.inf, -np.inf]
    for k, (term, mu) in enumerate(zip(var.terms, degrees, strict=True)):
        top = float(mu.max())
        if top <= 0.0:
            continue  # the term lies wholly outside the range
        at = x[mu >= top - 1e-9]
        peak = 0.5 * (float(at.min()) + float(at.max()))
        frac = (peak - low) / span
        row = 0 if frac - last_in_row[0] >= _LABEL_GAP else 1
        if row == 1 and frac - last_in_row[1] < _LABEL_GAP:
            row = 0  # both rows crowded: the lower row reads better
        last_in_row[row] = frac
        # a name at a range edge is aligned inwards so it stays inside the axes
        ha = "left" if frac < 0.03 else "right" if frac > 0.97 else "center"
        ax.annotate(
            term.name,
            (peak, top),
            xytext=(0, 3 + 11 * row),
            textcoords="offset points",
            ha=ha,
            va="bottom",
            fontsize=8,
            fontweight="bold",
            color=_TERM_COLOURS[k % len(_TERM_COLOURS)],
        )


def _curve_panel(ax: Axes, controllers: list[FuzzyController]) -> None:
    first = controllers[0]
    lows, highs = [], []
    for k, c in enumerate(controllers):
        var = c.system.inputs[0]
        low, high = _loop_range(var, 1.0 / c.input_gain)
        lows.append(low)
        highs.append(high)
        e = np.union1d(np.linspace(low, high, _CURVE_POINTS), [0.0] if low < 0 < high else [])
        u = c.curve(e)
        colour = controller_colour(k)
        label = c.name
        crossing = _zero_crossing(e, u)
        if crossing is not None:
            label += f" (u = 0 at e = {crossing:+.3g} V)".replace("-", "\u2212")
            ax.plot([crossing], [0.0], "o", color=colour, ms=5, mfc="white", mew=1.4, zorder=4)
        ax.plot(e, u, color=colour, lw=1.7, label=label, zorder=3)
    ax.axhline(0.0, color="0.3", lw=0.8, zorder=2)
    ax.axvline(0.0, color="0.3", lw=0.8, zorder=2)
    low, high = min(lows), max(highs)
    ax.set_xlim(low - 0.02 * (high - low), high + 0.02 * (high - low))
    ax.set_xlabel(_input_labels(first)[0])
    ax.set_ylabel(_output_label(first))
    ax.grid(True, color="0.88", lw=0.6)
    ax.set_axisbelow(True)
    ax.legend(loc="upper left", fontsize=8)


def _zero_crossing(e: np.ndarray, u: np.ndarray) -> float | None:
    """The error where the curve first crosses u = 0 (linear between samples), if it does."""
    exact = np.flatnonzero(u == 0.0)
    if exact.size:
        return float(e[exact[0]])
    change = np.flatnonzero(np.sign(u[:-1]) * np.sign(u[1:]) < 0)
    if not change.size:
        return None
    j = change[0]
    return float(e[j] - u[j] * (e[j + 1] - e[j]) / (u[j + 1] - u[j]))


def _surface_panel(ax: Axes, controller: FuzzyController) -> None:
    e_var, de_var = controller.system.inputs
    e_range = _loop_range(e_var, 1.0 / controller.input_gain)
    de_range = _loop_range(de_var, 1.0 / controller.rate_gain)
    e, de = np.meshgrid(
        np.linspace(*e_range, _SURFACE_POINTS), np.linspace(*de_range, _SURFACE_POINTS)
    )
    u = controller.curve(e, de)
    ax.plot_surface(e, de, u, cmap="viridis", edgecolor="0.2", lw=0.15, antialiased=True)
    e_label, de_label = _input_labels(controller)
    ax.set_xlabel(e_label, labelpad=8)
    ax.set_ylabel(de_label, labelpad=8)
    ax.zaxis.set_rotate_label(False)
    ax.set_zlabel(_output_label(controller), rotation=90, labelpad=8)
    # MATLAB's gensurf viewpoint (az = −37.5°, el = 30°).
    ax.view_init(elev=30.0, azim=-127.5)
    ax.set_xlim(*e_range)
    ax.set_ylim(*de_range)
    # Both input axes end at the front corner: the rate axis leaves its lowest tick
    # unlabelled so the two numbers there do not overprint.
    for axis, prune in ((ax.xaxis, None), (ax.yaxis, "lower"), (ax.zaxis, None)):
        axis.set_major_locator(MaxNLocator(5, steps=[1, 2, 2.5, 5, 10], prune=prune))
    ax.tick_params(labelsize=8, pad=1)
    ax.set_box_aspect(None, zoom=0.9)  # room for the axis labels inside the figure
