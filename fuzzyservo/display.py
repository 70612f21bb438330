"""How signals are shown: display units, axis labels, colours and saturated spans.

SI signals in, an engineer's units out (bar, mA, l/min unless the rig says otherwise).
Shared by the matplotlib figures (:mod:`fuzzyservo.plots`) and the designer's browser
plots, so both show a signal the same way; nothing here draws.
"""

from __future__ import annotations

import numpy as np

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
    "PRESSURE_COLOURS",
    "axis_label",
    "controller_colour",
    "display_unit",
    "saturated_spans",
    "signal_unit",
    "to_display",
]
