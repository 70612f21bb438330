"""A plant composed from components (``plant.components`` in a rig file).

:func:`compose` turns instances of component types (:mod:`fuzzyservo.components.declare`)
into a :class:`~fuzzyservo.plants.PlantModel`: a frozen parameter class whose fields
are the instances' parameters (file key ``<instance>.<key>``), the state vector laid
out by state group, and the source that joins the components' phase functions into one
right-hand side (:attr:`~fuzzyservo.plants.PlantModel.kernels`), which the closed loop
calls (:func:`fuzzyservo.simulation.binding.bind`). That source is only the sequence of calls: each
argument passed by its name, each return bound to the circuit's variable it names, every
index generated from the declarations; no equation is written there.

The circuit has one fluid, one supply, at most one accumulator, and one axis or several:
each axis one 4-way valve, at most one pair of lines, one actuator and any number of
loads (a part's axis is the third entry of its ``parts`` tuple, ``axis:`` in a rig
file). The supply sees the sum of the valves' flows; the loop drives every valve with
its one command. The phases of :data:`~fuzzyservo.components.declare.PHASES` run in
order, each instance's functions in the order the rig file lists them.
"""

from __future__ import annotations

import dataclasses
import importlib
import re
from collections.abc import Mapping
from functools import cache
from typing import Any

import numpy as np

from fuzzyservo._jit import compile_step
from fuzzyservo.components.declare import (
    CIRCUIT,
    PHASES,
    ROLES,
    STATE_GROUPS,
    Component,
    arguments,
    registry,
)
from fuzzyservo.components.effects import INPUT_EFFECTS, LIBRARY, EffectParams, Scales
from fuzzyservo.params import index_of, pack, quantity, vector, vector_offset
from fuzzyservo.plants import PlantModel
from fuzzyservo.plants._jacobian import jacobian_source
from fuzzyservo.plants.native import native_kernels

_STATIC_FORCE = "static_force"


class CompositionError(ValueError):
    """A composition that cannot be built; the message names the instance and the fix."""


_TOKENS = re.compile(r"\b(force|velocity|position|mass|input)\b")


def _resolve_unit(unit: str, mechanics: Mapping[str, str], input_unit: str) -> str:
    """A declared unit with its tokens resolved: ``force/velocity`` -> ``(N)/(m/s)``."""
    table = {**mechanics, "input": input_unit}
    if unit in table:
        return table[unit]
    return _TOKENS.sub(lambda m: f"({table[m.group(1)]})", unit)


def compose(parts: tuple[tuple[str, ...], ...], bristles: bool = False) -> PlantModel:
    """The plant of the instances ``parts`` = ((instance name, component type), ...), or
    ((instance name, component type, axis), ...) for a circuit of several axes.

    ``bristles``: with the ``bristles`` states (LuGre friction's bristle deflection, last
    in the state vector) and the components' ``bristle_code``; without them (the
    default) every run is spared a state that would stay at 0. Both forms share one
    parameter class; :meth:`~fuzzyservo.plants.PlantModel.for_params` picks the one a
    parameter set needs. Cached: the same composition gives the same plant (and
    parameter class) every time. Raises :class:`CompositionError` naming the instance
    when the circuit is incomplete.
    """
    return _compose(tuple(parts), bool(bristles))  # one cache key however it is called


