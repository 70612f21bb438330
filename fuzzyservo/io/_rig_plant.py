"""The plant of a rig file: its ``plant:`` section and its ``effects:``.

A composition of components (or a plant a caller names under ``plant.type``), each
parameter a quantity that may carry ``fit: [lower, upper]`` (an unknown for ``fuzzyservo
calibrate``), vector parameters read from the files the rig file names, the initial
state, and the declared effects written into the parameters. Used by
:mod:`fuzzyservo.io.rigs`.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

from fuzzyservo.errors import DataError, excerpt
from fuzzyservo.io._yaml import Node
from fuzzyservo.params import check, fields_by_key, vectors_by_key
from fuzzyservo.plants import PlantModel


def _params(
    plant: PlantModel, node: Node, unknowns: dict[str, tuple[float, float]] | None = None
) -> Any:
    by_key = fields_by_key(plant.params_cls)
    vectors = vectors_by_key(plant.params_cls)
    node.only((*by_key, *vectors))
    values: dict[str, Any] = {}
    for key, f in by_key.items():
        default = None if f.default is dataclasses.MISSING else f.default
        values[f.name] = _quantity(node, key, f.metadata["unit"], f.name, unknowns, default)
    for key, f in vectors.items():
        if node.has(key):
            values[f.name] = _vector(node.child(key), f.metadata["format"])
    return _build_params(plant, values, node)


def _composition(node: Node, unknowns: dict[str, tuple[float, float]]) -> tuple[PlantModel, Any]:
    """``plant.components``: instance name -> {type, parameters, source, note}."""
    from fuzzyservo.components.declare import registry
    from fuzzyservo.plants.composed import CompositionError, compose

    if not isinstance(node.data, dict) or not node.data:
        node.fail(
            "must map instance names to components ({type: ..., parameters: {...}}); "
            "see rigs/servo_lift.yaml"
        )
    types = registry()
    parts = []
    for name in node.data:
        child = node.child(str(name))
        child.only(("type", "axis", "parameters", "source", "note"))
        type_name = child.str("type")
        axis = child.str("axis") if child.has("axis") else ""
        if type_name not in types:
            child.fail(
                f"unknown component type {excerpt(type_name)}; choose one of {sorted(types)}",
                key="type",
            )
        parts.append((str(name), type_name, axis) if axis else (str(name), type_name))
    try:
        plant = compose(tuple(parts))
    except CompositionError as exc:
        node.fail(str(exc))
    by_key = fields_by_key(plant.params_cls)
    vectors = vectors_by_key(plant.params_cls)
    values: dict[str, Any] = {}
    for name, *_ in parts:
        params_node = node.child(name).child("parameters", default={})
        prefix = f"{name}."
        keys = {k[len(prefix) :]: f for k, f in by_key.items() if k.startswith(prefix)}
        files = {k[len(prefix) :]: f for k, f in vectors.items() if k.startswith(prefix)}
        params_node.only((*keys, *files))
        for key, f in keys.items():
            default = None if f.default is dataclasses.MISSING else f.default
            values[f.name] = _quantity(
                params_node, key, f.metadata["unit"], f.name, unknowns, default
            )
        for key, f in files.items():
            if not params_node.has(key):
                params_node.fail(f"missing key {key!r}; {f.metadata['doc']}", key=key)
            values[f.name] = _vector(params_node.child(key), f.metadata["format"])
    return plant, _build_params(plant, values, node)


def _fmu(
    node: Node, params_node: Node, unknowns: dict[str, tuple[float, float]]
) -> tuple[PlantModel, Any]:
    """``plant.fmu``: {file (relative to the rig file), input, load, signals, interface};
    the FMU's parameters under ``plant.parameters``."""
    from fuzzyservo.plants.fmu import INTERFACES, FmuPlantError, fmu_plant

    node.only(("file", "input", "load", "signals", "interface", "source", "note"))
    interface = node.str("interface") if node.has("interface") else None
    if interface is not None and interface not in INTERFACES:
        node.fail(f"must be one of {list(INTERFACES)}, got {interface!r}", key="interface")
    signals = node.child("signals", default={})
    for key, value in signals.data.items():
        if not isinstance(value, str):
            signals.fail("must name an FMU variable (e.g. position: x0)", key=str(key))
    try:
        plant = fmu_plant(
            Path(node.file).parent / node.str("file"),
            input=node.str("input") if node.has("input") else None,
            load=node.str("load") if node.has("load") else None,
            signals={str(k): v for k, v in signals.data.items()} or None,
            interface=interface,
        )
    except FmuPlantError as exc:
        node.fail(str(exc))
    return plant, _params(plant, params_node, unknowns)


