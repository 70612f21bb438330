"""The circuit's fluid: mineral oil with a bulk modulus (every composition has one)."""

from __future__ import annotations

from fuzzyservo.components.declare import Component, Param

#: the effects an actuator with :func:`two_chambers` reads: friction on its motion, the
#: leakages and the air in the law below (cylinders and motors declare these alike)
CHAMBER_EFFECTS = (
    "coulomb_friction",
    "stribeck_friction",
    "internal_leakage",
    "external_leakage",
    "entrained_air",
)


def two_chambers(volume_a: str, volume_b: str) -> str:
    """Source lines of an actuator's two chamber pressures under this oil's liquid law.

    Needs ``q_a``, ``q_b`` (port flows), ``area_a``, ``area_b`` (displacement per unit of
    motion), ``vel``, ``p_a``, ``p_b`` and ``L.q_leak`` (A→B leakage): the net inflows
    ``L.na``, ``L.nb`` lose the external leakage; the mass form's compression term
    ``L.ma``, ``L.mb`` (zero in the pressure form); each chamber's modulus is
    ``chamber_modulus`` (the oil's E unless ``entrained_air`` is on). Cylinders and motors
    share it, so the law is written once."""
    return f"""
L.na = q_a - area_a * vel - L.q_leak - E.external_leakage_m3_s_pa * p_a
L.nb = q_b + area_b * vel + L.q_leak - E.external_leakage_m3_s_pa * p_b
L.ma = mass_form * area_a * vel * p_a
L.mb = mass_form * area_b * vel * p_b
L.ea = chamber_modulus(p_a, L.na - L.ma / beta, beta, p)
L.eb = chamber_modulus(p_b, L.nb + L.mb / beta, beta, p)
DX.p_a = (L.ea * L.na - L.ma * (L.ea / beta)) / {volume_a}
DX.p_b = (L.eb * L.nb + L.mb * (L.eb / beta)) / {volume_b}
"""


def actuator_motion(
    position: str, velocity: str, acceleration: str, volumes: tuple[str, str], bristles: bool
) -> str:
    """Source lines of an actuator's motion phase: its friction ``L.f_fric`` (the
    static law, or with ``bristles`` LuGre's, which reads and moves the bristle state
    ``z``), ``DX.<position> = vel``, ``DX.<velocity> = <acceleration>`` (an expression that
    subtracts ``L.f_fric``) and the two chambers (:func:`two_chambers` on ``volumes``).
    Cylinders and motors share it."""
    friction = "actuator_friction(vel, X.z, mass, p)" if bristles else "friction_force(vel, p)"
    rate = "DX.z = bristle_rate(vel, X.z, p)\n" if bristles else ""
    return (
        f"L.f_fric = {friction}\nDX.{position} = vel\n{rate}DX.{velocity} = {acceleration}\n"
        + two_chambers(*volumes)
    )


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
        code={
            "fluid": "beta = bulk_modulus(p, P.bulk_modulus)\np_lam = P.laminar_pressure\n"
            "mass_form = P.mass_form"
        },
        effects=("bulk_modulus",),
        scales=lambda v: {"bulk_modulus": v["bulk_modulus"]},
    ),
)
