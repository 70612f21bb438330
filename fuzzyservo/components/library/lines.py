"""A pair of hydraulic lines between the valve's ports A, B and the actuator.

Each line is a volume V (its oil, at the valve end) and a laminar resistance R to the
actuator chamber (Hopsan's volume-restriction chain; docs/modelling.md "line loss"):

    q = (p_line − p_chamber)/R,   dp_line/dt = E/V·(q_valve − q)

with E = E_mix(p_line) under the ``entrained_air`` effect (components/effects.py).
"""

from __future__ import annotations

from typing import Any

from fuzzyservo.components.declare import Component, Param, Signal, State, phase
from fuzzyservo.components.effects import chamber_modulus


@phase("p_a_port", "p_b_port")
def line_pressures(X: Any) -> tuple[float, float]:
    """The valve's ports see the lines' pressures."""
    return X.p_la, X.p_lb


@phase("q_a", "q_b", "ea", "eb", "dx_p_la", "dx_p_lb")
def laminar_lines(
    P: Any, X: Any, p: Any, p_a: float, p_b: float, q_va: float, q_vb: float, beta: float
) -> tuple[float, ...]:
    """The flows through each line's resistance into the chambers; the lines' pressures."""
    q_a = (X.p_la - p_a) / P.resistance
    q_b = (X.p_lb - p_b) / P.resistance
    ea = chamber_modulus(X.p_la, q_va - q_a, beta, p)
    eb = chamber_modulus(X.p_lb, q_vb - q_b, beta, p)
    return q_a, q_b, ea, eb, ea / P.volume * (q_va - q_a), eb / P.volume * (q_vb - q_b)


COMPONENTS = (
    Component(
        type="lines",
        role="line",
        doc="two equal lines valve→actuator: laminar resistance R = 128·μ·L/(π·d⁴) and "
        "volume V = π·d²/4·L each",
        source="docs/modelling.md line loss; Hopsan HydraulicLaminarOrifice + HydraulicVolume",
        params=(
            Param("resistance", "Pa*s/m^3", "laminar resistance R of each line", positive=True),
            Param("volume", "m^3", "oil volume V of each line", positive=True),
        ),
        states=(
            State("p_la", "Pa", "pressure in line A", "line", 1e3, 1e6),
            State("p_lb", "Pa", "pressure in line B", "line", 1e3, 1e6),
        ),
        signals=(
            Signal("p_la", "Pa", "p_la"),
            Signal("p_lb", "Pa", "p_lb"),
            Signal("q_line_a", "m^3/s", "q_a", "flow into chamber A"),
            Signal("q_line_b", "m^3/s", "q_b", "flow into chamber B"),
        ),
        code={"line": line_pressures, "line_flow": laminar_lines},
        effects=("entrained_air",),
        initial=lambda v, ctx: {"p_la": ctx["p_a"], "p_lb": ctx["p_b"]},
    ),
)
