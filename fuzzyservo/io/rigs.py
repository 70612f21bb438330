"""Rig files (YAML) to :class:`~fuzzyservo.rig.Rig` objects.

Layout of a rig file (every number as ``{value, unit, source}``; see ``rigs/``)::

    name: dinca_cylinder
    title: ...
    source: ...
    plant:    {components: {valve: {type: servo_valve, parameters: {...}}, ...}, initial: {...}}
      # a composition of components (fuzzyservo.components.library)
    feedback: {signal: y, offset: ..., gain: ..., ratio: ...,
               noise: ..., adc_bits: ..., adc_lower: ..., adc_upper: ...}  # noise: std dev
    sensors:  {name: {signal, offset, gain, ratio}}          # optional extra readings
    actuator: {name: converter, gain: ..., lower: ..., upper: ...}
    controller: {sample_time: ..., io_delay: ...}  # io_delay: computation + conversion
    output:   {signal: y, display_unit: cm}
    scenarios: {name: {duration, warmup, reference, load, overrides, initial, noise, description}}
    effects:  {coulomb_friction: {force: {value: 150, unit: N}}, valve_lag: {...}}  # optional
    measured: {columns: {d: y_mm, u: u_V}, sample_period: {value: 7.7531, unit: ms}}  # optional
      # a DAQ export: preamble lines, no header, a date column, a sensor in volts, a load cell
    measured: {skip_lines: 3, names: [date, t, pos, F], drop: [date],
               columns: {t: t_s, pos: {as: y_mm, from: V, scale: {value: 20, unit: mm/V}},
                         F: {as: load_N, from: tf, tare: 50}}}

A plant parameter or effect parameter may carry ``fit: [lower, upper]`` (in its
``unit``): it is then an unknown that ``fuzzyservo calibrate`` fits within the bounds.
Effects are off unless declared; the names and parameters are those of
:data:`fuzzyservo.components.effects.LIBRARY`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from fuzzyservo.atomic import write_text
from fuzzyservo.errors import ConfigError, DataError, excerpt
from fuzzyservo.io._yaml import Node, read_yaml
from fuzzyservo.io.measured import ColumnScaling
from fuzzyservo.io.paths import name_problem, shipped_or_path
from fuzzyservo.limits import duration_problem, period_problem
from fuzzyservo.params import check, fields_by_key, vectors_by_key
from fuzzyservo.plants import PlantModel
from fuzzyservo.rig import Actuator, LinearSensor, MeasuredFormat, Rig, Scenario
from fuzzyservo.signals import Affine, Constant, Pulse, Signal, Sines, Steps
from fuzzyservo.units import parse_unit

_TOP = (
    "name",
    "title",
    "source",
    "plant",
    "feedback",
    "sensors",
    "actuator",
    "controller",
    "output",
    "scenarios",
    "effects",
    "measured",
)


def load_rig(path: str | Path, *, plants: Mapping[str, PlantModel] | None = None) -> Rig:
    """Read and validate a rig file (a path, or a shipped rig's name such as
    ``"dinca_cylinder"``); raise :class:`ConfigError` naming file and key.

    ``plants``: plants a file may name under ``plant.type`` with flat ``parameters``
    instead of composing one (none ship; the tests hold the compositions to the seeds'
    hand-written equations so).
    """
    path = shipped_or_path(path, "rigs", "rig")
    return rig_from_data(read_yaml(path), str(path), plants=plants)


def rig_from_data(
    data: dict[str, Any], file: str, *, plants: Mapping[str, PlantModel] | None = None
) -> Rig:
    """A rig from a rig file's parsed mapping (``file``: where it came from, for messages
    and the files it names, e.g. a variant of a shipped rig built in memory)."""
    root = Node(data, file)
    root.only(_TOP)
    plant_node = root.child("plant")
    unknowns: dict[str, tuple[float, float]] = {}
    plants = plants or {}
    if plant_node.has("type") and plant_node.data.get("type") not in plants:
        plant_node.fail(
            f"{excerpt(plant_node.data.get('type'))}: hand-written plant types are gone; compose "
            "the plant from components under 'plant.components' (e.g. rigs/dinca_cylinder.yaml)",
            key="type",
        )
    if plant_node.has("components") or not plant_node.has("type"):
        plant_node.only(("components", "initial"))
        plant, params = _composition(plant_node.child("components"), unknowns)
    else:
        plant_node.only(("type", "parameters", "initial"))
        plant = plants[plant_node.str("type")]
        params = _params(plant, plant_node.child("parameters"), unknowns)
    initial = _initial(plant, plant_node.child("initial", default={}))

    feedback = _sensor(root.child("feedback"), plant)
    sensors = {
        name: _sensor(node, plant, feedback=False)
        for name, node in root.children("sensors").items()
    }
    actuator = _actuator(root.child("actuator"), plant)
    ctrl = root.child("controller")
    ctrl.only(("sample_time", "io_delay"))
    sample_time = ctrl.quantity("sample_time", "s")
    if not sample_time > 0:
        ctrl.fail(
            f"must be > 0 s, got {sample_time} s; give the controller's sampling period",
            key="sample_time",
        )
    io_delay = ctrl.quantity("io_delay", "s", default=0.0)
    # (an implausible sample time is reported by _check_plausible below)
    if not 0 <= io_delay <= 100 * sample_time and not period_problem(sample_time):
        ctrl.fail(
            f"must lie in 0 .. 100 sample times ({100 * sample_time:g} s), got {io_delay} s; "
            "give the latency from sampling the feedback to the command reaching the actuator",
            key="io_delay",
        )
    params, effects = _effects(
        plant, params, root.child("effects", default={}), actuator.rated, sample_time, unknowns
    )
    measured = _measured(root.child("measured")) if root.has("measured") else None

    out = root.child("output")
    out.only(("signal", "display_unit"))
    output = out.str("signal")
    if output not in plant.signals:
        out.fail(
            f"unknown signal {excerpt(output)}; choose one of {list(plant.signals)}", key="signal"
        )
    display_units: dict[str, str] = {}
    if out.has("display_unit"):
        unit = out.str("display_unit")
        out.convert(1.0, unit, plant.signal_units[output], key="display_unit")
        display_units[output] = unit

    scenario_nodes = root.children("scenarios")
    if not scenario_nodes:
        root.fail("no scenarios; add at least one under 'scenarios:'", key="scenarios")
    scenarios = {
        name: _scenario(name, node, plant, params, feedback)
        for name, node in scenario_nodes.items()
    }
    _check_plausible(root, plant, params, initial, scenarios, sample_time)
    name = root.name("name", default=Path(file).stem)
    title = root.str("title", default="")
    source = root.str("source", default="")
    try:
        return Rig(
            name=name,
            title=title,
            source=source,
            plant=plant,
            params=params,
            initial=initial,
            feedback=feedback,
            sensors=sensors,
            actuator=actuator,
            sample_time_s=sample_time,
            output=output,
            display_units=display_units,
            scenarios=scenarios,
            path=file,
            effects=effects,
            unknowns=unknowns,
            measured=measured,
            io_delay_s=io_delay,
        )
    except ValueError as exc:
        # Rig re-checks what was validated above; reaching here is a loader bug, still one line
        raise ConfigError(f"{exc}; fix the rig file", file=file) from None


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
        child.only(("type", "parameters", "source", "note"))
        type_name = child.str("type")
        if type_name not in types:
            child.fail(
                f"unknown component type {excerpt(type_name)}; choose one of {sorted(types)}",
                key="type",
            )
        parts.append((str(name), type_name))
    try:
        plant = compose(tuple(parts))
    except CompositionError as exc:
        node.fail(str(exc))
    by_key = fields_by_key(plant.params_cls)
    vectors = vectors_by_key(plant.params_cls)
    values: dict[str, Any] = {}
    for name, _ in parts:
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


def _measured(node: Node) -> MeasuredFormat:
    """The ``measured:`` section: plain column names -> ``<signal>_<unit>`` (or a mapping
    with ``as``, ``from``, ``scale``, ``offset``, ``tare``), sample period, file layout."""
    node.only(
        ("columns", "sample_period", "resample", "skip_lines", "names", "drop", "source", "note")
    )
    columns: dict[str, str] = {}
    scaling: dict[str, ColumnScaling] = {}
    if node.has("columns"):
        cols = node.child("columns")
        for plain in cols.data:
            key = str(plain)
            if isinstance(cols.data[plain], dict):
                columns[key], scaling[key] = _column_scaling(cols.child(key))
            else:
                columns[key] = cols.str(key)
    skip = node.quantity("skip_lines", "1", default=0.0)
    if skip != int(skip) or skip < 0:
        node.fail(f"must be a whole number of lines >= 0, got {skip:g}", key="skip_lines")
    names = tuple(_text_list(node, "names"))
    drop = tuple(_text_list(node, "drop"))
    period = node.quantity("sample_period", "s") if node.has("sample_period") else None
    if period is not None and period_problem(period):
        node.fail(period_problem(period), key="sample_period")
    resample = node.flag("resample", False, "resample onto an even time grid")
    return MeasuredFormat(
        columns=columns,
        sample_period_s=period,
        resample=resample,
        scaling=scaling,
        skip_lines=int(skip),
        names=names,
        drop=drop,
    )


def _text_list(node: Node, key: str) -> list[str]:
    if not node.has(key):
        return []
    raw = node.data[key]
    if not isinstance(raw, list) or not raw or not all(isinstance(v, str) and v for v in raw):
        node.fail(f"must be a list of column names, like [t, r, y, u], got {excerpt(raw)}", key=key)
    return list(raw)


def _column_scaling(node: Node) -> tuple[str, ColumnScaling]:
    """One scaled column: ``{as: y_mm, from: V, scale: {value: 20, unit: mm/V},
    offset: {value: -5, unit: mm}, tare: 50}`` -> (``y_mm``, scaling in mm per raw unit).

    ``from`` is the unit of the raw numbers (default: plain numbers with a ``scale``,
    else the ``as`` unit). ``scale``
    (default 1 in the ``as`` unit per ``from`` unit) may carry a unit, which must be the
    ``as`` unit over the ``from`` unit in dimension; ``offset`` (default 0) is in the
    ``as`` unit unless it says its own; ``tare`` subtracts the mean of the first
    ``tare`` samples (a load cell's zero)."""
    from fuzzyservo.io.measured import UNIT_SUFFIXES

    node.only(("as", "from", "scale", "offset", "tare", "source", "note"))
    spec = node.str("as")
    suffix = next(
        (u for u in sorted(UNIT_SUFFIXES, key=len, reverse=True) if spec.endswith("_" + u)), None
    )
    if suffix is None or spec == "_" + suffix:
        node.fail(
            f"{excerpt(spec)} names no signal and unit; write <signal>_<unit>, e.g. y_mm or load_N",
            key="as",
        )
    target = UNIT_SUFFIXES[suffix][0]  # unit expression of the mapped column
    # without `from` and `scale` the raw numbers are already in the `as` unit (a tare only)
    raw_unit = node.str("from", default="1" if node.has("scale") else target)
    raw = node.unit(raw_unit, key="from")
    target_unit = parse_unit(target)
    if not node.has("scale"):
        if raw.dims != target_unit.dims:
            node.fail(
                f"from: {raw_unit} is not {target} in dimension; give a scale, "
                f"e.g. {{value: 20, unit: {target}/{raw_unit}}}",
                key="from",
            )
        scale = raw.factor / target_unit.factor
    elif isinstance(node.data["scale"], dict):
        scale_node = node.child("scale")
        scale_node.only(("value", "unit", "source", "note"))
        number = scale_node.number("value")
        unit = scale_node.unit(scale_node.str("unit"))
        if tuple(a + b for a, b in zip(unit.dims, raw.dims, strict=True)) != target_unit.dims:
            node.fail(
                f"unit {excerpt(scale_node.str('unit'))} does not turn {raw_unit} into {target}; "
                f"give the scale in {target}/{raw_unit} (or set from: to the raw unit)",
                key="scale.unit",
            )
        scale = number * unit.factor * raw.factor / target_unit.factor
    else:  # a plain number: the `as` unit per `from` unit (20 for 20 mm/V)
        scale = node.number("scale")
    if scale == 0:
        node.fail("must not be zero; give the sensor's sensitivity", key="scale")
    offset = 0.0
    if node.has("offset"):
        value = node.data["offset"]
        if isinstance(value, dict):
            offset = node.quantity("offset", UNIT_SUFFIXES[suffix][1]) / target_unit.factor
        else:
            offset = node.number("offset")
    tare = node.quantity("tare", "1", default=0.0)
    if tare != int(tare) or tare < 0:
        node.fail(
            f"must be a whole number of samples >= 1 (the load cell's zero is their mean), "
            f"got {tare:g}",
            key="tare",
        )
    return spec, ColumnScaling(scale=scale, offset=offset, tare_samples=int(tare))


# working pressures: below 1 bar or above 10 000 bar a value is a unit mistake (a bare
# number is read in Pa, so "supply_pressure: 70" is 70 Pa, not 70 bar)
_WORKING_PRESSURES = (
    "supply_pressure",
    "relief_cracking_pressure",
    "rated_pressure_drop",
    "nominal_pressure_drop",
)


def _check_plausible(
    root: Node,
    plant: PlantModel,
    params: Any,
    initial: dict[str, float],
    scenarios: dict[str, Scenario],
    sample_time: float,
) -> None:
    """Values every field accepts alone but no rig has: a sample period below 1 µs, a
    working pressure outside 1 bar .. 10 kbar, a start outside the stroke, a run too long
    to hold in memory, a scenario name that cannot be a file name."""
    if period_problem(sample_time):
        root.fail(period_problem(sample_time), key="controller.sample_time")
    for key, f in fields_by_key(plant.params_cls).items():
        instance, _, sub = key.rpartition(".")  # a composition's "supply.supply_pressure"
        if sub not in _WORKING_PRESSURES:
            continue
        value = getattr(params, f.name)
        if not 1e5 <= value <= 1e9:
            where = f"components.{instance}.parameters" if instance else "parameters"
            root.fail(
                f"{value:g} Pa ({value / 1e5:g} bar) is no working pressure (1 bar .. "
                "10 000 bar); a number without a unit is read in Pa: write it like "
                "{value: 70, unit: bar}",
                key=f"plant.{where}.{sub}",
            )
    stroke = getattr(params, "stroke_limits_m", None)
    for name, scenario in scenarios.items():
        where = f"scenarios.{name}"
        if name_problem(name):
            root.fail(name_problem(name), key=where)
        if duration_problem(scenario.duration_s, sample_time):
            root.fail(duration_problem(scenario.duration_s, sample_time), key=f"{where}.duration")
        if stroke is None:
            continue
        lo, hi = dataclasses.replace(params, **scenario.overrides).stroke_limits_m
        for key, start in (("plant.initial", initial), (where + ".initial", scenario.initial)):
            y = start.get("position", start.get("y_m"))  # a composition's, a kernel's name
            if y is not None and not lo <= y <= hi:
                root.fail(
                    f"{y:g} m lies outside the stroke {lo:g} .. {hi:g} m; give a start "
                    "position inside it (check the unit)",
                    key=f"{key}.position",
                )


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


def _sensor(node: Node, plant: PlantModel, *, feedback: bool = True) -> LinearSensor:
    """The feedback sensor reads a state (the compiled loop samples it); an extra sensor
    reads any signal (position, velocity, pressure, force ...), scaled and offset."""
    node.only(
        ("signal", "offset", "gain", "ratio", "unit", "noise", "adc_bits", "adc_lower", "adc_upper")
    )
    signal = node.str("signal")
    readable = plant.states if feedback else (*plant.signals, *plant.states)
    if signal not in readable:
        what = "state" if feedback else "signal"
        node.fail(
            f"unknown {what} {excerpt(signal)}; {'the feedback sensor reads' if feedback else 'sensors read'} "
            f"one of {list(dict.fromkeys(readable))}",
            key="signal",
        )
    signal_unit = plant.signal_units[signal]
    unit = node.str("unit", default="V")
    gain = node.quantity("gain", f"{unit}/({signal_unit})")
    ratio = node.quantity("ratio", "1", default=1.0)
    for key, value in (("gain", gain), ("ratio", ratio)):
        if value == 0:
            node.fail(
                f"must not be zero, got {value}; give the sensor's {key} "
                f"({'reading per unit of ' + signal if key == 'gain' else 'e.g. a gear ratio, 1 if none'})",
                key=key,
            )
    noise = node.quantity("noise", unit, default=0.0)
    if not noise >= 0:
        node.fail(f"must be >= 0 {unit} (a standard deviation), got {noise}", key="noise")
    bits_value = node.quantity("adc_bits", "1", default=0.0)
    if bits_value != int(bits_value) or not 0 <= bits_value <= 32:
        node.fail(f"must be a whole number of bits in 1..32, got {bits_value:g}", key="adc_bits")
    bits = int(bits_value)
    lower = node.quantity("adc_lower", unit, default=0.0)
    upper = node.quantity("adc_upper", unit, default=0.0)
    if bits and not lower < upper:
        node.fail(
            f"`adc_lower < adc_upper` must hold, but got (adc_lower={lower} {unit}, "
            f"adc_upper={upper} {unit}); give the ADC's input range",
            key="adc_upper",
        )
    return LinearSensor(
        signal=signal,
        offset=node.quantity("offset", unit, default=0.0),
        gain=gain,
        ratio=ratio,
        unit=unit,
        noise_std=noise,
        adc_bits=bits,
        adc_lower=lower,
        adc_upper=upper,
    )


def _actuator(node: Node, plant: PlantModel) -> Actuator:
    node.only(("name", "gain", "lower", "upper"))
    name, unit = plant.input
    lower = node.quantity("lower", unit)
    upper = node.quantity("upper", unit)
    if not lower < upper:
        node.fail(
            f"`lower < upper` must hold, but got (lower={lower} {unit}, upper={upper} {unit}); swap them"
        )
    gain = node.quantity("gain", f"{unit}/V")
    if gain == 0:
        node.fail(
            f"must not be zero, got {gain} {unit}/V; give the {unit} per command volt", key="gain"
        )
    return Actuator(
        name=node.str("name", default=name), gain=gain, lower=lower, upper=upper, unit=unit
    )


_SCENARIO_KEYS = (
    "description",
    "duration",
    "warmup",
    "reference",
    "load",
    "overrides",
    "initial",
    "noise",
)


def _scenario(
    name: str, node: Node, plant: PlantModel, params: Any, feedback: LinearSensor
) -> Scenario:
    node.only(_SCENARIO_KEYS)
    duration = node.quantity("duration", "s")
    warmup = node.quantity("warmup", "s", default=0.0)
    if not duration > 0:
        node.fail(f"must be > 0 s, got {duration} s; give the simulated time", key="duration")
    if not 0 <= warmup < duration:
        node.fail(
            f"must lie in [0, duration = {duration} s), got {warmup} s; "
            "make the warm-up shorter than the duration",
            key="warmup",
        )
    reference = _reference(node.child("reference"), plant, feedback)
    load = Constant(0.0)
    if node.has("load"):
        _, load_unit = plant.load
        load_node = node.child("load")
        if isinstance(load_node.data, dict) and load_node.data.get("type") == "measured":
            load = _measured_signal(load_node, load_unit)
        else:
            load = _signal(load_node, load_unit, lambda s: s)
    overrides = {}
    if node.has("overrides"):
        ov = node.child("overrides")
        by_key = fields_by_key(plant.params_cls)
        ov.only(by_key)
        for key in ov.data:
            overrides[by_key[key].name] = ov.quantity(key, by_key[key].metadata["unit"])
        _build_params(plant, {**dataclasses.asdict(params), **overrides}, ov)
    initial = _initial(plant, node.child("initial", default={}))
    noise = node.flag("noise", True, "sensor noise on or off")
    return Scenario(
        name=name,
        duration_s=duration,
        warmup_s=warmup,
        reference=reference,
        load=load,
        overrides=overrides,
        initial=initial,
        description=node.str("description", default=""),
        noise=noise,
    )


def _reference(node: Node, plant: PlantModel, feedback: LinearSensor) -> Signal:
    """A reference in the feedback unit, or in the unit of the sensed signal (through the sensor)."""
    unit = node.str("unit", default=feedback.unit)
    dims = node.unit(unit).dims
    if dims == parse_unit(feedback.unit).dims:
        return _signal(node, feedback.unit, lambda s: s)
    sensed_unit = plant.signal_units[feedback.signal]
    if dims == parse_unit(sensed_unit).dims:
        return _signal(
            node, sensed_unit, lambda s: Affine(s, gain=feedback.slope, offset=feedback.offset)
        )
    node.fail(
        f"unit {excerpt(unit)} is neither the feedback unit ({feedback.unit}) nor that of "
        f"{excerpt(feedback.signal)} ({sensed_unit}); give the reference in one of them",
        key="unit",
    )


def _measured_signal(node: Node, si_unit: str) -> Signal:
    """``{type: measured, file: f.csv, signal: f}``: a recorded signal (e.g. a load force
    measured on the rig), held between its samples; the file is read like measured data
    (``<signal>_<unit>`` columns) relative to the rig file, time shifted to start at 0."""
    from fuzzyservo.io.measured import read_measured
    from fuzzyservo.signals import Sampled

    node.only(("type", "file", "signal", "source", "note"))
    name = node.str("signal")
    path = Path(node.file).parent / node.str("file")
    try:
        data = read_measured(path, require=("t", name))
    except DataError as exc:
        node.fail(f"{exc}; fix the file or name another", key="file")
    node.convert(1.0, data.units[name], si_unit, key="signal")
    return Sampled(np.asarray(data.t - data.t[0]), np.asarray(data.signals[name]))


_SIGNAL_KEYS = {
    "constant": ("value",),
    "steps": ("times_s", "values", "initial"),
    "pulse": ("base", "amplitude", "period_s", "duty", "delay_s"),
    "sines": ("amplitudes", "frequencies_hz", "phases_rad", "offset"),
}


def _signal(node: Node, si_unit: str, wrap) -> Signal:
    kind = node.str("type")
    if kind not in _SIGNAL_KEYS:
        node.fail(
            f"unknown signal type {excerpt(kind)}; choose one of {sorted(_SIGNAL_KEYS)}", key="type"
        )
    node.only(("type", "unit", *_SIGNAL_KEYS[kind]))
    scale = node.convert(1.0, node.str("unit", default=si_unit), si_unit)
    # read every number first: ConfigErrors from the reads keep their own key
    make: type[Signal]
    if kind == "constant":
        make = Constant
        kwargs: dict[str, Any] = {"value": scale * node.number("value")}
    elif kind == "steps":
        make = Steps
        kwargs = {
            "times_s": tuple(node.numbers("times_s")),
            "values": tuple(scale * v for v in node.numbers("values")),
            "initial": scale * node.number("initial", default=0.0),
        }
    elif kind == "pulse":
        make = Pulse
        kwargs = {
            "base": scale * node.number("base"),
            "amplitude": scale * node.number("amplitude"),
            "period_s": node.number("period_s"),
            "duty": node.number("duty", default=0.5),
            "delay_s": node.number("delay_s", default=0.0),
        }
    else:
        make = Sines
        kwargs = {
            "amplitudes": tuple(scale * v for v in node.numbers("amplitudes")),
            "frequencies_hz": tuple(node.numbers("frequencies_hz")),
            "phases_rad": tuple(node.numbers("phases_rad", default=[])),
            "offset": scale * node.number("offset", default=0.0),
        }
    try:
        signal = make(**kwargs)
    except ValueError as exc:
        # the signal classes start their messages with the offending key: "period_s must be > 0"
        key, _, rest = str(exc).partition(" ")
        if key in kwargs and rest.startswith("must"):
            node.fail(f"{rest}; correct the value", key=key)
        node.fail(f"{exc}; correct the {kind} signal")
    return wrap(signal)


def write_calibrated_rig(
    source: str | Path,
    out: str | Path,
    *,
    parameters: dict[str, tuple[float, str, str]],
    effects: dict[str, dict[str, tuple[float, str, str]]],
    header: str,
    intervals: dict[str, tuple[float, float, bool]] | None = None,
) -> Path:
    """Write a copy of rig file ``source`` with ``parameters`` (key -> value, unit,
    source) changed under ``plant.parameters`` and ``effects`` (name -> key -> value,
    unit, source) declared. ``intervals`` (parameter key or ``effect.key`` -> 95 %
    interval low, high in the value's unit, at a bound) adds ``interval: [lo, hi]`` and
    ``at_bound`` to those entries. Comments of the original are not kept; ``header`` opens the
    file. Files the rig names are re-pointed relative to the new location."""
    import os

    import yaml

    data = read_yaml(source)
    src_dir = Path(source).resolve().parent
    out = Path(out)
    plant = data["plant"]
    composed = "components" in plant
    sections = (
        [c.setdefault("parameters", {}) or {} for c in plant["components"].values()]
        if composed
        else [plant["parameters"]]
    )
    for entries in sections:
        for entry in entries.values():
            if isinstance(entry, dict) and "file" in entry:
                target = (src_dir / entry["file"]).resolve()
                entry["file"] = os.path.relpath(target, out.parent.resolve())
    for full_key, (value, unit, source_text) in parameters.items():
        key = full_key
        if composed:  # "valve.rated_flow" lives at components.valve.parameters.rated_flow
            name, _, key = full_key.partition(".")
            component = plant["components"][name]
            if not component.get("parameters"):
                component["parameters"] = {}
            plant_params = component["parameters"]
        else:
            plant_params = plant["parameters"]
        old = plant_params.get(key, {})
        note = old.get("source") if isinstance(old, dict) else None
        plant_params[key] = {"value": float(value), "unit": unit, "source": source_text}
        _add_interval(plant_params[key], (intervals or {}).get(full_key))
        if note:
            plant_params[key]["note"] = f"declared source: {note}"
    section = data.setdefault("effects", {}) or {}
    for name, values in effects.items():
        section[name] = {
            key: {"value": float(v), "unit": u, "source": s} for key, (v, u, s) in values.items()
        }
        for key in values:
            _add_interval(section[name][key], (intervals or {}).get(f"{name}.{key}"))
    data["effects"] = section
    text = yaml.safe_dump(data, sort_keys=False, allow_unicode=True, width=100)
    lines = "".join(f"# {line}\n" for line in header.splitlines())
    return write_text(out, lines + text)


def _add_interval(entry: dict, interval: tuple[float, float, bool] | None) -> None:
    if interval is not None:
        lo, hi, at_bound = interval
        entry["interval"] = [float(lo), float(hi)]
        entry["at_bound"] = bool(at_bound)


@dataclasses.dataclass(frozen=True)
class FittedInterval:
    """A fitted value's 95 % interval as a calibrated rig file carries it (``interval`` and
    ``at_bound`` beside ``value`` and ``unit``; :func:`write_calibrated_rig`). ``key``: the
    plant parameter's key (``valve.rated_flow`` in a composition) or ``effect.key``;
    ``unit``: the entry's unit (effect parameters are SI, their unit is empty here)."""

    key: str
    low: float
    high: float
    unit: str
    at_bound: bool


def fitted_intervals(path: str | Path) -> list[FittedInterval]:
    """Every entry of rig file ``path`` that carries a fitted ``interval: [lo, hi]`` (what
    ``fuzzyservo calibrate`` writes into ``<rig>_calibrated.yaml``), in file order; a
    malformed interval is one :class:`ConfigError` line naming its key."""
    file = str(path)
    root = Node(read_yaml(path), file)
    plant = root.child("plant")
    found: list[tuple[str, Node]] = []  # key prefix, parameters section
    if plant.has("components"):
        for name, comp in plant.children("components").items():
            if comp.data.get("parameters"):
                found.append((f"{name}.", comp.child("parameters")))
    elif plant.has("parameters"):
        found.append(("", plant.child("parameters")))
    out = []
    for prefix, section in found:
        for key, entry in section.data.items():
            if isinstance(entry, dict) and "interval" in entry:
                out.append(_fitted(Node(entry, file, section.path(str(key))), prefix + str(key)))
    if root.data.get("effects"):
        for name, effect in root.children("effects").items():
            for key, entry in effect.data.items():
                if isinstance(entry, dict) and "interval" in entry:
                    node = Node(entry, file, effect.path(str(key)))
                    out.append(dataclasses.replace(_fitted(node, f"{name}.{key}"), unit=""))
    return out


def _fitted(node: Node, key: str) -> FittedInterval:
    pair = node.data["interval"]
    if not (
        isinstance(pair, list)
        and len(pair) == 2
        and all(isinstance(v, int | float) and not isinstance(v, bool) for v in pair)
        and all(np.isfinite(pair))
        and pair[0] <= pair[1]
    ):
        node.fail(
            f"must be [low, high], two finite numbers in order, got {excerpt(pair)}", key="interval"
        )
    at_bound = node.flag("at_bound", False, "the fit ended on its bound")
    unit = node.data.get("unit", "")
    return FittedInterval(key, float(pair[0]), float(pair[1]), str(unit or ""), at_bound)
