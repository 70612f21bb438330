"""A 4-way servo or proportional valve from its catalogue data, with spool dynamics.

Rated flow Q_N at the rated valve pressure drop Δp_N (both metering edges, e.g. 70 bar)
and the rated signal u_N. The spool ``x`` is normalised (1 at rated signal) and
follows the command ``x_c = clip(u/u_N, ±x_max)``:

    second order (f_n > 0):  ẍ = ω²(x_c − x) − 2ζω·ẋ,  ω = 2π·f_n
    first order (τ > 0):     τ·ẋ = x_c − x
    static (both 0):         x = x_c

``servo_valve`` and ``proportional_valve`` take every order and integrate the spool's
position and velocity; ``servo_valve_first_order`` and ``proportional_valve_first_order``
take a first-order or static spool and integrate its position only (one state fewer, in
the state vector and in the loop's Jacobian: the seed-000 and seed-001 valves).
and the openings are limited to the stroke ±x_max. The four metering edges with lap
``o`` (fraction of rated stroke: > 0 overlapped, 0 critically lapped, < 0 underlapped)
open as a_PA = a_BT = max(x − o, 0) and a_PB = a_AT = max(−x − o, 0); each passes
q = K·a·√Δp (the regularised orifice law), K = Q_N / ((1 − o)·√(Δp_N/2)) so that the
rated opening passes Q_N with Δp_N split over two edges. ``land_leakage`` K_l adds the
laminar clearance flow of every land, K_l·Δp on each of the four edges whatever the
spool position (seed 001 eq. 3-4, −K_l·(p0 − pa) and −K_l·pb), which holds a closed
valve's ports at (p_s + p_t)/2. ``line_resistance`` puts a laminar line behind ports A
and B (the port pressure balances edge and line flows); the land leakage, a small
laminar flow, is taken at the pressure behind that line.
"""

from __future__ import annotations

import math
from typing import Any

from fuzzyservo.components.declare import Component, Param, Signal, State, phase
from fuzzyservo.components.effects import E
from fuzzyservo.components.valves import metering_edges

_PARAMS = (
    Param("rated_flow", "m^3/s", "Q_N at rated signal and rated pressure drop", positive=True),
    Param("rated_pressure_drop", "Pa", "Δp_N over both metering edges (catalogue: 70 bar)",
          positive=True),
    Param("rated_signal", "input", "u_N: the signal that opens the valve fully", positive=True),
    Param("overlap", "1", "lap o as a fraction of rated stroke (> 0 overlap, < 0 underlap)",
          default=0.0, minimum=-0.5, maximum=0.5),
    Param("spool_natural_frequency", "Hz", "f_n of a second-order spool (0: not second order)",
          default=0.0, nonnegative=True),
    Param("spool_damping", "1", "ζ of the second-order spool", default=0.7, positive=True),
    Param("spool_time_constant", "s", "τ of a first-order spool (used when f_n = 0)",
          default=0.0, nonnegative=True),
    Param("stroke_limit", "1", "x_max: the spool's stroke as a fraction of rated",
          default=1.0, positive=True),
    Param("land_leakage", "m^3/(s*Pa)", "K_l: laminar clearance leakage of each land",
          default=0.0, nonnegative=True),
)  # fmt: skip


# The spool, by order: a second-order type keeps the spool velocity as a state; a
# first-order one does without (one state fewer to integrate and to difference in the
# Jacobian: the seed-000 and seed-001 valves are first order).
@phase("lim", "xc", "dx_xs", "dx_vs", "x")
def second_order_spool(P: Any, X: Any, u: float) -> tuple[float, float, float, float, float]:
    """The spool's opening x and its derivatives: second order, first order or static."""
    lim = P.stroke_limit
    xc = min(max(u / P.rated_signal, -lim), lim)
    if P.spool_natural_frequency > 0.0:
        w = 2.0 * math.pi * P.spool_natural_frequency
        dxs = X.vs
        dvs = w * w * (xc - X.xs) - 2.0 * P.spool_damping * w * X.vs
        x = min(max(X.xs, -lim), lim)
    elif P.spool_time_constant > 0.0:
        dxs = (xc - X.xs) / P.spool_time_constant
        dvs = 0.0
        x = min(max(X.xs, -lim), lim)
    else:
        dxs = 0.0
        dvs = 0.0
        x = xc
    return lim, xc, dxs, dvs, x


