"""A fixed pump with a relief valve feeding a volume (seed 003 eq. 1).

    dp_s/dt = E/V·(Q_pump − Q_relief(p_s) − q_supply)
    Q_relief = K_r·(d + √(d² + δ²))/2,  d = p_s − p_crack,  K_r = Q_pump/(p_nom − p_crack)

The relief opens at the cracking pressure and passes the whole pump flow at the
nominal pressure; when the valve draws more than the pump delivers, p_s sags.
``entrained_air`` gives the volume E_mix(p) instead of E.
"""

from __future__ import annotations

import math
from typing import Any

from fuzzyservo.components.declare import Component, Param, Signal, State, phase
from fuzzyservo.components.effects import chamber_modulus


@phase("p_s", "p_t")
def pump_pressure(P: Any, X: Any) -> tuple[float, float]:
    return X.p_s, P.tank_pressure


@phase("d", "kr", "q_relief", "q_net", "dx_p_s")
def relief(
    P: Any, p: Any, p_s: float, q_supply: float, beta: float
) -> tuple[float, float, float, float, float]:
    """The relief's flow and the supply volume's pressure."""
    d = p_s - P.relief_cracking_pressure
    kr = P.pump_flow / (P.supply_pressure - P.relief_cracking_pressure)
    q_relief = 0.5 * kr * (d + math.sqrt(d * d + P.relief_knee * P.relief_knee))
    q_net = P.pump_flow - q_relief - q_supply
    return d, kr, q_relief, q_net, chamber_modulus(p_s, q_net, beta, p) / P.supply_volume * q_net


def _resting(v: dict[str, float]) -> float:
    """p_s where the relief passes the whole pump flow (no valve flow)."""
    kr = v["pump_flow"] / (v["supply_pressure"] - v["relief_cracking_pressure"])
    a = 2.0 * v["pump_flow"] / kr
    return v["relief_cracking_pressure"] + (a * a - v["relief_knee"] ** 2) / (2.0 * a)


def _check(v: dict[str, float]) -> str | None:
    if not v["relief_cracking_pressure"] < v["supply_pressure"]:
        return (
            "relief_cracking_pressure: `relief_cracking_pressure < supply_pressure` must hold, "
            f"but got ({v['relief_cracking_pressure']} Pa, {v['supply_pressure']} Pa); the "
            "relief passes the whole pump flow at the nominal supply pressure"
        )
    return None


COMPONENTS = (
    Component(
        type="pump_supply",
        role="supply",
        doc="fixed-displacement pump Q_pump into a volume V, relief valve from p_crack to "
        "p_nom; tank at p_t",
        source="seed 003 eq. 1 and Table 1 (Hydroprax); Hopsan HydraulicPressureReliefValve",
        params=(
            Param("pump_flow", "m^3/s", "pump delivery Q_pump", positive=True),
            Param(
                "supply_pressure",
                "Pa",
                "p_nom: the relief passes all of Q_pump here",
                positive=True,
            ),
            Param(
                "relief_cracking_pressure",
                "Pa",
                "p_crack: the relief starts to open",
                positive=True,
            ),
            Param("relief_knee", "Pa", "δ: rounds the relief's corner", default=5e3, positive=True),
            Param("supply_volume", "m^3", "oil volume between pump and valve", positive=True),
            Param(
                "tank_pressure",
                "Pa",
                "pressure at the valve's T port",
                default=0.0,
                nonnegative=True,
            ),
        ),
        states=(State("p_s", "Pa", "supply pressure", "supply", 1e3, 1e6),),
        signals=(
            Signal("p_s", "Pa", "p_s"),
            Signal("p_t", "Pa", "p_t"),
            Signal("q_pump", "m^3/s", "pump_flow"),
            Signal("q_relief", "m^3/s", "q_relief"),
        ),
        code={"supply": pump_pressure, "supply_flow": relief},
        initial_keys={"pressure_s": ("p_s", "Pa")},
        initial=lambda v, ctx: {
            "p_s": ctx.get("p_s", _resting(v)),
            "p_t": v["tank_pressure"],
        },
        scales=lambda v: {"pressure": v["supply_pressure"] - v["tank_pressure"]},
        check=_check,
        effects=("entrained_air",),
        refuses={"supply_droop": "limits the flow to its pump_flow already; fit that instead"},
    ),
)