def _quantity(
    node: Node,
    key: str,
    si_unit: str,
    field: str,
    unknowns: dict[str, tuple[float, float]] | None,
    default: float | None = None,
) -> float:
    """A quantity that may carry ``fit: [lower, upper]`` (same unit as its value): the
    bounds go to ``unknowns[field]`` in SI."""
    raw = node.data.get(key) if isinstance(node.data, dict) else None
    if not (isinstance(raw, dict) and "fit" in raw):
        return node.quantity(key, si_unit, default=default)
    if unknowns is None:
        node.fail("`fit` bounds are not allowed here; give a plain value", key=f"{key}.fit")
    plain = Node({k: v for k, v in raw.items() if k != "fit"}, node.file, node.path(key))
    value_node = Node({key: plain.data}, node.file, node.key)
    value = value_node.quantity(key, si_unit)
    unit = plain.str("unit", default=si_unit)
    bounds = Node(raw, node.file, node.path(key)).numbers("fit")
    if len(bounds) != 2 or not bounds[0] < bounds[1]:
        node.fail(
            f"must be [lower, upper] with lower < upper (in {unit}), got {excerpt(bounds)}; "
            "give the range the value may take",
            key=f"{key}.fit",
        )
    lo, hi = (plain.convert(b, unit, si_unit) for b in bounds)
    lo, hi = min(lo, hi), max(lo, hi)
    if not lo <= value <= hi:
        node.fail(
            f"value {value:g} {si_unit} lies outside its fit bounds [{lo:g}, {hi:g}] {si_unit}; "
            "widen the bounds or move the value",
            key=f"{key}.fit",
        )
    unknowns[field] = (lo, hi)
    return value


def _effects(
    plant: PlantModel,
    params: Any,
    node: Node,
    rated_input: float,
    sample_time: float,
    unknowns: dict[str, tuple[float, float]],
) -> tuple[Any, tuple[str, ...]]:
    """The ``effects:`` section: each declared effect's parameters written into ``params``."""
    from fuzzyservo.components.effects import LIBRARY, fixed_defaults

    if not isinstance(node.data, dict):
        node.fail(
            "must be a mapping of effect names to their parameters (docs/calibration.md, The effect library)"
        )
    for name in node.data:
        if name not in LIBRARY:
            node.fail(f"unknown effect {excerpt(name)}; choose one of {sorted(LIBRARY)}", key=name)
        refusal = plant.refusal(name)
        if refusal:
            node.fail(refusal, key=name)
    values: dict[str, float] = {}
    declared: dict[str, list[str]] = {}  # effect -> the parameter keys the file gives
    for name, effect_node in _effect_nodes(node):
        effect = LIBRARY[name]
        effect_node.only((*(p.key for p in effect.params), "source", "note"))
        for param in effect.params:
            si_unit = plant.effect_unit(param.unit)
            if effect_node.has(param.key):
                values[param.field] = _quantity(
                    effect_node, param.key, si_unit, param.field, unknowns
                )
            elif param.fitted and not param.optional:
                effect_node.fail(
                    f"missing key {param.key!r} (a value in {si_unit}); give it, or "
                    f"`{{value: ..., unit: {si_unit}, fit: [lower, upper]}}` to have it fitted",
                )
        declared[name] = [p.key for p in effect.params if effect_node.has(p.key)]
    if not declared:
        return params, ()
    params = _build_params(plant, {**dataclasses.asdict(params), **values}, node)
    scales = plant.scales(params, rated_input, sample_time)
    defaults = {}
    for name, given in declared.items():
        defaults.update(fixed_defaults(name, params, scales, given))
    if defaults:
        params = dataclasses.replace(params, **defaults)
    return params, tuple(declared)


def _effect_nodes(node: Node) -> list[tuple[str, Node]]:
    return [
        (name, Node(data if data is not None else {}, node.file, node.path(name)))
        for name, data in node.data.items()
    ]


def _read_valve_network(path: Path) -> tuple[float, ...]:
    from fuzzyservo.io.valve_data import read_valve_network

    return read_valve_network(path).weights


# vector parameters (params.vector) are read from a file named in the rig file
_VECTOR_READERS = {"valve_network": _read_valve_network}


def _vector(node: Node, fmt: str) -> tuple[float, ...]:
    """``{file, source, note}``: the file, relative to the rig file, read by its format."""
    node.only(("file", "source", "note"))
    path = Path(node.file).parent / node.str("file")
    try:
        return _VECTOR_READERS[fmt](path)
    except DataError as exc:
        node.fail(f"{exc}; fix the file or name another", key="file")


def _build_params(plant: PlantModel, values: dict[str, float], node: Node) -> Any:
    try:
        params = plant.params_cls(**values)
        check(params)
    except ValueError as exc:
        key, _, rest = str(exc).partition(": ")
        if plant.components and key in fields_by_key(plant.params_cls):
            # a composition's key "valve.rated_flow" lives at valve.parameters.rated_flow
            name, _, sub = key.partition(".")
            if node.has(name):
                node.child(name).child("parameters", default={}).fail(rest, key=sub)
            node.fail(rest, key=key)
        if key in fields_by_key(plant.params_cls) or key in vectors_by_key(plant.params_cls):
            node.fail(rest, key=key)
        node.fail(str(exc))
    return params


def _initial(plant: PlantModel, node: Node) -> dict[str, float]:
    node.only(plant.initial_keys)
    return {
        kw: node.quantity(key, unit)
        for key, (kw, unit) in plant.initial_keys.items()
        if node.has(key)
    }
