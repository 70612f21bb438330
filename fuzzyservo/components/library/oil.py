"""The circuit's fluid: mineral oil with a bulk modulus (every composition has one)."""

from __future__ import annotations

from typing import Any

from fuzzyservo._jit import njit
from fuzzyservo.components.declare import Component, Param, phase
from fuzzyservo.components.effects import (
    E,
    actuator_friction,
    bristle_rate,
    bulk_modulus,
    chamber_modulus,
    friction_force,
)

#: the effects an actuator with :func:`two_chambers` reads: friction on its motion, the
#: leakages and the air in the law below (cylinders and motors declare these alike)
CHAMBER_EFFECTS = (
    "coulomb_friction",
    "stribeck_friction",
    "internal_leakage",
    "external_leakage",
    "entrained_air",
)


@njit(cache=True, inline="always")
def two_chambers(
    q_a: float,
    q_b: float,
    area_a: float,
    area_b: float,
    vel: float,
    p_a: float,
    p_b: float,
    q_leak: float,
    volume_a: float,
    volume_b: float,
    mass_form: float,
    beta: float,
    p: Any,
) -> tuple[float, float]:
    """dp_a/dt, dp_b/dt of an actuator's two chambers under this oil's liquid law.

    ``q_a``, ``q_b`` the port flows, ``area_a``, ``area_b`` the displacement per unit of
    motion, ``q_leak`` the A→B leakage: the net inflows lose the external leakage; the
    mass form's compression term (zero in the pressure form); each chamber's modulus is
    ``chamber_modulus`` (the oil's E unless ``entrained_air`` is on). Cylinders and
    motors share it, so the law is written once."""
    na = q_a - area_a * vel - q_leak - p[E.external_leakage_m3_s_pa] * p_a
    nb = q_b + area_b * vel + q_leak - p[E.external_leakage_m3_s_pa] * p_b
    ma = mass_form * area_a * vel * p_a
    mb = mass_form * area_b * vel * p_b
    ea = chamber_modulus(p_a, na - ma / beta, beta, p)
    eb = chamber_modulus(p_b, nb + mb / beta, beta, p)
    return (ea * na - ma * (ea / beta)) / volume_a, (eb * nb + mb * (eb / beta)) / volume_b


@phase("f_fric")
def static_friction(p: Any, vel: float) -> float:
    """An actuator's friction under the friction effects' static law."""
    return friction_force(vel, p)


@phase("f_fric", "dx_z")
def lugre_friction(X: Any, p: Any, vel: float, mass: float) -> tuple[float, float]:
    """An actuator's friction under LuGre's law, which reads and moves the actuator's
    bristle state ``z`` (a composition that carries the ``bristles`` states)."""
    return actuator_friction(vel, X.z, mass, p), bristle_rate(vel, X.z, p)


@phase("beta", "p_lam", "mass_form")
def fluid(P: Any, p: Any) -> tuple[float, float, float]:
    """The oil's effective bulk modulus, orifice regularisation and liquid law."""
    return bulk_modulus(p, P.bulk_modulus), P.laminar_pressure, P.mass_form


COMPONENTS = (
    Component(
        type="oil",
        role="fluid",
        doc="hydraulic oil: bulk modulus E [Pa] of every volume; the orifice law's laminar "
        "pressure p_lam [Pa] below which flow turns linear in Δp; the chambers' "
        "liquid law (pressure or mass form)",
        source="docs/modelling.md typical ranges (oil 1.4-1.8 GPa); orifice law near Δp = 0",
        params=(
            Param("bulk_modulus", "Pa", "the oil's bulk modulus E", positive=True),
            Param(
                "laminar_pressure",
                "Pa",
                "orifice regularisation (0.01-1 bar)",
                default=1e4,
                positive=True,
            ),
            Param(
                "mass_form",
                "1",
                "1: flows are volumes at reference density and a chamber's displacement flow "
                "carries the compression (1 + p/E) (the mass form, seed 002 eq. 8-9); 0: the "
                "pressure form dp/dt = E/V·(q − A·v)",
                default=0.0,
                minimum=0.0,
                maximum=1.0,
            ),
        ),
        code={"fluid": fluid},
        effects=("bulk_modulus",),
        scales=lambda v: {"bulk_modulus": v["bulk_modulus"]},
    ),
)
