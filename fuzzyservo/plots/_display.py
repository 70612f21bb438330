"""Display units and labels shared by the figures: SI signals in, engineer's units out."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from fuzzyservo.simulation.result import SimResult
from fuzzyservo.units import parse_unit, to_si

# The unit a quantity is read in on a test bench, by its SI dimension (a rig's
# ``display_units`` overrides these per signal).
_PREFERRED = ("bar", "mA", "l/min")

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
    """The unit ``name`` is shown in: the rig's choice, else bar/mA/l/min, else SI."""
    if name in result.display_units:
        return result.display_units[name]
    dims = parse_unit(si_unit).dims
    for unit in _PREFERRED:
        if parse_unit(unit).dims == dims:
            return unit
    return si_unit


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


def axis_label(name: str, unit: str) -> str:
    quantity = _QUANTITY.get(name)
    text = f"{quantity} {name}" if quantity else name
    return f"{text} [{unit}]" if unit else text


def label_span(ax: Axes, start: float, end: float, text: str) -> None:
    """A small grey label at the top of a shaded time span (warm-up, validation)."""
    ax.text(
        0.5 * (start + end),
        0.98,
        text,
        transform=ax.get_xaxis_transform(),
        ha="center",
        va="top",
        fontsize=8,
        color="0.45",
    )


def save(fig: Figure, path: str | Path) -> Path:
    """Write ``fig`` to ``path`` (PNG unless the suffix names another format) at 120 dpi.

    Creates the parent folder; leaves the figure open and touches no pyplot state.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fmt = path.suffix[1:].lower() or "png"
    fig.savefig(path, dpi=120, format=fmt)
    return path