@cache
def _compose(parts: tuple[tuple[str, ...], ...], bristles: bool) -> PlantModel:
    types = registry()
    instances: list[tuple[str, Component]] = []
    axis_of: dict[str, str] = {}  # instance -> its axis ("" in a one-axis circuit)
    for name, type_name, *axis in parts:
        axis_of[name] = axis[0] if axis else ""
        if not name.isidentifier():
            raise CompositionError(
                f"{name}: an instance name must be a Python identifier (letters, digits, _)"
            )
        if type_name not in types:
            raise CompositionError(
                f"{name}: unknown component type {type_name!r}; choose one of {sorted(types)}"
            )
        instances.append((name, types[type_name]))
    axes = _axes(instances, axis_of, types)
    valve = next(c for _, c in instances if c.role == "valve")
    actuator = next(c for _, c in instances if c.role == "actuator")
    mechanics = dict(actuator.mechanics or {"force": "N", "velocity": "m/s", "position": "m"})
    # the scenario's load input: each axis's actuator force, unless a load takes it
    takers = {axis_of[n]: c for n, c in instances if c.role == "load" and c.load}
    input_name, input_unit = valve.input or ("u", "V")

    # parameters: one frozen dataclass, fields <instance>__<key>, file keys <instance>.<key>
    fields = []
    owner: dict[str, tuple[str, Component, str]] = {}  # field -> (instance, component, key)
    for name, comp in instances:
        for prm in comp.params:
            field_name = f"{name}__{prm.key}"
            if prm.length:  # a vector (e.g. network weights), packed after the scalars
                meta = vector(f"{name}.{prm.key}", prm.length, fmt=prm.fmt, doc=prm.doc).metadata
                fields.append((field_name, tuple[float, ...], dataclasses.field(metadata=meta)))
                owner[field_name] = (name, comp, prm.key)
                continue
            unit = _resolve_unit(prm.unit, mechanics, input_unit)
            kwargs: dict[str, Any] = {
                "positive": prm.positive,
                "nonnegative": prm.nonnegative,
                "minimum": prm.minimum,
                "maximum": prm.maximum,
                "doc": prm.doc,
            }
            if prm.default is not None:
                kwargs["default"] = prm.default
            fields.append((field_name, float, quantity(f"{name}.{prm.key}", unit, **kwargs)))
            owner[field_name] = (name, comp, prm.key)
    # required fields before defaulted ones (dataclass rule); the order packs the vector
    fields.sort(key=lambda f: f[2].default is not dataclasses.MISSING)
    label = "_".join(t for _, t, *_ in parts)
    if bristles:  # one parameter class for both forms: the same values run on either
        params_cls = compose(parts).params_cls
    else:
        params_cls = dataclasses.make_dataclass(
            "ComposedParams",
            fields,
            bases=(EffectParams,),
            frozen=True,
            namespace={
                "__doc__": f"Parameters of the composition {label} (SI).",
                "__post_init__": _make_post_init(instances),
                # pickled as its composition and values: the class is made here, at load time,
                # so a worker process (calibration's candidate pool) rebuilds it with compose()
                "__reduce__": lambda self: (
                    _composed_params,
                    (parts, {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}),
                ),
                **_stroke(instances),
            },
        )
        params_cls.__module__ = __name__
        params_cls.__qualname__ = f"ComposedParams[{label}]"
    # P.key: a scalar's entry p[i]; a vector's start in p (code passes p and it on)
    param_index = {
        (name, prm.key): (
            (True, vector_offset(params_cls, f"{name}__{prm.key}"))
            if prm.length
            else (False, index_of(params_cls, f"{name}__{prm.key}"))
        )
        for name, comp in instances
        for prm in comp.params
    }

    # states, grouped in STATE_GROUPS order
    declared = [
        (name, comp, st)
        for name, comp in instances
        for st in comp.states
        if bristles or st.group != "bristles"
    ]
    declared.sort(key=lambda item: STATE_GROUPS.index(item[2].group))
    state_index = {(name, st.name): i for i, (name, _, st) in enumerate(declared)}
    state_names = tuple(_named(axis_of[name], st.name) for name, _, st in declared)
    if len(set(state_names)) != len(state_names):
        raise CompositionError(f"two components declare the same state name: {state_names}")

    calls = _Calls(param_index, state_index, axis_of)
    # the body: phases in order, instances in file order; defaults where a role is absent
    body: list[str] = []
    for axis in axes:
        body += [f"{_local(axis, 'mass')} = 0.0", f"{_local(axis, 'f_load')} = "
                 + ("0.0" if axis in takers else "f_ext")]  # fmt: skip
        calls.circuit |= {_local(axis, "mass"), _local(axis, "f_load")}
    body += [line for name, comp in instances for line in calls.records(name, comp)]
    lined = {axis_of[n] for n, c in instances if c.role == "line"}
    for phase in PHASES:
        for axis in axes:
            if phase in _WITHOUT_LINES and axis not in lined:
                for target, source in _WITHOUT_LINES[phase]:
                    body.append(f"{_local(axis, target)} = {_local(axis, source)}")
                    calls.circuit.add(_local(axis, target))
        for name, comp in instances:
            functions = (bristles and comp.bristle_code.get(phase)) or comp.code.get(phase)
            if functions is not None:
                body.append(f"# {name} ({comp.type}): {phase}")
                for function in functions if isinstance(functions, tuple) else (functions,):
                    body.append(calls.call(name, comp, phase, function))
        if phase == "valve" and axes != ("",):  # the supply serves every axis's valve
            for total in _SUPPLY_FLOWS:
                body.append(f"{total} = " + " + ".join(_local(a, total, True) for a in axes))
                calls.circuit.add(total)
    signals = [(name, comp, sig) for name, comp in instances for sig in comp.signals]
    signals += [(axis, None, _LOAD_SIGNAL) for axis in axes]
    signal_names = tuple(
        _named(axis_of.get(name, name) if comp else name, sig.name) for name, comp, sig in signals
    )
    if len(set(signal_names)) != len(signal_names):
        raise CompositionError(f"two components declare the same signal name: {signal_names}")
    writes = [
        f"out[{k}] = " + (calls.value(name, comp, sig.source) if comp else _local(name, sig.source))
        for k, (name, comp, sig) in enumerate(signals)
    ]
    stopping = [(name, comp) for name, comp in instances if comp.end_stop is not None]
    stop_lines = [line for name, comp in stopping for line in calls.records(name, comp)]
    stops = [calls.expression(name, comp, comp.end_stop) for name, comp in stopping]
    binding = _SOURCE.format(
        label=label,
        imports="\n".join(calls.imports),
        body=_indent(body),
        writes=_indent(writes),
        n=len(state_names),
        stop_records=_indent(stop_lines),
        stop=" or ".join(stops) or "False",
    ) + (jacobian_source(body, len(state_names)) or "")

    effects = tuple(
        name
        for name in LIBRARY
        if name in INPUT_EFFECTS or any(name in c.effects for _, c in instances)
    )
    units = {
        named: _resolve_unit(sig.unit, mechanics, input_unit)
        for named, (_, _, sig) in zip(signal_names, signals, strict=True)
    }
    initial_keys: dict[str, tuple[str, str]] = {}
    for name, comp in instances:
        for key, (kw, unit) in comp.initial_keys.items():
            axis = axis_of[name]
            si = _resolve_unit(unit, mechanics, input_unit)
            initial_keys[_named(axis, key)] = (_named(axis, kw), si)
            initial_keys.setdefault(key, (kw, si))  # on an axis: every axis's, unless its own
    scale = np.array([st.scale for _, _, st in declared])
    typical = np.array([st.typical for _, _, st in declared])
    model = PlantModel(
        type_name="composition",
        binding=binding,
        params_cls=params_cls,
        states=state_names,
        signals=signal_names,
        signal_units=units,
        input=(input_name, input_unit),
        load=next(iter(takers.values())).load if takers else actuator.load or ("f_load", "N"),
        initial_keys=initial_keys,
        initial_state=lambda params, **kw: _initial_state(
            model, instances, axis_of, axes, params, kw
        ),
        state_scale=lambda params: scale.copy(),
        typical_state=lambda params: typical.copy(),
        description=" + ".join(f"{n} ({c.type})" for n, c in instances),
        effects=effects,
        mechanics=mechanics,
        null_input=lambda params: _null(valve, instances, params),
        effect_scales=lambda params, rated, dt: _scales(instances, params, rated, dt),
        components=parts,
        bristles=bristles
        if any(st.group == "bristles" for _, c in instances for st in c.states)
        else None,
        # every pressure a component declares is a node pressure against the tank
        pressures=tuple(name for name in signal_names if units[name] == "Pa"),
        rebuild=compose,
        state_paths=tuple(f"{name}.{st.name}" for name, _, st in declared),
        state_units=tuple(_resolve_unit(st.unit, mechanics, input_unit) for _, _, st in declared),
    )
    return model


