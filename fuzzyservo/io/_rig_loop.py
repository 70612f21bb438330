"""The loop around a rig file's plant: the feedback sensor and extra sensors, the
actuator, and the scenarios with their reference and load signals (in the file's units,
converted to SI; a load may be a recorded signal). Used by :mod:`fuzzyservo.io.rigs`.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from fuzzyservo.errors import DataError, excerpt
from fuzzyservo.io._rig_plant import _build_params, _initial
from fuzzyservo.io._yaml import Node
from fuzzyservo.params import fields_by_key
from fuzzyservo.plants import PlantModel
from fuzzyservo.rig import Actuator, LinearSensor, Scenario
from fuzzyservo.signals import Affine, Constant, Pulse, Signal, Sines, Steps
from fuzzyservo.units import parse_unit


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
