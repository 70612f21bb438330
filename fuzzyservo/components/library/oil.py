"""The circuit's fluid: mineral oil with a bulk modulus (every composition has one)."""

from __future__ import annotations

from fuzzyservo.components.declare import Component, Param

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
