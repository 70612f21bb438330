"""A rig's composed plant as an FMU: what the FMU declares, from the rig.

:func:`plant_fmu_model` gathers the FMU's variables from a rig — the plant's states
(named ``<instance>.<state>``, starting where the rig's default scenario starts), its
input and load, its signals as outputs, the parameters the plant reads (the rig's
values as start values) — and the C that :mod:`fuzzyservo.plants.c_source` translates from the
components' equations. :mod:`._plant_wrapper` writes the model description and the FMI
wrapper (model exchange and co-simulation) around it.

The loop's own stages (delay, valve bias, dead band and lag, the sensor, the converter)
are not part of the plant: the FMU holds the hydraulics only, and a rig that runs it as
its plant declares those stages again, as it would for any FMU.
"""

from __future__ import annotations

import dataclasses
import re
from typing import Any

import numpy as np

from fuzzyservo.codegen._fmu import FmuBuild
from fuzzyservo.codegen._plant_wrapper import PlantFmuModel, PlantVariable, plant_fmu_build
from fuzzyservo.components.effects import INPUT_EFFECTS, LIBRARY
from fuzzyservo.plants import PlantModel
from fuzzyservo.plants.c_source import plant_c_sources
from fuzzyservo.rig import Rig
from fuzzyservo.simulation import DEFAULT_TOL


def plant_fmu_model(rig: Rig, *, tolerance: float | None = None) -> PlantFmuModel:
    """The FMU of ``rig``'s plant at the parameters and initial state of its default
    scenario; ``tolerance`` the co-simulation solver's default relative tolerance (None:
    the loop's own accuracy, :data:`~fuzzyservo.simulation.closed_loop.DEFAULT_TOL` of the
    smallest ratio of a state's error scale to its size).
    Raises :class:`~fuzzyservo.codegen.TranslationError` for a plant whose equations
    fall outside what is translated to C (the message names the function and line)."""
    scenario = rig.scenario()
    params = rig.params_for(scenario)
    plant = rig.plant.for_params(params)
    files = plant_c_sources(plant)
    x0 = np.asarray(plant.initial_state(params, **{**rig.initial, **scenario.initial}))
    scale = np.asarray(plant.state_scale(params), dtype=float)
    typical = np.asarray(plant.typical_state(params), dtype=float)
    states = tuple(
        PlantVariable(path, unit, f"state {name} of the plant", float(x))
        for path, unit, name, x in zip(
            plant.state_paths, plant.state_units, plant.states, x0, strict=True
        )
    )
    outputs = tuple(
        PlantVariable(name, plant.signal_units[name], f"signal {name}") for name in plant.signals
    )
    input_name, input_unit = plant.input
    load_name, load_unit = plant.load
    return PlantFmuModel(
        identifier=_identifier(rig.name),
        description=f"{rig.title or rig.name}: {plant.description} (plant only, exported by "
        "fuzzyservo)",
        states=states,
        nominals=tuple(float(v) for v in typical),
        typical=tuple(float(v) for v in typical),
        input=PlantVariable(input_name, input_unit, "the plant's command input"),
        load=PlantVariable(load_name, load_unit, "external load opposing +position"),
        outputs=outputs,
        parameters=_parameters(plant, params),
        c_files=files,
        # the loop's own accuracy: its local error DEFAULT_TOL·scale, as a share of nominal
        tolerance=tolerance or float(DEFAULT_TOL * np.min(scale / typical)),
        # so that the FMU run back as a rig's plant takes the steps its composition takes
        error_scales=tuple(float(v) for v in scale),
    )


def fmu_signals(plant: PlantModel) -> dict[str, str]:
    """How a rig that runs the exported FMU maps the loop's signals: each state by its
    own name to the FMU's state (``y: cylinder.y``: the feedback sensor reads a state),
    every other signal to the output of its name."""
    out = dict(zip(plant.states, plant.state_paths, strict=True))
    out.update({name: name for name in plant.signals if name not in out})
    return out


def _parameters(plant: PlantModel, params: Any) -> tuple[PlantVariable, ...]:
    """Every entry of the packed parameter vector, in its order: a field's file key
    (``cylinder.stroke``, ``coulomb_friction.force``) or a vector's elements ``key[i]``.
    Effect parameters the plant does not read (the loop's stages, effects of other
    components) are marked so; the wrapper keeps them constant."""
    read = {name for name in plant.effects if name not in INPUT_EFFECTS}
    effect_of = {p.field: name for name, e in LIBRARY.items() for p in e.params}
    out = []
    fields = dataclasses.fields(params)
    for f in fields:
        meta = f.metadata
        if "key" not in meta:
            continue
        unit = meta["unit"]
        effect = effect_of.get(f.name)
        if meta.get("effect"):
            unit = plant.effect_unit(unit)
        doc = meta.get("doc") or meta["key"]
        used = effect is None or effect in read
        out.append(
            PlantVariable(
                meta["key"],
                unit,
                doc if used else f"{doc} (not read by this plant)",
                float(getattr(params, f.name)),
                tunable=used,
            )
        )
    for f in fields:
        if "vector_key" not in f.metadata:
            continue
        values = getattr(params, f.name) or (0.0,) * f.metadata["length"]
        out += [
            PlantVariable(
                f"{f.metadata['vector_key']}[{i + 1}]", "1", f.metadata.get("doc", ""), float(v)
            )
            for i, v in enumerate(values)
        ]
    return tuple(out)


def _identifier(name: str) -> str:
    text = re.sub(r"\W+", "_", name).strip("_") or "plant"
    return text if text[0].isalpha() else f"plant_{text}"


def plant_fmu(rig: Rig, *, fmi: int = 3, tolerance: float | None = None) -> FmuBuild:
    """The FMU of ``rig``'s plant (:func:`plant_fmu_model`), built for this platform:
    model exchange and co-simulation, FMI ``fmi`` 3 or 2."""
    return plant_fmu_build(plant_fmu_model(rig, tolerance=tolerance), fmi=fmi)
