"""A plant composed from components (``plant.components`` in a rig file).

:func:`compose` turns instances of component types (:mod:`fuzzyservo.components.declare`)
into a :class:`~fuzzyservo.plants.PlantModel`: a frozen parameter class whose fields
are the instances' parameters (file key ``<instance>.<key>``), the state vector laid
out by state group, and the Python source of one flat right-hand side, which the
closed loop is compiled against (:func:`fuzzyservo._jit.bind_plant`). Every index in
that source is generated from the declarations; none is written by hand.

The circuit has one fluid, one supply, one 4-way valve, at most one pair of lines,
one actuator and any number of loads; the phases of :data:`~fuzzyservo.components.declare.PHASES`
run in order, each instance's code in the order the rig file lists them.
"""

from __future__ import annotations

import ast
import dataclasses
import re
from collections.abc import Mapping
from functools import cache
from typing import Any

import numpy as np

from fuzzyservo.components.declare import (
    PHASES,
    ROLES,
    STATE_GROUPS,
    Component,
    registry,
)
from fuzzyservo.components.effects import INPUT_EFFECTS, LIBRARY, E, EffectParams, Scales
from fuzzyservo.params import index_of, pack, quantity, vector, vector_offset
from fuzzyservo.plants import PlantModel
from fuzzyservo.plants._jacobian import jacobian_source

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


