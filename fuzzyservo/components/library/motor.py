"""A hydraulic motor: displacement D, chamber volumes, shaft inertia (seed 000 eq. 14-17).

States: angle ``theta`` [rad], speed ``w`` [rad/s], port pressures ``p_a``, ``p_b`` [Pa]:

    dp_a/dt = E_a/V_a·(q_a − D·w − q_leak),  dp_b/dt = E_b/V_b·(q_b + D·w + q_leak)
    J·dw/dt = η_hm·(p_a − p_b)·D − T_fric(w) − T_loads

J is the shaft's inertia plus every ``mass`` load (kg·m² on a motor). η_hm is the
hydro-mechanical efficiency (seed 001 eq. 14-15; 1 by default), a constant factor on
the ideal torque in both directions of power flow. At rest the port pressures hold
the loads' static torque symmetric about the middle of supply and tank, where a
symmetric valve holds an equal-area motor. Effects: friction, ``internal_leakage``
(cross-port, q_leak = K_l·(p_a − p_b)) and ``external_leakage`` (case drain, K_e·p
from each port) and ``entrained_air`` (E_a, E_b = E_mix(p) instead of E).
"""

from __future__ import annotations

from typing import Any

from fuzzyservo.components.declare import Component, Param, Signal, State, phase
from fuzzyservo.components.effects import E
from fuzzyservo.components.library.oil import (
    CHAMBER_EFFECTS,
    lugre_friction,
    static_friction,
    two_chambers,
)


def _initial(v: dict[str, float], ctx: dict[str, float]) -> dict[str, float]:
    p_s, p_t = ctx.get("p_s", 0.0), ctx.get("p_t", 0.0)
    dp = ctx.get("static_force", 0.0) / (v["hydromechanical_efficiency"] * v["displacement"])
    if "pressure_b" in ctx:
        pb = ctx["pressure_b"]
        pa = ctx.get("pressure_a", pb + dp)
    elif "pressure_a" in ctx:
        pa = ctx["pressure_a"]
        pb = pa - dp
    else:
        pa = p_t + 0.5 * (p_s - p_t) + 0.5 * dp
        pb = pa - dp
    return {"theta": ctx.get("angle", 0.0), "w": ctx.get("speed", 0.0), "p_a": pa, "p_b": pb}


@phase("pos", "vel", "p_a", "p_b", "area_a", "area_b", "f_stop", "q_leak")
def shaft(P: Any, X: Any, p: Any) -> tuple[float, ...]:
    """The shaft's angle and speed, the ports' pressures, the cross-port leakage."""
    q_leak = p[E.internal_leakage_m3_s_pa] * (X.p_a - X.p_b)
    return X.theta, X.w, X.p_a, X.p_b, P.displacement, P.displacement, 0.0, q_leak


@phase("mass")
def shaft_inertia(P: Any, mass: float) -> float:
    return mass + P.inertia


@phase("dx_theta", "dx_w", "dx_p_a", "dx_p_b")
def motion(
    P: Any,
    p: Any,
    vel: float,
    p_a: float,
    p_b: float,
    area_a: float,
    area_b: float,
    f_fric: float,
    f_load: float,
    mass: float,
    q_a: float,
    q_b: float,
    q_leak: float,
    mass_form: float,
    beta: float,
) -> tuple[float, float, float, float]:
    """Torque balance on the shaft, and the ports."""
    acceleration = (P.hydromechanical_efficiency * (p_a - p_b) * area_a - f_fric - f_load) / mass
    dp_a, dp_b = two_chambers(
        q_a,
        q_b,
        area_a,
        area_b,
        vel,
        p_a,
        p_b,
        q_leak,
        P.volume_a,
        P.volume_b,
        mass_form,
        beta,
        p,
    )
    return vel, acceleration, dp_a, dp_b


COMPONENTS = (
    Component(
        type="motor",
        role="actuator",
        doc="hydraulic motor: displacement D per radian, chamber volumes, shaft inertia",
        source="seed 000 eq. 14-17 (Selim et al.); seed 001 eq. 1-9, 14-15; Hopsan HydraulicMotorC",
        params=(
            Param("displacement", "m^3/rad", "D: volume per radian", positive=True),
            Param("volume_a", "m^3", "oil volume of port A and its line", positive=True),
            Param("volume_b", "m^3", "oil volume of port B and its line", positive=True),
            Param("inertia", "kg*m^2", "shaft inertia", positive=True),
            Param(
                "hydromechanical_efficiency",
                "1",
                "η_hm: shaft torque over the ideal (p_a − p_b)·D",
                default=1.0,
                positive=True,
                maximum=1.0,
            ),
        ),
        states=(
            State("theta", "rad", "shaft angle", "motion", 1e-3, 1.0),
            State("w", "rad/s", "shaft speed", "motion", 1e-2, 10.0),
            State("p_a", "Pa", "pressure at port A", "chamber", 1e3, 1e6),
            State("p_b", "Pa", "pressure at port B", "chamber", 1e3, 1e6),
            # LuGre friction's bristles: only with a friction effect's pre-sliding distance
            State("z", "rad", "friction bristles' mean deflection", "bristles", 1e-7, 1e-3),
        ),
        signals=(
            Signal("theta", "rad", "pos"),
            Signal("w", "rad/s", "vel"),
            Signal("p_a", "Pa", "p_a"),
            Signal("p_b", "Pa", "p_b"),
            Signal("t_friction", "N*m", "f_fric", "friction of the friction effects"),
            Signal("q_leak", "m^3/s", "q_leak", "cross-port leakage A→B"),
        ),
        code={"actuator": shaft, "mass": shaft_inertia, "motion": (static_friction, motion)},
        bristle_code={"motion": (lugre_friction, motion)},
        effects=CHAMBER_EFFECTS,
        initial=_initial,
        initial_keys={
            "angle": ("angle", "rad"),
            "speed": ("speed", "rad/s"),
            "pressure_a": ("pressure_a", "Pa"),
            "pressure_b": ("pressure_b", "Pa"),
        },
        scales=lambda v: {"area": v["displacement"]},
        load=("t_load", "N*m"),
        mechanics={"force": "N*m", "velocity": "rad/s", "position": "rad", "mass": "kg*m^2"},
    ),
)
