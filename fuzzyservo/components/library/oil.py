"""The circuit's fluid: mineral oil with a bulk modulus (every composition has one)."""

from __future__ import annotations

from fuzzyservo.components.declare import Component, Param

COMPONENTS = (
    Component(
        type="oil",
        role="fluid",
        doc="hydraulic oil: bulk modulus E [Pa] of every volume; the orifice law's laminar "
        "pressure p_lam [Pa] below which flow turns linear in Δp",
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
        ),
        code={"fluid": "beta = bulk_modulus(p, P.bulk_modulus)\np_lam = P.laminar_pressure"},
        effects=("bulk_modulus",),
        scales=lambda v: {"bulk_modulus": v["bulk_modulus"]},
    ),
)
