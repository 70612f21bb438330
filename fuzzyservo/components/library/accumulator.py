"""A gas-loaded accumulator on the supply node, behind a laminar inlet (Hopsan's
HydraulicAckumulator).

The gas, pre-charged to p_0 in the volume V_0, is compressed polytropically by the oil
volume V_oil it lets in; the inlet is a laminar restriction K between the supply node
(p_s) and the accumulator:

    p_gas = p_0·(V_0 / (V_0 − V_oil))^n,   q = K·(p_s − p_gas),   dV_oil/dt = q

and the supply node sees one more consumer: ``q_supply += q``. The exponent n is 1.4
(adiabatic nitrogen) for transients shorter than the gas's thermal time constant (a few
seconds), 1.0 (isothermal) for slow cycles. An empty accumulator (V_oil = 0: the gas at
its pre-charge, the membrane on the poppet) delivers nothing more, however far p_s
falls below p_0; it only charges again once p_s exceeds p_0.
"""

from __future__ import annotations

from typing import Any

from fuzzyservo.components.declare import Component, Param, Signal, State, phase


@phase("v_gas", "p_gas", "q", "dx_v_oil", "q_supply")
def gas_loaded(P: Any, X: Any, p_s: float, q_supply: float) -> tuple[float, ...]:
    """The gas's pressure, the inlet flow (none out of an empty accumulator), the supply
    node's one more consumer."""
    v_gas = max(min(P.gas_volume - X.v_oil, P.gas_volume), 1e-9 * P.gas_volume)
    p_gas = P.precharge_pressure * (P.gas_volume / v_gas) ** P.polytropic_exponent
    q = P.inlet_conductance * (p_s - p_gas)
    q = max(q, 0.0) if X.v_oil <= 0.0 else q
    return v_gas, p_gas, q, q, q_supply + q


def _charged(v: dict[str, float], ctx: dict[str, float]) -> dict[str, float]:
    """The oil volume at rest, in balance with the supply pressure (no inlet flow)."""
    p_s = ctx["p_s"]
    if p_s <= v["precharge_pressure"]:
        return {"v_oil": 0.0}
    ratio = (v["precharge_pressure"] / p_s) ** (1.0 / v["polytropic_exponent"])
    return {"v_oil": v["gas_volume"] * (1.0 - ratio)}


COMPONENTS = (
    Component(
        type="accumulator",
        role="accumulator",
        doc="gas-loaded accumulator on the supply node: pre-charge p_0 in V_0, polytropic "
        "gas p·V^n = const, laminar inlet K; empty below p_0",
        source="Hopsan HydraulicAckumulator (V0, Kca, kappa, p0); polytropic law "
        "p_0·V_0^n = p·V^n of gas-loaded accumulators (e.g. Esposito, Fluid Power with "
        "Applications, accumulator sizing)",
        params=(
            Param("precharge_pressure", "Pa", "p_0: the gas pressure when empty", positive=True),
            Param("gas_volume", "m^3", "V_0: the gas volume when empty (the size)", positive=True),
            Param(
                "polytropic_exponent",
                "1",
                "n: 1.4 adiabatic (fast transients), 1.0 isothermal (slow cycles)",
                default=1.4,
                minimum=1.0,
                maximum=1.67,
            ),
            Param(
                "inlet_conductance",
                "m^3/(s*Pa)",
                "K: laminar inlet q = K·Δp (a throttle: smaller K)",
                default=1e-8,
                positive=True,
            ),
        ),
        states=(State("v_oil", "m^3", "oil volume in the accumulator", "supply", 1e-8, 1e-5),),
        signals=(
            Signal("p_acc", "Pa", "p_gas", "gas pressure"),
            Signal("q_acc", "m^3/s", "q", "flow into the accumulator"),
            Signal("v_acc", "m^3", "v_oil", "oil volume in the accumulator"),
        ),
        code={"node": gas_loaded},
        initial=_charged,
    ),
)