class _Calls:
    """The generated source that joins the instances' phase functions: each instance's
    records (``<instance>_P``, ``<instance>_X``), and each call with its arguments passed
    by name and its returns bound to the circuit's variables, to the state derivatives
    ``dx[i]`` or to the instance's own values ``<instance>_<name>``, every index the
    position the declarations give (components/declare.py)."""

    def __init__(
        self,
        param_index: Mapping[tuple[str, str], tuple[bool, int]],
        state_index: Mapping[tuple[str, str], int],
        axis_of: Mapping[str, str] | None = None,
    ) -> None:
        self.param_index, self.state_index = param_index, state_index
        self.axis_of = axis_of or {}
        self.imports: list[str] = ["from fuzzyservo.components.declare import record"]
        self.aliases: dict[int, str] = {}  # id(function or record) -> its name in the source
        self.circuit: set[str] = set()  # circuit variables set so far
        self.own: dict[str, set[str]] = {}  # instance -> the values it returned so far

    def _alias(self, thing: Any, statement: str) -> str:
        if id(thing) not in self.aliases:
            alias = f"_c{len(self.aliases)}"
            self.aliases[id(thing)] = alias
            self.imports.append(statement.format(alias=alias))
        return self.aliases[id(thing)]

    def _function(self, comp: Component, function: Any) -> str:
        py = function.py_func
        module = importlib.import_module(py.__module__)
        if getattr(module, py.__name__, None) is not function:
            raise CompositionError(
                f"component {comp.type!r}: {py.__qualname__} is not a module-level function "
                f"of {py.__module__}; define it at the module's top level"
            )
        return self._alias(function, f"from {py.__module__} import {py.__name__} as {{alias}}")

    def records(self, name: str, comp: Component) -> list[str]:
        """The statements that build the instance's ``P`` and ``X`` records."""
        lines = []
        if comp.params:
            cls = comp.values
            alias = self._alias(cls, f"{{alias}} = record({cls.__name__!r}, {cls._fields!r})")
            entries = []
            for prm in comp.params:
                vector, at = self.param_index[(name, prm.key)]
                entries.append(str(at) if vector else f"p[{at}]")
            lines.append(f"{name}_P = {alias}({', '.join(entries)})")
        if comp.states:
            cls = comp.state
            alias = self._alias(cls, f"{{alias}} = record({cls.__name__!r}, {cls._fields!r})")
            entries = [
                f"x[{self.state_index[(name, st.name)]}]"
                if (name, st.name) in self.state_index
                else "0.0"
                for st in comp.states
            ]
            lines.append(f"{name}_X = {alias}({', '.join(entries)})")
        return lines

    def _argument(self, name: str, comp: Component, arg: str, where: str) -> str:
        if arg in ("P", "X"):
            if not (comp.params if arg == "P" else comp.states):
                raise CompositionError(
                    f"component {comp.type!r}: {where} reads {arg} but declares no "
                    f"{'parameters' if arg == 'P' else 'states'}"
                )
            return f"{name}_{arg}"
        if arg in ("p", "u", "f_ext"):
            return arg
        if arg in self.own.get(name, ()):
            return f"{name}_{arg}"
        if self._circuit(name, comp, arg) in self.circuit:
            return self._circuit(name, comp, arg)
        raise CompositionError(
            f"component {comp.type!r}: {where} reads {arg!r}, which no earlier phase "
            "provides; return it from an earlier phase or fix the name"
        )

    def call(self, name: str, comp: Component, phase: str, function: Any) -> str:
        """One phase's call: ``<returns> = <function>(<arguments>)``."""
        where = f"its {phase} phase"
        args = [self._argument(name, comp, a, where) for a in arguments(function)]
        targets = []
        for ret in function.returns:
            state = ret[3:] if ret.startswith("dx_") else None
            if state is not None and (name, state) in self.state_index:
                targets.append(f"dx[{self.state_index[(name, state)]}]")
            elif state is not None:
                raise CompositionError(
                    f"component {comp.type!r}: {where} returns {ret!r} but declares no "
                    f"state {state!r} in this form"
                )
            elif ret in CIRCUIT:
                self.circuit.add(self._circuit(name, comp, ret))
                targets.append(self._circuit(name, comp, ret))
            else:
                self.own.setdefault(name, set()).add(ret)
                targets.append(f"{name}_{ret}")
        alias = self._function(comp, function)
        return f"{', '.join(targets)} = {alias}({', '.join(args)})"

    def value(self, name: str, comp: Component, source: str) -> str:
        """What a signal records: a value the instance returned, its state or parameter,
        or a circuit variable."""
        if source in self.own.get(name, ()):
            return f"{name}_{source}"
        if (name, source) in self.state_index:
            return f"x[{self.state_index[(name, source)]}]"
        vector, at = self.param_index.get((name, source), (True, None))
        if at is not None and not vector:
            return f"p[{at}]"
        if self._circuit(name, comp, source) in self.circuit:
            return self._circuit(name, comp, source)
        raise CompositionError(
            f"component {comp.type!r}: a signal records {source!r}, which it neither returns, "
            "declares nor reads from the circuit; fix the signal's source"
        )

    def _circuit(self, name: str, comp: Component, variable: str) -> str:
        """A circuit variable as this instance sees it: its axis's own (an actuator's
        motion, its ports, its valve's flows) or the one every axis shares."""
        return _local(self.axis_of.get(name, ""), variable, comp.role == "valve")

    def expression(self, name: str, comp: Component, function: Any) -> str:
        """A call of a function of the instance's records (``end_stop``)."""
        args = [self._argument(name, comp, a, "its end_stop") for a in arguments(function)]
        return f"{self._function(comp, function)}({', '.join(args)})"