def compose(parts: tuple[tuple[str, str], ...], bristles: bool = False) -> PlantModel:
    """The plant of the instances ``parts`` = ((instance name, component type), ...).

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
def _compose(parts: tuple[tuple[str, str], ...], bristles: bool) -> PlantModel:
    types = registry()
    instances: list[tuple[str, Component]] = []
    for name, type_name in parts:
        if not name.isidentifier():
            raise CompositionError(
                f"{name}: an instance name must be a Python identifier (letters, digits, _)"
            )
        if type_name not in types:
            raise CompositionError(
                f"{name}: unknown component type {type_name!r}; choose one of {sorted(types)}"
            )
        instances.append((name, types[type_name]))
    for role, (lo, hi) in ROLES.items():
        count = sum(1 for _, c in instances if c.role == role)
        if not lo <= count <= hi:
            which = sorted(t for t, c in types.items() if c.role == role)
            need = f"exactly {lo}" if lo == hi else f"{lo} to {hi}"
            raise CompositionError(
                f"a composition needs {need} {role} component(s), got {count}; "
                f"add or remove one of {which}"
            )
    valve = next(c for _, c in instances if c.role == "valve")
    actuator = next(c for _, c in instances if c.role == "actuator")
    for name, comp in instances:
        if comp.actuators and actuator.type not in comp.actuators:
            raise CompositionError(
                f"{name}: a {comp.type} load is not meaningful on a {actuator.type}; "
                f"it applies to {list(comp.actuators)}"
            )
    mechanics = dict(actuator.mechanics or {"force": "N", "velocity": "m/s", "position": "m"})
    # the scenario's load input: the actuator's force, unless a load component takes it
    takers = [c for _, c in instances if c.role == "load" and c.load]
    if len(takers) > 1:
        raise CompositionError(
            f"{len(takers)} loads take the scenario's load input "
            f"({', '.join(c.type for c in takers)}); keep one of them"
        )
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
    label = "_".join(t for _, t in parts)
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
    state_names = tuple(st.name for _, _, st in declared)
    if len(set(state_names)) != len(state_names):
        raise CompositionError(f"two components declare the same state name: {state_names}")

    def subst(name: str, comp: Component, text: str) -> str:
        return _Vocabulary(name, comp, param_index, state_index).resolve(text)

    # the body: phases in order, instances in file order; defaults where a role is absent
    body: list[str] = ["mass = 0.0", "f_load = 0.0" if takers else "f_load = f_ext"]
    has_line = any(c.role == "line" for _, c in instances)
    for phase in PHASES:
        if phase == "line" and not has_line:
            body += ["p_a_port = p_a", "p_b_port = p_b"]
        if phase == "line_flow" and not has_line:
            body += ["q_a = q_va", "q_b = q_vb"]
        for name, comp in instances:
            code = (bristles and comp.bristle_code.get(phase)) or comp.code.get(phase)
            if code:
                body.append(f"# {name} ({comp.type}): {phase}")
                body += [line for line in subst(name, comp, _dedent(code)).splitlines()]
    signals = [(name, comp, sig) for name, comp in instances for sig in comp.signals]
    signals.append(("", None, _LOAD_SIGNAL))
    signal_names = tuple(sig.name for _, _, sig in signals)
    if len(set(signal_names)) != len(signal_names):
        raise CompositionError(f"two components declare the same signal name: {signal_names}")
    writes = [
        f"out[{k}] = {subst(name, comp, sig.expr) if comp else sig.expr}"
        for k, (name, comp, sig) in enumerate(signals)
    ]
    stops = [f"({subst(name, comp, comp.end_stop)})" for name, comp in instances if comp.end_stop]
    binding = _SOURCE.format(
        label=label,
        body=_indent(body),
        writes=_indent(writes),
        n=len(state_names),
        stop=" or ".join(stops) or "False",
    ) + (jacobian_source(body, len(state_names)) or "")

    effects = tuple(
        name
        for name in LIBRARY
        if name in INPUT_EFFECTS or any(name in c.effects for _, c in instances)
    )
    units = {sig.name: _resolve_unit(sig.unit, mechanics, input_unit) for _, _, sig in signals}
    initial_keys: dict[str, tuple[str, str]] = {}
    for _, comp in instances:
        for key, (kw, unit) in comp.initial_keys.items():
            initial_keys[key] = (kw, _resolve_unit(unit, mechanics, input_unit))
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
        load=takers[0].load if takers else actuator.load or ("f_load", "N"),
        initial_keys=initial_keys,
        initial_state=lambda params, **kw: _initial_state(model, instances, params, kw),
        state_scale=lambda params: scale.copy(),
        typical_state=lambda params: typical.copy(),
        description=" + ".join(f"{n} ({c.type})" for n, c in instances),
        effects=effects,
        mechanics=mechanics,
        null_input=lambda params: _null(valve, instances, params),
        effect_scales=lambda params, rated, dt: _scales(instances, params, rated, dt),
        components=tuple((n, c.type) for n, c in instances),
        bristles=bristles
        if any(st.group == "bristles" for _, c in instances for st in c.states)
        else None,
        # every pressure a component declares is a node pressure against the tank
        pressures=tuple(name for name in signal_names if units[name] == "Pa"),
        rebuild=compose,
    )
    return model


class _Vocabulary(ast.NodeTransformer):
    """One instance's code with its vocabulary resolved (components/declare.py): the
    attribute ``P.key`` becomes ``p[i]`` (a vector parameter: its start ``i`` in p), ``X.name``/``DX.name`` become ``x[i]``/``dx[i]``,
    ``E.field`` the effect's ``p[i]`` and ``L.name`` the local ``<instance>_name``, with
    every ``i`` the position the declarations give. The code is parsed, rewritten as a
    syntax tree and printed back, so only names in the code (not in its strings or
    comments) change, and a name the component did not declare is an error."""

    def __init__(
        self,
        name: str,
        comp: Component,
        param_index: Mapping[tuple[str, str], tuple[bool, int]],
        state_index: Mapping[tuple[str, str], int],
    ) -> None:
        self.name, self.comp = name, comp
        self.param_index, self.state_index = param_index, state_index

    def resolve(self, code: str) -> str:
        try:
            tree = ast.parse(code)
        except SyntaxError as exc:
            raise CompositionError(
                f"component {self.comp.type!r}: its code does not parse ({exc.msg}, line "
                f"{exc.lineno}); fix the component's code"
            ) from None
        return ast.unparse(ast.fix_missing_locations(self.visit(tree)))

    def visit_Attribute(self, node: ast.Attribute) -> ast.AST:
        if not (isinstance(node.value, ast.Name) and node.value.id in _VOCABULARY):
            return self.generic_visit(node)
        prefix, ident = node.value.id, node.attr
        if prefix == "L":
            return ast.copy_location(ast.Name(f"{self.name}_{ident}", node.ctx), node)
        if prefix == "P" and self.param_index.get((self.name, ident), (False, 0))[0]:
            # a vector parameter: its start in p (the code passes p and it on)
            offset = self.param_index[(self.name, ident)][1]
            return ast.copy_location(ast.Constant(offset), node)
        vector, at = self._position(prefix, ident)
        index = ast.Subscript(ast.Name(vector, ast.Load()), ast.Constant(at), node.ctx)
        return ast.copy_location(index, node)

    def _position(self, prefix: str, ident: str) -> tuple[str, int]:
        what = {"E": "effect parameter", "P": "parameter"}.get(prefix, "state")
        fix = "use a field of EffectParams" if prefix == "E" else "declare it or fix the name"
        if prefix == "E":
            at = getattr(E, ident) if ident in E._fields else None
        elif prefix == "P":
            at = self.param_index.get((self.name, ident), (False, None))[1]
        else:
            at = self.state_index.get((self.name, ident))
        if at is None:
            raise CompositionError(
                f"component {self.comp.type!r}: code uses undeclared {what} {ident!r}; {fix}"
            )
        return {"E": "p", "P": "p", "X": "x", "DX": "dx"}[prefix], at


# the prefixes of a component's code (components/declare.py)
_VOCABULARY = ("P", "X", "DX", "L", "E")


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
    model: Any, instances: list[tuple[str, Component]], params: Any, given: dict[str, float]
) -> np.ndarray:
    """States at rest: each component's ``initial`` in phase order, sharing the circuit
    values (``p_s``, ``p_t``, ...); then, unless the chamber pressures are given, once more
    with the load's static force at that state so that the piston starts in balance."""

    def once(static_force: float) -> np.ndarray:
        ctx: dict[str, float] = {**given, _STATIC_FORCE: static_force}
        values: dict[str, float] = {}
        order = sorted(
            instances, key=lambda item: min((PHASES.index(ph) for ph in item[1].code), default=0)
        )
        for name, comp in order:
            if comp.initial is None:
                continue
            out = comp.initial(instance_values(params, name, comp), ctx)
            ctx.update(out)
            values.update({k: v for k, v in out.items() if k in model.states})
        return np.array([values.get(s, 0.0) for s in model.states], dtype=np.float64)

    x0 = once(0.0)
    out = np.empty(len(model.signals))
    model.loop.plant_signals(x0, model.null_input(params), 0.0, pack(params), out)
    force = float(out[model.signals.index(_LOAD_SIGNAL.name)])
    return once(force) if np.isfinite(force) and force != 0.0 else x0


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


def _dedent(code: str) -> str:
    import textwrap

    return textwrap.dedent(code).strip("\n")


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
from fuzzyservo.components.kernels import *  # noqa: F403  (the components' shared maps)


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
    return {stop}
"""
