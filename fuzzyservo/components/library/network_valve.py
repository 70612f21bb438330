"""A 4-way proportional valve given by a trained network (seed 003 §2-5).

The feed-forward network maps (p_s, U, p_a, p_b) to the flows (Q_A, Q_B) out of ports A
and B (4-5-2, tanh/linear; :mod:`fuzzyservo.components.valves`), with U clipped to
±U_max; the supply passes Q_A for U ≥ 0 and Q_B otherwise (the edge P→A or P→B that
is open), the rest returns to the tank. ``fuzzyservo fit-valve`` trains the weights on
measured valve data and writes the file the rig names under ``weights``.
"""

from __future__ import annotations

from typing import Any

from fuzzyservo.components.declare import Component, Param, Signal, phase
from fuzzyservo.components.valves import NN_SIZE, nn_forward


@phase("q_va", "q_vb", "q_supply", "q_tank")
def network_flows(
    P: Any, p: Any, u: float, p_s: float, p_a_port: float, p_b_port: float
) -> tuple[float, float, float, float]:
    """The network's port flows at the clipped command; the open edge's flow from P."""
    umax = P.control_voltage_max
    uc = min(max(u, -umax), umax)
    q_va, q_vb = nn_forward(p, P.weights, p_s, uc, p_a_port, p_b_port)
    q_supply = q_va if uc >= 0.0 else q_vb
    q_tank = q_supply - q_va - q_vb
    return q_va, q_vb, q_supply, q_tank


COMPONENTS = (
    Component(
        type="network_valve",
        role="valve",
        doc="proportional valve given by a network trained on its measured flows",
        source="seed 003 §2-5 (feed-forward network, Levenberg-Marquardt)",
        params=(
            Param("control_voltage_max", "V", "U_max: the command's range", positive=True),
            Param(
                "weights",
                "1",
                "name the JSON file written by `fuzzyservo fit-valve`",
                length=NN_SIZE,
                fmt="valve_network",
            ),
        ),
        signals=(
            Signal("q_a", "m^3/s", "q_va", "flow out of port A"),
            Signal("q_b", "m^3/s", "q_vb", "flow out of port B"),
            Signal("q_supply", "m^3/s", "q_supply", "flow drawn from P"),
            Signal("q_tank", "m^3/s", "q_tank", "flow returned to T"),
        ),
        code={"valve": network_flows},
        scales=lambda v: {"input": v["control_voltage_max"]},
        input=("u_c", "V"),
    ),
)
