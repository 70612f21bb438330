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
from typing import Any

from fuzzyservo._jit import njit
from fuzzyservo.components.declare import Component, Param, Signal, State, phase
from fuzzyservo.components.effects import E
from fuzzyservo.components.library.oil import (
    CHAMBER_EFFECTS,
    lugre_friction,
    static_friction,
    two_chambers,
)

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
    Signal("f_hyd", "N", "f_hyd", "hydraulic force p_a·A_a − p_b·A_b"),
    Signal("f_friction", "N", "f_fric", "friction of the friction effects"),
    Signal("q_leak", "m^3/s", "q_leak", "internal leakage A→B"),
)


@phase("area_a", "area_b")
def single_rod_areas(P: Any) -> tuple[float, float]:
    """Piston area A_a on side A, the annulus A_b on side B."""
    area_a = 0.25 * math.pi * P.piston_diameter**2
    area_b = 0.25 * math.pi * (P.piston_diameter**2 - P.rod_diameter**2)
    return area_a, area_b


@phase("area_a", "area_b")
def double_rod_areas(P: Any) -> tuple[float, float]:
    """The annulus on both sides."""
    area_a = 0.25 * math.pi * (P.piston_diameter**2 - P.rod_diameter**2)
    area_b = 0.25 * math.pi * (P.piston_diameter**2 - P.rod_diameter**2)
    return area_a, area_b


@phase("pos", "vel", "p_a", "p_b", "f_stop", "va", "vb", "q_leak", "f_hyd")
def chambers(
    P: Any, X: Any, p: Any, area_a: float, area_b: float
) -> tuple[float, float, float, float, float, float, float, float, float]:
    """The motion and the chamber pressures; the chamber volumes (floored at 5 % of the
    dead volumes), the end-stop force beyond 0 and the stroke, the A→B leakage."""
    pos = X.y
    vel = X.v
    p_a = X.p_a
    p_b = X.p_b
    ye = pos + P.zero_position
    va = max(P.dead_volume_a + area_a * ye, 0.05 * P.dead_volume_a)
    vb = max(P.dead_volume_b + area_b * (P.stroke - ye), 0.05 * P.dead_volume_b)
    f_stop = 0.0
    if ye < 0.0:
        f_stop = -P.end_stop_stiffness * ye - (P.end_stop_damping * vel if vel < 0.0 else 0.0)
    elif ye > P.stroke:
        f_stop = -P.end_stop_stiffness * (ye - P.stroke) - (
            P.end_stop_damping * vel if vel > 0.0 else 0.0
        )
    q_leak = p[E.internal_leakage_m3_s_pa] * (p_a - p_b)
    f_hyd = p_a * area_a - p_b * area_b
    return pos, vel, p_a, p_b, f_stop, va, vb, q_leak, f_hyd


@phase("mass")
def piston_mass(P: Any, mass: float) -> float:
    return mass + P.piston_mass


@phase("dx_y", "dx_v", "dx_p_a", "dx_p_b")
def motion(
    p: Any,
    vel: float,
    p_a: float,
    p_b: float,
    area_a: float,
    area_b: float,
    f_fric: float,
    f_load: float,
    f_stop: float,
    mass: float,
    q_a: float,
    q_b: float,
    q_leak: float,
    va: float,
    vb: float,
    mass_form: float,
    beta: float,
) -> tuple[float, float, float, float]:
    """Newton's law on the piston, and the chambers."""
    acceleration = (p_a * area_a - p_b * area_b - f_fric - f_load + f_stop) / mass
    dp_a, dp_b = two_chambers(
        q_a, q_b, area_a, area_b, vel, p_a, p_b, q_leak, va, vb, mass_form, beta, p
    )
    return vel, acceleration, dp_a, dp_b


@njit(cache=True)
def beyond_stroke(P: Any, X: Any) -> bool:
    """True beyond a mechanical stop."""
    return X.y + P.zero_position < 0.0 or X.y + P.zero_position > P.stroke


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
            "actuator": (double_rod_areas if double else single_rod_areas, chambers),
            "mass": piston_mass,
            "motion": (static_friction, motion),
        },
        bristle_code={"motion": (lugre_friction, motion)},
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
        end_stop=beyond_stroke,
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
