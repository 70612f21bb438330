"""Supply and return through restrictions into the valve's own chambers (seed 002 eq. 17-18).

    dp_s/dt = E/V_s·(q_in − q_supply),   q_in = R_a·√(p_a − p_s)
    dp_t/dt = E/V_t·(q_tank − q_ret),    q_ret = R_r·√(p_t − p_r)

``supply_droop`` caps q_in at the pump's delivery; ``entrained_air`` gives each volume
E_mix(p) instead of E.
"""

from __future__ import annotations

from typing import Any

from fuzzyservo.components.declare import Component, Param, Signal, State, phase
from fuzzyservo.components.effects import chamber_modulus, pump_limited
from fuzzyservo.components.orifice import signed_sqrt_flow


@phase("p_s", "p_t")
def chamber_pressures(X: Any) -> tuple[float, float]:
    return X.p_s, X.p_t


@phase("q_in", "q_ret", "dx_p_s", "dx_p_t")
def restrictions(
    P: Any,
    p: Any,
    p_s: float,
    p_t: float,
    q_supply: float,
    q_tank: float,
    beta: float,
    p_lam: float,
) -> tuple[float, float, float, float]:
    """Flows through R_a (capped by ``supply_droop``) and R_r; the chambers' pressures."""
    q_in = pump_limited(signed_sqrt_flow(P.supply_resistance, P.supply_pressure - p_s, p_lam), p)
    q_ret = signed_sqrt_flow(P.return_resistance, p_t - P.return_pressure, p_lam)
    es = chamber_modulus(p_s, q_in - q_supply, beta, p)
    et = chamber_modulus(p_t, q_tank - q_ret, beta, p)
    return (
        q_in,
        q_ret,
        es / P.supply_volume * (q_in - q_supply),
        et / P.return_volume * (q_tank - q_ret),
    )


COMPONENTS = (
    Component(
        type="restriction_supply",
        role="supply",
        doc="constant pressures behind turbulent restrictions R_a, R_r into the valve's "
        "supply and return chambers (volumes V_s, V_t)",
        source="seed 002 eq. 3-4, 17-18 (Dinca & Corcau)",
        params=(
            Param("supply_pressure", "Pa", "pressure upstream of R_a", positive=True),
            Param(
                "return_pressure", "Pa", "pressure downstream of R_r", default=0.0, nonnegative=True
            ),
            Param("supply_resistance", "m^3/(s*sqrt(Pa))", "R_a: q = R_a·√Δp", positive=True),
            Param("return_resistance", "m^3/(s*sqrt(Pa))", "R_r: q = R_r·√Δp", positive=True),
            Param("supply_volume", "m^3", "valve supply chamber V_s", positive=True),
            Param("return_volume", "m^3", "valve return chamber V_t", positive=True),
        ),
        states=(
            State("p_s", "Pa", "supply chamber pressure", "supply", 1e3, 1e6),
            State("p_t", "Pa", "return chamber pressure", "supply", 1e3, 1e6),
        ),
        signals=(
            Signal("p_s", "Pa", "p_s"),
            Signal("p_t", "Pa", "p_t"),
            Signal("q_in", "m^3/s", "q_in", "flow through R_a"),
            Signal("q_ret", "m^3/s", "q_ret", "flow through R_r"),
        ),
        code={"supply": chamber_pressures, "supply_flow": restrictions},
        effects=("supply_droop", "entrained_air"),
        initial_keys={"pressure_s": ("p_s", "Pa"), "pressure_t": ("p_t", "Pa")},
        initial=lambda v, ctx: {
            "p_s": ctx.get("p_s", v["supply_pressure"]),
            "p_t": ctx.get("p_t", v["return_pressure"]),
        },
        scales=lambda v: {"pressure": v["supply_pressure"] - v["return_pressure"]},
        check=lambda v: (
            None
            if v["supply_pressure"] > v["return_pressure"]
            else "supply_pressure: must exceed return_pressure; check both values and their units"
        ),
    ),
)
