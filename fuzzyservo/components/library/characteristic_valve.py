"""A critically lapped 4-way proportional valve from its measured flow curve (seed 003 eq. 7).

The curve Q(U) = c4·U⁴ + c3·U³ + c2·U² + c1·U + c0 was measured at a pressure drop Δp_nom
per metering edge, with U clipped to ±U_max; each edge passes Q(U)·√(Δp/Δp_nom) (the
orifice law), U > 0 opening P→A and B→T, U < 0 P→B and A→T. ``line_resistance`` puts
a laminar line behind ports A and B.

``orifice_valve`` is the ideal valve on the same four edges, opening linearly in U:
each passes C·(U/U_max)·√Δp (seed 003's third valve model, C from eq. 7 at ±U_max).
"""

from __future__ import annotations

import math
from typing import Any

from fuzzyservo.components.declare import Component, Param, Signal, phase
from fuzzyservo.components.valves import four_edges, polynomial_flow

_SIGNALS = (
    Signal("q_a", "m^3/s", "q_va", "flow out of port A"),
    Signal("q_b", "m^3/s", "q_vb", "flow out of port B"),
    Signal("q_supply", "m^3/s", "q_supply", "flow drawn from P"),
    Signal("q_tank", "m^3/s", "q_tank", "flow returned to T"),
)


# the openings run apart from the edges (components/valves.py four_edges): they read no
# pressure, so the loop's Jacobian does not evaluate them again for each pressure it perturbs
@phase("c_pa", "c_pb")
def measured_curve(P: Any, u: float) -> tuple[float, float]:
    """The edges' coefficients from Q(U)/√Δp_nom, U clipped to ±U_max (positive opens
    P→A and B→T)."""
    umax = P.control_voltage_max
    uc = min(max(u, -umax), umax)
    k = polynomial_flow(
        uc, umax, P.flow_c0, P.flow_c1, P.flow_c2, P.flow_c3, P.flow_c4
    ) / math.sqrt(P.nominal_pressure_drop)
    return max(k, 0.0), max(-k, 0.0)


@phase("c_pa", "c_pb")
def linear_orifice(P: Any, u: float) -> tuple[float, float]:
    """The edges' coefficients C·(U/U_max), U clipped to ±U_max."""
    umax = P.control_voltage_max
    uc = min(max(u, -umax), umax)
    k = P.orifice_coefficient * uc / umax
    return max(k, 0.0), max(-k, 0.0)


_RANGE = Param("control_voltage_max", "V", "U_max: the curve's range", positive=True)

COMPONENTS = (
    Component(
        type="characteristic_valve",
        role="valve",
        doc="proportional valve given by a measured flow polynomial in its voltage",
        source="seed 003 eq. 7 and §3 (Hydroprax, Rexroth 4WRE 6)",
        params=(
            _RANGE,
            Param("flow_c0", "m^3/s", "c0", default=0.0),
            Param("flow_c1", "m^3/(s*V)", "c1"),
            Param("flow_c2", "m^3/(s*V^2)", "c2", default=0.0),
            Param("flow_c3", "m^3/(s*V^3)", "c3", default=0.0),
            Param("flow_c4", "m^3/(s*V^4)", "c4", default=0.0),
            Param(
                "nominal_pressure_drop",
                "Pa",
                "Δp_nom per edge where the curve holds",
                positive=True,
            ),
        ),
        signals=_SIGNALS,
        code={"valve": (measured_curve, four_edges)},
        effects=("line_resistance",),
        scales=lambda v: {
            "flow": abs(
                v["flow_c1"] * v["control_voltage_max"]
                + v["flow_c3"] * v["control_voltage_max"] ** 3
            ),
            "input": v["control_voltage_max"],
        },
        input=("u_c", "V"),
    ),
    Component(
        type="orifice_valve",
        role="valve",
        doc="ideal proportional valve: each edge C·(U/U_max)·√Δp",
        source="seed 003 §2 (the ideal orifice valve model)",
        params=(
            _RANGE,
            Param(
                "orifice_coefficient",
                "m^3/(s*sqrt(Pa))",
                "C: an edge's flow per √Pa at U_max",
                positive=True,
            ),
        ),
        signals=_SIGNALS,
        code={"valve": (linear_orifice, four_edges)},
        effects=("line_resistance",),
        scales=lambda v: {
            "flow_coefficient": v["orifice_coefficient"],
            "input": v["control_voltage_max"],
        },
        input=("u_c", "V"),
    ),
)
