"""Plants: pure right-hand sides of named states with frozen, unit-named parameters.

Every plant is a composition of declared components (``plant.components`` in a rig
file, :func:`fuzzyservo.plants.composed.compose`); :class:`PlantModel` is what the
simulator and the file reader need to know about one.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from types import ModuleType
from typing import Any

import numpy as np

from fuzzyservo.components.effects import Scales, has_bristles


@dataclass(frozen=True)
class PlantModel:
    """Everything the simulator and the file reader need to know about a plant.

    Built by :func:`~fuzzyservo.plants.composed.compose`; ``binding`` may also import
    kernels written by hand (``tests/reference_plants`` holds the seeds' equations so).
    """

    type_name: str
    # source of the plant's kernels: it defines plant_rhs, plant_signals and
    # plant_in_end_stop, a composition's plant_jacobian too (plants/_jacobian.py), a stepped
    # plant's plant_advance (:attr:`kernels`; simulation/binding.py binds them to the loop)
    binding: str
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
    # (instance, type) or (instance, type, axis) of a composition
    components: tuple[tuple[str, ...], ...] = ()
    # a composition with LuGre friction's bristle states: whether this form carries them
    # (compose's ``bristles``); None where no component declares them
    bristles: bool | None = None
    # gauge chamber pressures [Pa] among the signals: checked against the vapour
    # pressure after every run (simulation/validity.py)
    pressures: tuple[str, ...] = ()
    # how a composition is made again from its parts and bristle form (compose itself:
    # a module-level function, so a plant pickles as its parts); None for any other plant
    rebuild: Callable[[tuple[tuple[str, str], ...], bool], PlantModel] | None = None
    # numbers the compiled kernels read after the packed parameters, for a parameter set
    # (an FMU plant's instance and C function addresses, plants/_fmi_calls.py); None: none.
    # Such a plant holds state outside the loop, so its runs are never batched in parallel
    attach: Callable[[Any], np.ndarray] | None = None
    # how any other plant is made again in another process: (function, arguments)
    recipe: tuple[Callable[..., PlantModel], tuple[Any, ...]] | None = None
    # each state as its component names it, ``<instance>.<state>``, and its SI unit (a
    # composition's: what an exported plant FMU calls its states); empty where unknown
    state_paths: tuple[str, ...] = ()
    state_units: tuple[str, ...] = ()
    # stepped by its own solver once per control interval (a co-simulation FMU's binding
    # defines plant_advance), not integrated by the loop
    stepped: bool = False

    def __reduce_ex__(self, protocol: int) -> Any:
        """A composition pickles as its parts (its functions are closures made at load
        time; :func:`~fuzzyservo.plants.composed.compose` rebuilds the same plant), a plant
        with a ``recipe`` as that, any other plant as its fields."""
        if self.recipe is not None:
            return self.recipe
        if self.rebuild is not None:
            return self.rebuild, (self.components, bool(self.bristles))
        return super().__reduce_ex__(protocol)

    def packed(self, params: Any) -> np.ndarray:
        """The vector ``p`` the compiled loop reads: ``params`` packed
        (:func:`fuzzyservo.params.pack`), then what the plant attaches for them."""
        from fuzzyservo.params import pack

        p = pack(params)
        return p if self.attach is None else np.concatenate([p, self.attach(params)])

    def for_params(self, params: Any) -> PlantModel:
        """The form of this plant that simulates ``params``: a composition carries LuGre
        friction's bristle states only where a friction effect has a pre-sliding distance
        (:func:`~fuzzyservo.components.effects.has_bristles`); both forms give the same
        run for any other parameters, the one without them faster."""
        if self.rebuild is None or self.bristles is None or self.bristles == has_bristles(params):
            return self
        return self.rebuild(self.components, not self.bristles)

    @property
    def kernels(self) -> ModuleType:
        """The module of the plant's kernels (:attr:`binding`), each compiled when first
        called: ``plant_rhs(x, u, f_ext, p, dx)``, ``plant_signals(x, u, f_ext, p, out)``,
        ``plant_in_end_stop(x, p)``, and where the plant has them ``plant_jacobian`` and
        ``plant_advance``. The closed loop calls them compiled as C functions
        (:func:`fuzzyservo.simulation.binding.bind`)."""
        from fuzzyservo._jit import load_generated

        return load_generated(self.binding)

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
            from fuzzyservo.components.declare import registry

            types = registry()
            for name, type_name, *_ in self.components:
                why = types[type_name].refuses.get(effect)
                if why:
                    return f"effect {effect!r} is not meaningful here: {name} ({type_name}) {why}"
            readers = sorted(t for t, c in types.items() if effect in c.effects)
            return (
                f"effect {effect!r} is not modelled by this composition: none of its components "
                f"reads it; components that do: {readers}"
            )
        if self.stepped and effect == "valve_lag":
            return (
                f"effect {effect!r} is not applicable: the spool's lag is a state the loop "
                f"integrates, and {self.description} is stepped by its own solver; take the "
                "FMU's model-exchange interface"
            )
        if self.attach is not None:  # a black box (an FMU): only the loop's stages reach it
            return (
                f"effect {effect!r} is not applicable: it acts inside the plant, a black box "
                f"({self.description}); the effects on its command are {list(self.effects)}"
            )
        return (
            f"effect {effect!r} is not modelled for plant type {self.type_name!r}; "
            f"it models {list(self.effects)}"
        )


__all__ = ["PlantModel"]