# roles every axis has its own of (valve, lines, actuator, loads); the others serve all
_SHARED_ROLES = ("fluid", "supply", "accumulator")
# circuit variables every axis shares: the fluid's, the supply's pressures and its flows
_SHARED = ("beta", "p_lam", "mass_form", "p_s", "p_t", "q_supply", "q_tank")
# an axis without lines: its valve's ports see the chambers, its chambers the valve's flows
_WITHOUT_LINES = {
    "line": (("p_a_port", "p_a"), ("p_b_port", "p_b")),
    "line_flow": (("q_a", "q_va"), ("q_b", "q_vb")),
}
# what each axis's valve draws from the supply and returns, summed for the supply
_SUPPLY_FLOWS = ("q_supply", "q_tank")


def _local(axis: str, variable: str, valve: bool = False) -> str:
    """A circuit variable's name in the generated source: an axis's own carries the
    axis (``pos__lift_left``); a shared one, or any in a one-axis circuit, is bare."""
    own = variable not in _SHARED or (valve and variable in _SUPPLY_FLOWS)
    return f"{variable}__{axis}" if axis and own else variable


def _named(axis: str, name: str) -> str:
    """A state, signal or initial key as the rig names it: ``<axis>_<name>`` on an axis."""
    return f"{axis}_{name}" if axis else name