@phase("lim", "xc", "dx_xs", "x")
def first_order_spool(P: Any, X: Any, u: float) -> tuple[float, float, float, float]:
    """The spool's opening x and its derivative: first order or static."""
    lim = P.stroke_limit
    xc = min(max(u / P.rated_signal, -lim), lim)
    if P.spool_time_constant > 0.0:
        dxs = (xc - X.xs) / P.spool_time_constant
        x = min(max(X.xs, -lim), lim)
    else:
        dxs = 0.0
        x = xc
    return lim, xc, dxs, x


@phase("q_pa", "q_at", "q_pb", "q_bt", "q_va", "q_vb", "q_supply", "q_tank")
def edges(
    P: Any,
    p: Any,
    x: float,
    p_s: float,
    p_t: float,
    p_a_port: float,
    p_b_port: float,
    p_lam: float,
) -> tuple[float, ...]:
    """The four metering edges at the opening x, and the lands' clearance leakage."""
    k = P.rated_flow / ((1.0 - P.overlap) * math.sqrt(0.5 * P.rated_pressure_drop))
    c_pa = k * max(x - P.overlap, 0.0)
    c_pb = k * max(-x - P.overlap, 0.0)
    q_pa, q_at, q_pb, q_bt = metering_edges(
        c_pa, c_pb, c_pb, c_pa, p_s, p_t, p_a_port, p_b_port, p[E.line_resistance_pa_s_m3], p_lam
    )
    q_pa += P.land_leakage * (p_s - p_a_port)
    q_at += P.land_leakage * (p_a_port - p_t)
    q_pb += P.land_leakage * (p_s - p_b_port)
    q_bt += P.land_leakage * (p_b_port - p_t)
    return q_pa, q_at, q_pb, q_bt, q_pa - q_at, q_pb - q_bt, q_pa + q_pb, q_at + q_bt


_POSITION = State("xs", "1", "spool position (1 = rated opening)", "valve", 1e-5, 1.0)
# A first-order spool is a lag, not a resonance: 1e-4 of its rated opening is the local
# error of seeds 000 and 001's kernels (1 mV of a 10 V spool), which the seeds' compare
# results were measured with; 1e-5 cost them 10-15 % more steps for no visible change.
_LAG_POSITION = State("xs", "1", "spool position (1 = rated opening)", "valve", 1e-4, 1.0)
_VELOCITY = State("vs", "1/s", "spool velocity", "valve", 1e-2, 100.0)
_SIGNALS = (
    Signal("x_spool", "1", "x", "spool opening, limited to the stroke"),
    Signal("q_a", "m^3/s", "q_va", "flow out of port A"),
    Signal("q_b", "m^3/s", "q_vb", "flow out of port B"),
    Signal("q_supply", "m^3/s", "q_supply", "flow drawn from P"),
    Signal("q_tank", "m^3/s", "q_tank", "flow returned to T"),
)


def _valve(type_name: str, input_: tuple[str, str], doc: str, second_order: bool) -> Component:
    params = (
        _PARAMS
        if second_order
        else tuple(p for p in _PARAMS if p.key not in ("spool_natural_frequency", "spool_damping"))
    )
    return Component(
        type=type_name,
        role="valve",
        doc=doc,
        source="Hopsan Hydraulic43Valve (four edges with overlaps, second-order spool with a "
        "stroke limit); ISO 10770-1 rated flow at 70 bar valve drop; seed 001 eq. 3-4 "
        "(land leakage K_l)",
        params=params,
        states=(_POSITION, _VELOCITY) if second_order else (_LAG_POSITION,),
        signals=_SIGNALS,
        code={"valve": (second_order_spool if second_order else first_order_spool, edges)},
        effects=("line_resistance",),
        initial=(lambda v, ctx: {"xs": 0.0, "vs": 0.0})
        if second_order
        else (lambda v, ctx: {"xs": 0.0}),
        scales=lambda v: {
            "flow": v["rated_flow"] * v["stroke_limit"],
            "input": v["rated_signal"],
        },
        input=input_,
    )


COMPONENTS = (
    _valve(
        "servo_valve",
        ("i", "A"),
        "4-way servo-valve driven by a current: rated flow, pressure drop and current, "
        "lap, first- or second-order spool, stroke limit",
        second_order=True,
    ),
    _valve(
        "proportional_valve",
        ("u_c", "V"),
        "4-way proportional valve driven by a voltage (the amplifier's input): rated flow, "
        "pressure drop and voltage, lap, first- or second-order spool, stroke limit",
        second_order=True,
    ),
    _valve(
        "servo_valve_first_order",
        ("i", "A"),
        "servo_valve with a first-order (or static) spool: one state fewer",
        second_order=False,
    ),
    _valve(
        "proportional_valve_first_order",
        ("u_c", "V"),
        "proportional_valve with a first-order (or static) spool: one state fewer",
        second_order=False,
    ),
)
