"""The seeds' plants as they were written by hand, kept to hold the compositions to them.

The shipped seed rigs are compositions of components (the top-level ``rigs/``); the
modules here are the hand-written kernels they replaced, each one seed's equations
written out with hand-kept ``P_*``/``E_*`` indices, and ``rigs/`` the rig files that
drove them. :func:`reference_rig` loads one (``tests/test_reference_plants.py`` compares
the two, the kernel tests check the equations).
"""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

from fuzzyservo.components.effects import INPUT_EFFECTS
from fuzzyservo.io.rigs import load_rig
from fuzzyservo.plants import PlantModel
from fuzzyservo.rig import Rig
from reference_plants import ahc_cylinder, ahc_motor, cylinder, hydroprax, motor

RIGS = Path(__file__).parent / "rigs"


def _zero_null(params: object) -> float:
    """The plant input of hydraulic null: zero."""
    return 0.0


def from_module(type_name: str, module: ModuleType, description: str) -> PlantModel:
    """A plant from a kernel module's declarations (STATES, SIGNALS, ..., initial_state)."""
    binding = "\n".join(
        f"from {module.__name__} import {name} as plant_{name}"
        for name in ("in_end_stop", "rhs", "signals")
    )
    return PlantModel(
        type_name=type_name,
        binding=binding,
        params_cls=module.PARAMS,
        states=module.STATES,
        signals=module.SIGNALS,
        signal_units=module.SIGNAL_UNITS,
        input=module.INPUT,
        load=module.LOAD,
        initial_keys=module.INITIAL_KEYS,
        initial_state=module.initial_state,
        state_scale=module.state_scale,
        typical_state=module.typical_state,
        description=description,
        # a plant whose kernels read no plant-side effect takes only the input effects
        effects=getattr(module, "EFFECTS", INPUT_EFFECTS),
        mechanics=getattr(module, "MECHANICS", {"force": "N", "velocity": "m/s"}),
        null_input=getattr(module, "null_input", _zero_null),
        effect_scales=getattr(module, "effect_scales", None),
        pressures=getattr(module, "PRESSURES", ()),
    )


PLANTS: dict[str, PlantModel] = {
    model.type_name: model
    for model in (
        from_module(
            "open_centre_cylinder",
            cylinder,
            "open-centre servo-valve + asymmetric cylinder (seed 002)",
        ),
        from_module("servo_motor", motor, "servo-valve + axial-piston motor (seed 000)"),
        from_module(
            "hydroprax_pdcv",
            hydroprax,
            "proportional valve + single-rod cylinder, spring load, pump with relief (seed 003)",
        ),
        from_module(
            "ahc_cylinder",
            ahc_cylinder,
            "servo-valve + double-acting cylinder, AHC wave simulator (seed 001)",
        ),
        from_module(
            "ahc_motor",
            ahc_motor,
            "servo-valve + hydraulic motor with cable drum and load, AHC compensator (seed 001)",
        ),
    )
}


def reference_rig(name: str) -> Rig:
    """The seed rig ``name`` on its hand-written plant (``rigs/<name>.yaml``)."""
    return load_rig(RIGS / f"{name}.yaml", plants=PLANTS)