def _axes(
    instances: list[tuple[str, Component]], axis_of: dict[str, str], types: dict[str, Component]
) -> tuple[str, ...]:
    """The circuit's axes in file order (``("",)``: one, unnamed), each checked to hold
    exactly one valve and one actuator, at most one pair of lines, loads meaningful on
    its actuator and at most one load taking the scenario's input."""
    named = [n for n, c in instances if c.role not in _SHARED_ROLES]
    for name, comp in instances:
        if comp.role in _SHARED_ROLES and axis_of[name]:
            raise CompositionError(
                f"{name}: a {comp.role} serves every axis; remove its axis ({axis_of[name]!r})"
            )
    axes = tuple(dict.fromkeys(axis_of[n] for n in named)) or ("",)
    if len(axes) > 1 and "" in axes:
        bare = next(n for n in named if not axis_of[n])
        raise CompositionError(
            f"{bare}: give every valve, line, actuator and load an axis, or none; "
            f"the others are on {[a for a in axes if a]}"
        )
    for axis in axes:
        if axis and not axis.isidentifier():
            raise CompositionError(f"axis {axis!r}: must be a Python identifier (letters, _)")
        on_axis = [(n, c) for n, c in instances if axis_of[n] == axis or c.role in _SHARED_ROLES]
        where = f" on axis {axis!r}" if axis else ""
        for role, (lo, hi) in ROLES.items():
            count = sum(1 for _, c in on_axis if c.role == role)
            if not lo <= count <= hi:
                which = sorted(t for t, c in types.items() if c.role == role)
                need = f"exactly {lo}" if lo == hi else f"{lo} to {hi}"
                raise CompositionError(
                    f"a composition needs {need} {role} component(s){where}, got {count}; "
                    f"add or remove one of {which}"
                )
        actuator = next(c for _, c in on_axis if c.role == "actuator")
        for name, comp in on_axis:
            if comp.actuators and actuator.type not in comp.actuators:
                raise CompositionError(
                    f"{name}: a {comp.type} load is not meaningful on a {actuator.type}; "
                    f"it applies to {list(comp.actuators)}"
                )
        takers = [c for _, c in on_axis if c.role == "load" and c.load]
        if len(takers) > 1:
            raise CompositionError(
                f"{len(takers)} loads take the scenario's load input{where} "
                f"({', '.join(c.type for c in takers)}); keep one of them"
            )
    actuators = {c.type for _, c in instances if c.role == "actuator"}
    if len({str(types[t].mechanics) for t in actuators}) > 1:
        raise CompositionError(
            f"the axes' actuators {sorted(actuators)} move in different units; "
            "compose cylinders with cylinders or motors with motors"
        )
    inputs = {c.input for _, c in instances if c.role == "valve"}
    if len(inputs) > 1:
        raise CompositionError(
            f"the axes' valves take different inputs {sorted(map(str, inputs))}; the loop "
            "drives every valve with one command: compose valves of one input"
        )
    return axes


