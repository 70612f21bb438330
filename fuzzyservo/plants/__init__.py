"""Plant families: pure right-hand sides of named states with frozen, unit-named parameters.

:data:`PLANTS` maps the ``plant.type`` a rig file names to its :class:`PlantModel`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from types import ModuleType
from typing import Any

import numpy as np

from fuzzyservo.components.effects import INPUT_EFFECTS, Scales
from fuzzyservo.plants import ahc_cylinder, ahc_motor, cylinder, hydroprax, motor


@dataclass(frozen=True)
class PlantModel:
    """Everything the simulator and the file reader need to know about a plant family."""

    type_name: str
    binding: str  # source that binds plant_rhs/plant_signals/plant_in_end_stop (_jit.bind_plant)
    params_cls: type
    states: tuple[str, ...]
    signals: tuple[str, ...]
    signal_units: dict[str, str]
    input: tuple[str, str]
    load: tuple[str, str]
    initial_keys: dict[str, tuple[str, str]]
    initial_state: Callable[..., np.ndarray]
    state_scale: Callable[[Any], np.ndarray]
    typical_state: Callable[[Any], np.ndarray]
    description: str
    effects: tuple[str, ...]  # names of components/effects.py this plant models
    mechanics: dict[str, str]  # SI units of "force" and "velocity" for effect parameters
    null_input: Callable[[Any], float]
    effect_scales: Callable[[Any, float, float], Any] | None
    components: tuple[tuple[str, str], ...] = ()  # (instance, type) of a composition
    # gauge chamber pressures [Pa] among the signals: checked against the vapour
    # pressure after every run (simulation/validity.py)
    pressures: tuple[str, ...] = ()

    @classmethod
    def from_module(cls, type_name: str, module: ModuleType, description: str) -> PlantModel:
        """Collect a plant module's declarations (STATES, SIGNALS, ..., initial_state)."""
        return cls(
            type_name=type_name,
            binding=_binding(module.__name__),
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

    def __reduce_ex__(self, protocol: int) -> Any:
        """A composition pickles as its parts (its functions are closures made at load
        time; :func:`~fuzzyservo.plants.composed.compose` rebuilds the same plant), a
        hand-written plant as its fields."""
        if self.components:
            from fuzzyservo.plants.composed import compose

            return compose, (self.components,)
        return super().__reduce_ex__(protocol)

    @property
    def loop(self) -> ModuleType:
        """The closed loop compiled for this plant (``simulation/_plant_loop.py``)."""
        from fuzzyservo._jit import bind_plant

        return bind_plant(self.binding)

    def scales(self, params: Any, rated_input: float, sample_time_s: float) -> Scales:
        """Sizes effect bounds scale with (components/effects.py); a plant without
        ``effect_scales`` knows only its input and period (NaN elsewhere)."""
        if self.effect_scales is None:
            nan = float("nan")
            return Scales(nan, nan, nan, nan, rated_input, nan, sample_time_s)
        return self.effect_scales(params, rated_input, sample_time_s)

    def effect_unit(self, token: str) -> str:
        """SI unit of an effect parameter here: "force", "velocity", "input" resolved."""
        if token == "input":
            return self.input[1]
        return self.mechanics.get(token, token)

    def refusal(self, effect: str) -> str | None:
        """Why this plant cannot take ``effect``, or None when it models it."""
        if effect in self.effects:
            return None
        if self.components:
            from fuzzyservo.components._declare import registry

            types = registry()
            for name, type_name in self.components:
                why = types[type_name].refuses.get(effect)
                if why:
                    return f"effect {effect!r} is not meaningful here: {name} ({type_name}) {why}"
            readers = sorted(t for t, c in types.items() if effect in c.effects)
            return (
                f"effect {effect!r} is not modelled by this composition: none of its components "
                f"reads it; components that do: {readers}"
            )
        return (
            f"effect {effect!r} is not modelled for plant type {self.type_name!r}; "
            f"it models {list(self.effects)}"
        )


def _binding(module: str) -> str:
    return "\n".join(
        f"from {module} import {name} as plant_{alias}"
        for name, alias in (("in_end_stop", "in_end_stop"), ("rhs", "rhs"), ("signals", "signals"))
    )


def _zero_null(params: Any) -> float:
    """The plant input of hydraulic null: zero."""
    return 0.0


PLANTS: dict[str, PlantModel] = {
    model.type_name: model
    for model in (
        PlantModel.from_module(
            "open_centre_cylinder",
            cylinder,
            "open-centre servo-valve + asymmetric cylinder (seed 002)",
        ),
        PlantModel.from_module(
            "servo_motor",
            motor,
            "servo-valve + axial-piston motor, velocity loop (seed 000)",
        ),
        PlantModel.from_module(
            "hydroprax_pdcv",
            hydroprax,
            "proportional valve + single-rod cylinder, spring load, pump with relief (seed 003)",
        ),
        PlantModel.from_module(
            "ahc_cylinder",
            ahc_cylinder,
            "servo-valve + double-acting cylinder, AHC wave simulator (seed 001)",
        ),
        PlantModel.from_module(
            "ahc_motor",
            ahc_motor,
            "servo-valve + hydraulic motor with cable drum and load, AHC compensator (seed 001)",
        ),
    )
}

__all__ = ["PLANTS", "PlantModel"]
