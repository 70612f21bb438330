"""A constant-pressure supply and tank (an accumulator or a large pressure-controlled pump)."""

from __future__ import annotations

from typing import Any

from fuzzyservo.components.declare import Component, Param, Signal, phase


@phase("p_s", "p_t")
def pressures(P: Any) -> tuple[float, float]:
    return P.supply_pressure, P.tank_pressure


COMPONENTS = (
    Component(
        type="ideal_supply",
        role="supply",
        doc="p_s = supply_pressure and p_t = tank_pressure whatever the valve draws",
        source="Hopsan HydraulicPressureSourceC; seed 000 (constant P_s)",
        params=(
            Param("supply_pressure", "Pa", "pressure at the valve's P port", positive=True),
            Param(
                "tank_pressure",
                "Pa",
                "pressure at the valve's T port",
                default=0.0,
                nonnegative=True,
            ),
        ),
        signals=(Signal("p_s", "Pa", "p_s"), Signal("p_t", "Pa", "p_t")),
        code={"supply": pressures},
        initial=lambda v, ctx: {"p_s": v["supply_pressure"], "p_t": v["tank_pressure"]},
        scales=lambda v: {"pressure": v["supply_pressure"] - v["tank_pressure"]},
        refuses={
            "supply_droop": "holds its pressure whatever the flow; compose a pump_supply "
            "(or restriction_supply) to model a pump's limit"
        },
        check=lambda v: (
            None
            if v["supply_pressure"] > v["tank_pressure"]
            else "supply_pressure: must exceed tank_pressure; check both values and their units"
        ),
    ),
)