def _composed_params(parts: tuple[tuple[str, str], ...], values: dict[str, float]) -> Any:
    """The parameters ``values`` of the composition ``parts`` (how they unpickle)."""
    return compose(parts).params_cls(**values)


def _stroke(instances: list[tuple[str, Component]]) -> dict[str, Any]:
    """``stroke_limits_m`` (where the end stops engage, in the rig's y) for a cylinder."""
    name = next((n for n, c in instances if c.role == "actuator" and c.end_stop), None)
    if name is None:
        return {}

    def stroke_limits_m(self: Any) -> tuple[float, float]:
        zero = getattr(self, f"{name}__zero_position")
        return (-zero, getattr(self, f"{name}__stroke") - zero)

    return {"stroke_limits_m": property(stroke_limits_m)}


def instance_values(params: Any, name: str, comp: Component) -> dict[str, float]:
    """One instance's scalar parameter values by key (SI)."""
    return {p.key: float(getattr(params, f"{name}__{p.key}")) for p in comp.params if not p.length}


def _make_post_init(instances: list[tuple[str, Component]]):
    def __post_init__(self: Any) -> None:
        for name, comp in instances:
            if comp.check is None:
                continue
            problem = comp.check(instance_values(self, name, comp))
            if problem:
                key, _, rest = problem.partition(": ")
                raise ValueError(f"{name}.{key}: {rest}")

    return __post_init__


