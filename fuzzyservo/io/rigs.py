"""Rig files (YAML) to :class:`~fuzzyservo.rig.Rig` objects.

Layout of a rig file (every number as ``{value, unit, source}``; see ``rigs/``)::

    name: dinca_cylinder
    title: ...
    source: ...
    plant:    {components: {valve: {type: servo_valve, parameters: {...}}, ...}, initial: {...}}
      # a composition of components (fuzzyservo.components.library), or a plant FMU:
    plant:    {fmu: {file: plant.fmu, input: u, load: f, signals: {y: x}}, parameters: {...}}
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

The sections are read by private modules of :mod:`fuzzyservo.io`: ``_rig_plant`` (the
plant, its parameters and unknowns, the effects), ``_rig_loop`` (sensors, actuator,
scenarios and their signals) and ``_rig_measured`` (the measured-data layout). This
module ties them into a :class:`~fuzzyservo.rig.Rig`, checks what only the whole file
shows, and writes and reads back calibrated copies.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from fuzzyservo.atomic import write_text
from fuzzyservo.errors import ConfigError, excerpt
from fuzzyservo.io._rig_loop import _actuator, _scenario, _sensor
from fuzzyservo.io._rig_measured import _measured
from fuzzyservo.io._rig_plant import _composition, _effects, _fmu, _initial, _params
from fuzzyservo.io._yaml import Node, read_yaml
from fuzzyservo.io.paths import name_problem, shipped_or_path
from fuzzyservo.limits import duration_problem, period_problem
from fuzzyservo.params import fields_by_key
from fuzzyservo.plants import PlantModel
from fuzzyservo.rig import Rig, Scenario

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


def rig_file(name: str | Path) -> Path | None:
    """The rig file ``name`` names — a YAML file whose top level has ``plant:``, or a
    shipped rig's name — else None (a controller file, say, or nothing)."""
    text = str(name)
    path = Path(text)
    if not path.is_file():
        if path.suffix or "/" in text or "\\" in text:
            return None
        try:
            path = Path(shipped_or_path(text, "rigs", "rig"))
        except ConfigError:
            return None
    if path.suffix.lower() not in (".yaml", ".yml"):
        return None
    try:
        return path if "plant" in read_yaml(path) else None
    except ConfigError:
        return None


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
    if plant_node.has("fmu"):
        plant_node.only(("fmu", "parameters", "initial"))
        plant, params = _fmu(
            plant_node.child("fmu"), plant_node.child("parameters", default={}), unknowns
        )
    elif plant_node.has("components") or not plant_node.has("type"):
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


def write_fmu_rig(
    source: str | Path,
    out: str | Path,
    *,
    fmu: str | Path,
    input: str,
    load: str,
    signals: Mapping[str, str],
    header: str,
) -> Path:
    """Write a copy of rig file ``source`` whose plant is the FMU ``fmu`` (its plant
    exported): ``plant.fmu`` maps the ``input``, ``load`` and ``signals`` (loop name ->
    FMU variable); the rest of the rig — loop stages, scenarios, effects — stays as it
    is. Comments of the original are not kept; ``header`` opens the file."""
    import os

    import yaml

    data = read_yaml(source)
    out = Path(out)
    data["name"] = f"{data.get('name', Path(source).stem)}_fmu"
    data["plant"] = {
        "fmu": {
            "file": os.path.relpath(Path(fmu).resolve(), out.parent.resolve()),
            "input": input,
            "load": load,
            "signals": dict(signals),
        }
    }
    text = yaml.safe_dump(data, sort_keys=False, allow_unicode=True, width=100)
    lines = "".join(f"# {line}\n" for line in header.splitlines())
    return write_text(out, lines + text)
