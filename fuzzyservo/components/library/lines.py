"""A pair of hydraulic lines between the valve's ports A, B and the actuator.

Each line is a volume V (its oil, at the valve end) and a laminar resistance R to the
actuator chamber (Hopsan's volume-restriction chain; docs/modelling.md "line loss"):

    q = (p_line − p_chamber)/R,   dp_line/dt = E/V·(q_valve − q)

with E = E_mix(p_line) under the ``entrained_air`` effect (components/effects.py).
"""

from __future__ import annotations

from fuzzyservo.components.declare import Component, Param, Signal, State

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
            Signal("p_la", "Pa", "X.p_la"),
            Signal("p_lb", "Pa", "X.p_lb"),
            Signal("q_line_a", "m^3/s", "q_a", "flow into chamber A"),
            Signal("q_line_b", "m^3/s", "q_b", "flow into chamber B"),
        ),
        code={
            "line": "p_a_port = X.p_la\np_b_port = X.p_lb",
            "line_flow": """
                q_a = (X.p_la - p_a) / P.resistance
                q_b = (X.p_lb - p_b) / P.resistance
                L.ea = chamber_modulus(X.p_la, q_va - q_a, beta, p)
                L.eb = chamber_modulus(X.p_lb, q_vb - q_b, beta, p)
                DX.p_la = L.ea / P.volume * (q_va - q_a)
                DX.p_lb = L.eb / P.volume * (q_vb - q_b)
            """,
        },
        effects=("entrained_air",),
        initial=lambda v, ctx: {"p_la": ctx["p_a"], "p_lb": ctx["p_b"]},
    ),
)