def _initial_state(
    model: Any,
    instances: list[tuple[str, Component]],
    axis_of: dict[str, str],
    axes: tuple[str, ...],
    params: Any,
    given: dict[str, float],
) -> np.ndarray:
    """States at rest: each component's ``initial`` in phase order, sharing the circuit
    values (``p_s``, ``p_t``, ...) with the shared components and those of its own axis;
    then, unless the chamber pressures are given, once more with each axis's static load
    force at that state so that every piston starts in balance."""

    def once(static_force: dict[str, float]) -> np.ndarray:
        shared: dict[str, float] = dict(given)
        own: dict[str, dict[str, float]] = {a: {} for a in axes if a}
        values: dict[str, float] = {}
        order = sorted(
            instances, key=lambda item: min((PHASES.index(ph) for ph in item[1].code), default=0)
        )
        for name, comp in order:
            if comp.initial is None:
                continue
            axis = axis_of[name]
            prefix = f"{axis}_"
            ctx = {**shared, _STATIC_FORCE: static_force.get(axis, 0.0)}
            if axis:
                ctx.update({k[len(prefix) :]: v for k, v in given.items() if k.startswith(prefix)})
                ctx.update(own[axis])
            out = comp.initial(instance_values(params, name, comp), ctx)
            (own[axis] if axis else shared).update(out)
            for key, value in out.items():
                if _named(axis, key) in model.states:
                    values[_named(axis, key)] = value
        return np.array([values.get(s, 0.0) for s in model.states], dtype=np.float64)

    x0 = once({})
    out = np.empty(len(model.signals))
    with compile_step(f"the plant's kernels ({model.description}; {len(model.states)} states)"):
        native = native_kernels(model)
        signals = model.kernels.plant_signals if native is None else native.signals
        signals(x0, model.null_input(params), 0.0, pack(params), out)
    forces = {a: float(out[model.signals.index(_named(a, _LOAD_SIGNAL.name))]) for a in axes}
    if all(np.isfinite(f) and f == 0.0 for f in forces.values()):
        return x0
    return once({a: f for a, f in forces.items() if np.isfinite(f)})


def _null(valve: Component, instances: list[tuple[str, Component]], params: Any) -> float:
    if valve.null is None:
        return 0.0
    name = next(n for n, c in instances if c is valve)
    return float(valve.null(instance_values(params, name, valve)))


def _scales(
    instances: list[tuple[str, Component]], params: Any, rated: float, sample_time_s: float
) -> Scales:
    """Sizes effect bounds scale with: stall force p·A, the valve's flow, its speed."""
    merged: dict[str, float] = {}
    for name, comp in instances:
        if comp.scales is not None:
            merged.update(comp.scales(instance_values(params, name, comp)))
    pressure = merged.get("pressure", float("nan"))
    area = merged.get("area", float("nan"))
    flow = merged.get("flow", merged.get("flow_coefficient", float("nan")) * pressure**0.5)
    velocity = flow / area
    return Scales(
        force=pressure * area,
        velocity=velocity,
        flow=flow,
        pressure=pressure,
        input=rated,
        bulk_modulus=merged.get("bulk_modulus", float("nan")),
        sample_time=sample_time_s,
        smoothing_velocity=5e-3 * velocity,
    )


def _indent(lines: list[str]) -> str:
    return "\n".join("    " + line if line else "" for line in lines)


# the signal every composition records: what the loads push back with (incl. f_ext)
from fuzzyservo.components.declare import Signal as _Signal  # noqa: E402

_LOAD_SIGNAL = _Signal("f_loads", "force", "f_load", "every load's force opposing +pos")

_SOURCE = """
# generated by fuzzyservo.plants.composed for: {label}
import math

import numpy as np

from fuzzyservo._jit import njit
{imports}


@njit(cache=True, inline="always")
def plant_rhs(x, u, f_ext, p, dx):
{body}


@njit(cache=True)
def plant_signals(x, u, f_ext, p, out):
    dx = np.empty({n})
{body}
{writes}


@njit(cache=True)
def plant_in_end_stop(x, p):
{stop_records}
    return {stop}
"""
