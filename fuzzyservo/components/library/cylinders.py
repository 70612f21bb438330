"""Hydraulic cylinders: single-rod (differential) and double-rod (equal areas).

States: position ``y`` [m] (0 at ``zero_position`` from the retracted end), velocity ``v`` [m/s], chamber
pressures ``p_a`` (piston side, +y extends) and ``p_b`` [Pa]:

    V_a = V_0a + A_a·y_e,  V_b = V_0b + A_b·(L − y_e),  y_e = y + y_0   (floored at 5 % of V_0)
    dp_a/dt = E_a/V_a·(q_a − A_a·v·c_a − q_leak),  dp_b/dt = E_b/V_b·(q_b + A_b·v·c_b + q_leak)
    c = 1 + p/E in the oil's mass form (flows at reference density), else 1
    E_a = E_b = E, or E_mix(p) with the ``entrained_air`` effect (components/effects.py)
    m·dv/dt = p_a·A_a − p_b·A_b − F_fric(v) − F_loads + F_stop

``m`` is the piston's mass plus every ``mass`` load; F_loads every load's force and
the scenario's; F_stop a stiff spring-damper beyond 0 and the stroke L (the seeds are
silent; docs/modelling.md "chamber volumes must never reach zero"). Effects: friction
(``coulomb_friction``, ``stribeck_friction``; LuGre's bristle state ``z`` exists only
where one of them has a pre-sliding distance), ``internal_leakage`` q_leak = K_l·(p_a − p_b),
``external_leakage`` K_e·p out of each chamber.
"""

from __future__ import annotations

import math

from fuzzyservo.components.declare import Component, Param, Signal, State
from fuzzyservo.components.library.oil import CHAMBER_EFFECTS, actuator_motion

_COMMON = (
    Param("stroke", "m", "stroke L", positive=True),
    Param("zero_position", "m", "where the rig's y = 0 lies, from the retracted end",
          default=0.0),
    Param("piston_mass", "kg", "piston and rod mass", positive=True),
    Param("dead_volume_a", "m^3", "oil in chamber A at y = 0 (ports, end cap, hose)",
          positive=True),
    Param("dead_volume_b", "m^3", "oil in chamber B at y = L", positive=True),
    Param("end_stop_stiffness", "N/m", "end cap stiffness beyond the stroke", default=1e8,
          positive=True),
    Param("end_stop_damping", "N*s/m", "end cap damping beyond the stroke", default=1e4,
          nonnegative=True),
)  # fmt: skip

_STATES = (
    State("y", "m", "piston position from the retracted end", "motion", 1e-6, 1e-3),
    State("v", "m/s", "piston velocity", "motion", 1e-3, 0.1),
    State("p_a", "Pa", "pressure in chamber A (piston side)", "chamber", 1e3, 1e6),
    State("p_b", "Pa", "pressure in chamber B", "chamber", 1e3, 1e6),
    # LuGre friction's bristles: only with a friction effect's pre-sliding distance
    State("z", "m", "friction bristles' mean deflection", "bristles", 1e-8, 1e-5),
)
_SIGNALS = (
    Signal("y", "m", "pos"),
    Signal("v", "m/s", "vel"),
    Signal("p_a", "Pa", "p_a"),
    Signal("p_b", "Pa", "p_b"),
    Signal("f_stop", "N", "f_stop", "end-stop force"),
    Signal("f_hyd", "N", "p_a * area_a - p_b * area_b", "hydraulic force p_a·A_a − p_b·A_b"),
    Signal("f_friction", "N", "L.f_fric", "friction of the friction effects"),
    Signal("q_leak", "m^3/s", "L.q_leak", "internal leakage A→B"),
)

