"""The open-centre servo-valve of seed 002 (Dinca & Corcau eq. 13-16).

Four slots whose opening coefficients move linearly with Δi = i − I_bias:

    Q1 = (a + b·Δi)·√(p_s − p_A),  Q2 = (a − b·Δi)·√(p_A − p_t)
    Q3 = (a − b·Δi)·√(p_s − p_B),  Q4 = (a + b·Δi)·√(p_B − p_t)

Closing-current logic: beyond Δi ≥ +I_cl slots 2 and 3 are shut, beyond Δi ≤ −I_cl
slots 1 and 4 (each slot closes where its coefficient reaches zero, I_cl = a/b). Every
√ is the regularised orifice law. ``line_resistance`` puts a laminar line behind ports
A and B. The valve's null is the bias current.
"""

from __future__ import annotations

from fuzzyservo.components.declare import Component, Param, Signal

COMPONENTS = (
    Component(
        type="open_centre_valve",
        role="valve",
        doc="open-centre servo-valve: slot coefficients a ± b·(i − I_bias), closing current",
        source="seed 002 eq. 13-16 (Dinca & Corcau)",
        params=(
            Param("slot_coefficient_a", "m^3/(s*sqrt(Pa))", "a: every slot at null", positive=True),
            Param(
                "slot_coefficient_b", "m^3/(s*A*sqrt(Pa))", "b: opening per ampere", positive=True
            ),
            Param("closing_current", "A", "I_cl: a slot pair shuts beyond ±I_cl", positive=True),
            Param("bias_current", "A", "I_bias: the current of hydraulic null", default=0.0),
        ),
        signals=(
            Signal("q1", "m^3/s", "L.q1", "slot 1: P→A"),
            Signal("q2", "m^3/s", "L.q2", "slot 2: A→T"),
            Signal("q3", "m^3/s", "L.q3", "slot 3: P→B"),
            Signal("q4", "m^3/s", "L.q4", "slot 4: B→T"),
            Signal("q_a", "m^3/s", "q_va", "flow out of port A"),
            Signal("q_b", "m^3/s", "q_vb", "flow out of port B"),
            Signal("q_supply", "m^3/s", "q_supply", "flow drawn from P"),
            Signal("q_tank", "m^3/s", "q_tank", "flow returned to T"),
        ),
        code={
            "valve": """
                L.di = u - P.bias_current
                L.c14 = P.slot_coefficient_a + P.slot_coefficient_b * L.di
                L.c23 = P.slot_coefficient_a - P.slot_coefficient_b * L.di
                if L.di >= P.closing_current:
                    L.c23 = 0.0
                if L.di <= -P.closing_current:
                    L.c14 = 0.0
                L.c14 = max(L.c14, 0.0)
                L.c23 = max(L.c23, 0.0)
                L.q1, L.q2, L.q3, L.q4 = metering_edges(
                    L.c14, L.c23, L.c23, L.c14, p_s, p_t, p_a_port, p_b_port,
                    E.line_resistance_pa_s_m3, p_lam,
                )
                q_va = L.q1 - L.q2
                q_vb = L.q3 - L.q4
                q_supply = L.q1 + L.q3
                q_tank = L.q2 + L.q4
            """
        },
        effects=("line_resistance",),
        scales=lambda v: {
            "flow_coefficient": v["slot_coefficient_a"]
            + v["slot_coefficient_b"] * v["closing_current"],
            "input": v["closing_current"],
        },
        null=lambda v: v["bias_current"],
        input=("i", "A"),
    ),
)
