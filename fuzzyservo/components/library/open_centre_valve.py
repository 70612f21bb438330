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

from typing import Any

from fuzzyservo.components.declare import Component, Param, Signal, phase
from fuzzyservo.components.valves import four_edges


# the openings run apart from the slots' flows (components/valves.py four_edges): they
# read no pressure, so the loop's Jacobian does not evaluate them again per pressure
@phase("c_pa", "c_pb")
def openings(P: Any, u: float) -> tuple[float, float]:
    """The slots' coefficients at Δi = u − I_bias (slots 1 and 4: P→A, B→T; slots 2 and
    3: A→T, P→B), each shut beyond its closing current."""
    di = u - P.bias_current
    c14 = P.slot_coefficient_a + P.slot_coefficient_b * di
    c23 = P.slot_coefficient_a - P.slot_coefficient_b * di
    if di >= P.closing_current:
        c23 = 0.0
    if di <= -P.closing_current:
        c14 = 0.0
    return max(c14, 0.0), max(c23, 0.0)


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
            Signal("q1", "m^3/s", "q_pa", "slot 1: P→A"),
            Signal("q2", "m^3/s", "q_at", "slot 2: A→T"),
            Signal("q3", "m^3/s", "q_pb", "slot 3: P→B"),
            Signal("q4", "m^3/s", "q_bt", "slot 4: B→T"),
            Signal("q_a", "m^3/s", "q_va", "flow out of port A"),
            Signal("q_b", "m^3/s", "q_vb", "flow out of port B"),
            Signal("q_supply", "m^3/s", "q_supply", "flow drawn from P"),
            Signal("q_tank", "m^3/s", "q_tank", "flow returned to T"),
        ),
        code={"valve": (openings, four_edges)},
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
