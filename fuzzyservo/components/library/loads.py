"""Loads on the actuator: mass, spring, damper, gravity, constant force, friction.

Each adds to the moving mass or to the force opposing +y (or torque opposing +θ on a
motor). A load force measured on the rig is the scenario's ``load`` (any signal type,
``samples`` for a recorded series), which every composition takes.
"""

from __future__ import annotations

import math
from typing import Any

from fuzzyservo.components.declare import Component, Param, Signal, phase

_STANDARD_GRAVITY = 9.80665  # m/s², ISO 80000-3


@phase("mass")
def moving_mass(P: Any, mass: float) -> float:
    return mass + P.mass


@phase("f", "f_load")
def spring(P: Any, pos: float, f_load: float) -> tuple[float, float]:
    f = P.stiffness * (pos - P.free_position)
    return f, f_load + f


@phase("f", "f_load")
def damper(P: Any, vel: float, f_load: float) -> tuple[float, float]:
    f = P.coefficient * vel
    return f, f_load + f


@phase("f", "f_load")
def gravity(P: Any, mass: float, f_load: float) -> tuple[float, float]:
    f = mass * P.acceleration * math.sin(P.incline)
    return f, f_load + f


@phase("f_load")
def constant_force(P: Any, f_load: float) -> float:
    return f_load + P.force


@phase("f", "f_load")
def friction(P: Any, vel: float, f_load: float) -> tuple[float, float]:
    f = P.viscous_coefficient * vel + P.coulomb_force * math.tanh(vel / P.smoothing_velocity)
    return f, f_load + f


@phase("f", "f_load")
def brake(P: Any, vel: float, f_ext: float, f_load: float) -> tuple[float, float]:
    """f_load starts at the scenario's f_ext: the brake replaces that push by its drag."""
    f = f_ext * math.tanh(vel / P.smoothing_velocity)
    return f, f_load + (f - f_ext)


COMPONENTS = (
    Component(
        type="mass",
        role="load",
        doc="a mass moved with the actuator (kg; kg·m² of inertia on a motor)",
        source="Newton's second law; Hopsan MechanicTranslationalMass",
        params=(Param("mass", "mass", "moving mass or inertia", positive=True),),
        code={"mass": moving_mass},
    ),
    Component(
        type="spring",
        role="load",
        doc="F = k·(y − y_0): a spring pushing back against extension",
        source="seed 003 Table 1 (K_L); Hopsan MechanicTranslationalSpring",
        params=(
            Param("stiffness", "force/position", "k", nonnegative=True),
            Param("free_position", "position", "y_0 where the spring is relaxed", default=0.0),
        ),
        signals=(Signal("f_spring", "force", "f"),),
        code={"load": spring},
    ),
    Component(
        type="damper",
        role="load",
        doc="F = c·v: viscous friction of the guides and the load",
        source="seed 002 §4 (f), seed 003 Table 1 (F_vo)",
        params=(Param("coefficient", "force/velocity", "c", nonnegative=True),),
        signals=(Signal("f_damper", "force", "f"),),
        code={"load": damper},
    ),
    Component(
        type="gravity",
        role="load",
        doc="F = m·g·sin(α): the weight of every moving mass along an axis inclined α "
        "above the horizontal (π/2: vertical, extension lifts)",
        source="Newton; the moving mass is the actuator's plus every mass load",
        params=(
            Param(
                "incline",
                "rad",
                "α: axis above the horizontal",
                default=1.5707963267948966,
                minimum=-1.5707963267948966,
                maximum=1.5707963267948966,
            ),
            Param("acceleration", "m/s^2", "g", default=_STANDARD_GRAVITY, positive=True),
        ),
        signals=(Signal("f_gravity", "force", "f"),),
        code={"load": gravity},
        actuators=("single_rod_cylinder", "double_rod_cylinder"),
    ),
    Component(
        type="constant_force",
        role="load",
        doc="a constant force opposing extension (a preload, a weight on a cable)",
        source="Hopsan MechanicForceTransformer",
        params=(Param("force", "force", "F opposing +y", default=0.0),),
        code={"load": constant_force},
    ),
    Component(
        type="friction",
        role="load",
        doc="F = F_c·tanh(v/v_c) + c·v: Coulomb friction smoothed over v_c, plus viscous",
        source="docs/modelling.md Friction (smooth form); seed 003 eq. 6 (F_co, F_vo)",
        params=(
            Param("coulomb_force", "force", "F_c", nonnegative=True),
            Param("smoothing_velocity", "velocity", "v_c of tanh(v/v_c)", positive=True),
            Param("viscous_coefficient", "force/velocity", "c", default=0.0, nonnegative=True),
        ),
        signals=(Signal("f_load_friction", "force", "f"),),
        code={"load": friction},
    ),
    Component(
        type="brake",
        role="load",
        doc="the scenario's load as a brake: F = F_load(t)·tanh(v/v_c) opposes motion "
        "(a shoe or disc brake slows and holds, never drives)",
        source="seed 000 §2 (shoe brake as a variable load); docs/modelling.md Friction",
        params=(Param("smoothing_velocity", "velocity", "v_c of tanh(v/v_c)", positive=True),),
        signals=(Signal("f_brake", "force", "f"),),
        code={"load": brake},
    ),
)