_ACTUATOR = """
    pos = X.y
    vel = X.v
    p_a = X.p_a
    p_b = X.p_b
    area_a = {area_a}
    area_b = {area_b}
    L.ye = pos + P.zero_position
    L.va = max(P.dead_volume_a + area_a * L.ye, 0.05 * P.dead_volume_a)
    L.vb = max(P.dead_volume_b + area_b * (P.stroke - L.ye), 0.05 * P.dead_volume_b)
    f_stop = 0.0
    if L.ye < 0.0:
        f_stop = -P.end_stop_stiffness * L.ye - (P.end_stop_damping * vel if vel < 0.0 else 0.0)
    elif L.ye > P.stroke:
        f_stop = -P.end_stop_stiffness * (L.ye - P.stroke) - (
            P.end_stop_damping * vel if vel > 0.0 else 0.0
        )
    L.q_leak = E.internal_leakage_m3_s_pa * (p_a - p_b)
"""
# the motion phase, with and without LuGre friction's bristle state
_ACCELERATION = "(p_a * area_a - p_b * area_b - L.f_fric - f_load + f_stop) / mass"
_VOLUMES = ("L.va", "L.vb")


def _areas(v: dict[str, float], double: bool) -> tuple[float, float]:
    a_piston = 0.25 * math.pi * v["piston_diameter"] ** 2
    a_rod = 0.25 * math.pi * v["rod_diameter"] ** 2
    return (a_piston - a_rod if double else a_piston), a_piston - a_rod


def _initial(double: bool):
    def initial(v: dict[str, float], ctx: dict[str, float]) -> dict[str, float]:
        """At rest at ``position``; p_b half-way between tank and supply and p_a holding
        the loads' static force, unless the pressures are given."""
        aa, ab = _areas(v, double)
        y = ctx.get("position", 0.0)
        p_s, p_t = ctx.get("p_s", 0.0), ctx.get("p_t", 0.0)
        pb = ctx.get("pressure_b", p_t + 0.5 * (p_s - p_t))
        pa = ctx.get("pressure_a", (pb * ab + ctx.get("static_force", 0.0)) / aa)
        return {"y": y, "v": ctx.get("velocity", 0.0), "p_a": pa, "p_b": pb}

    return initial


def _check(v: dict[str, float]) -> str | None:
    if not v["rod_diameter"] < v["piston_diameter"]:
        return (
            f"rod_diameter: must be smaller than piston_diameter (rod {v['rod_diameter']} m >= "
            f"piston {v['piston_diameter']} m); check that the two are not swapped"
        )
    return None


def _cylinder(type_name: str, double: bool, doc: str) -> Component:
    area_a = (
        "0.25 * math.pi * (P.piston_diameter ** 2 - P.rod_diameter ** 2)"
        if double
        else "0.25 * math.pi * P.piston_diameter ** 2"
    )
    area_b = "0.25 * math.pi * (P.piston_diameter ** 2 - P.rod_diameter ** 2)"
    rod_doc = "diameter of each of the two rods" if double else "rod diameter"
    return Component(
        type=type_name,
        role="actuator",
        doc=doc,
        source="seed 003 eq. 3-6; seed 002 eq. 7-12; Hopsan HydraulicCylinderC",
        params=(
            Param("piston_diameter", "m", "bore", positive=True),
            Param("rod_diameter", "m", rod_doc, positive=True),
            *_COMMON,
        ),
        states=_STATES,
        signals=_SIGNALS,
        code={
            "actuator": _ACTUATOR.format(area_a=area_a, area_b=area_b),
            "mass": "mass += P.piston_mass",
            "motion": actuator_motion("y", "v", _ACCELERATION, _VOLUMES, bristles=False),
        },
        bristle_code={"motion": actuator_motion("y", "v", _ACCELERATION, _VOLUMES, bristles=True)},
        effects=CHAMBER_EFFECTS,
        initial=_initial(double),
        initial_keys={
            "position": ("position", "m"),
            "velocity": ("velocity", "m/s"),
            "pressure_a": ("pressure_a", "Pa"),
            "pressure_b": ("pressure_b", "Pa"),
        },
        scales=lambda v: {"area": _areas(v, double)[0]},
        load=("f_load", "N"),
        mechanics={"force": "N", "velocity": "m/s", "position": "m", "mass": "kg"},
        end_stop="X.y + P.zero_position < 0.0 or X.y + P.zero_position > P.stroke",
        check=_check,
    )


COMPONENTS = (
    _cylinder(
        "single_rod_cylinder",
        False,
        "differential cylinder: piston area A_a, annulus A_b, dead volumes, end stops",
    ),
    _cylinder(
        "double_rod_cylinder",
        True,
        "double-rod (synchronous) cylinder: equal annuli A_a = A_b, dead volumes, end stops",
    ),
)
