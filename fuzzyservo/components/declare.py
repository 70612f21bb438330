"""How a component is declared: once, with its parameters, states, signals and code.

A rig file composes a plant from components (``plant.components``), as Hopsan and
Simscape Fluids build a circuit. Each component type is one module under
``components/library/`` that defines ``COMPONENTS``, a tuple of :class:`Component`;
:func:`registry` finds them, so a new component is that one file plus its test.

A component's equations are ordinary functions, one per phase of the circuit
(:data:`PHASES`), compiled by numba and decorated with :func:`phase`, which names what
they return. The composer (:mod:`fuzzyservo.plants.composed`) joins them: it passes each
argument by its name and generates only the sequence of calls.

``P``        the instance's parameters, a record with one field per declared key
             (a vector parameter's field is its start in ``p``)
``X``        its states, a record with one field per declared state
``p``        the whole parameter vector (effect parameters are ``p[E.<field>]``,
             :data:`~fuzzyservo.components.effects.E`; the shared maps read it)
``u``, ``f_ext``  the plant's input and the scenario's load
a circuit variable (:data:`CIRCUIT`): what one instance hands the next through the
             ports it shares with them (the valve's port pressures, the flows into the
             actuator, the moving mass ...)
any other name: what this instance returned in an earlier phase

A returned name is a circuit variable, ``dx_<state>`` (that state's derivative) or a
value of this instance (a signal may record it). A signal names the value it records;
``end_stop`` is a function of ``P`` and ``X``, true beyond a mechanical stop. Every
function runs alone too: ``comp.values(...)`` and ``comp.state(...)`` build its records.
"""

from __future__ import annotations

import importlib
import inspect
import pkgutil
from collections import namedtuple
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from functools import cache
from typing import Any

from fuzzyservo._jit import njit

# Phases in the order the composed right-hand side runs them, and what each defines.
PHASES = (
    "fluid",  # beta (effective bulk modulus) [Pa], p_lam (orifice regularisation) [Pa], mass_form
    "supply",  # p_s, p_t: pressures at the valve's P and T ports [Pa]
    "actuator",  # pos, vel; p_a, p_b [Pa]; area_a, area_b [m² or m³/rad]; f_stop
    "line",  # p_a_port, p_b_port: the pressures the valve's A and B ports see [Pa]
    "valve",  # q_va, q_vb out of ports A, B; q_supply from P, q_tank into T [m³/s]
    "line_flow",  # q_a, q_b: the flows reaching the actuator's chambers [m³/s]
    "mass",  # mass += moving mass [kg or kg·m²]
    "load",  # f_load += force opposing +pos [N or N·m]
    "motion",  # the actuator's derivatives
    "node",  # other consumers at the supply node (an accumulator): q_supply += their intake
    "supply_flow",  # the supply's derivatives (it sees q_supply, q_tank)
)

# The circuit's variables: what the phases above hand each other, by name (SI).
CIRCUIT = (
    "beta", "p_lam", "mass_form",  # fluid
    "p_s", "p_t",  # supply
    "pos", "vel", "p_a", "p_b", "area_a", "area_b", "f_stop",  # actuator
    "p_a_port", "p_b_port",  # line
    "q_va", "q_vb", "q_supply", "q_tank",  # valve
    "q_a", "q_b",  # line_flow
    "mass", "f_load",  # mass, load
)  # fmt: skip

# Roles: how many of each a composition holds, and the phases they may write.
ROLES: dict[str, tuple[int, int]] = {
    "fluid": (1, 1),
    "supply": (1, 1),
    "valve": (1, 1),
    "line": (0, 1),
    "actuator": (1, 1),
    "load": (0, 99),
    "accumulator": (0, 1),
}

# State groups, in the order the composed state vector lists them (the seed plants'
# order: motion first, then the supply side, the chambers, lines, the valve's spool).
# ``bristles`` (LuGre friction's bristle deflection) comes last and only in a composition
# that carries it (compose's ``bristles``: a friction effect with a pre-sliding distance);
# without it every other state keeps its place and no run pays for a state held at 0.
STATE_GROUPS = ("motion", "supply", "chamber", "line", "valve", "bristles")


@dataclass(frozen=True)
class Param:
    """One parameter: the key in the rig file, its SI unit, what it is, its bounds.

    ``unit`` may be a token the composition resolves: ``force``/``velocity``/``position``
    (N or N·m, m/s or rad/s, m or rad) or ``input`` (the valve's input unit).
    ``length`` > 0 makes it a vector of that many floats, read from a file of format
    ``fmt`` (e.g. a valve network's weights); code reads ``P.key`` as its start in ``p``.
    """

    key: str
    unit: str
    doc: str
    default: float | None = None
    positive: bool = False
    nonnegative: bool = False
    minimum: float | None = None
    maximum: float | None = None
    length: int = 0
    fmt: str = ""


@dataclass(frozen=True)
class State:
    """One state: name (unique in a composition), unit, group, and its sizes: ``scale``
    is one unit of local error, ``typical`` its finite-difference magnitude (SI)."""

    name: str
    unit: str
    doc: str
    group: str
    scale: float
    typical: float


@dataclass(frozen=True)
class Signal:
    """One recorded signal: name (unique in a composition), unit, and the value it
    records: a circuit variable, or the instance's state, parameter or returned value."""

    name: str
    unit: str
    source: str
    doc: str = ""


def phase(*returns: str) -> Callable[[Callable[..., Any]], Any]:
    """A phase function, compiled by numba, returning the values ``returns`` names in
    that order (one name: the value itself; several: a tuple)."""

    def compiled(function: Callable[..., Any]) -> Any:
        dispatcher = njit(cache=True)(function)
        dispatcher.returns = returns
        return dispatcher

    return compiled


def arguments(function: Any) -> tuple[str, ...]:
    """The names a phase function (or ``end_stop``) takes, in order."""
    return tuple(inspect.signature(function.py_func).parameters)


@cache
def record(name: str, fields: tuple[str, ...]) -> type:
    """The record (a named tuple, which numba compiles to plain values) with ``fields``."""
    return namedtuple(name, fields)


@dataclass(frozen=True)
class Component:
    """A component type: everything the composer, the rig reader and the docs need.

    ``code``: phase -> function (:func:`phase`), or a tuple of them run in order;
    ``bristle_code``: the phases whose
    function differs in a composition that carries the ``bristles`` states (LuGre
    friction). ``initial``: SI state values at rest from the parameter values (by key) and the
    circuit so far (``p_s``, ``p_t``, the rig's initial keys); ``scales``: what this
    component tells about the rig's size (``pressure``, ``flow``, ``area``, ``input``
    ...); ``null``: the valve input of hydraulic null; ``effects``: the effects of
    components/effects.py its code reads; ``initial_keys``: rig-file initial keys ->
    (circuit name, SI unit); ``end_stop``: a function of ``P``, ``X`` true beyond a
    mechanical stop; ``check``: a problem with the values as ``"key: what is wrong; the
    fix"``, or None.
    """

    type: str
    role: str
    doc: str
    source: str
    params: tuple[Param, ...] = ()
    states: tuple[State, ...] = ()
    signals: tuple[Signal, ...] = ()
    code: Mapping[str, Any] = field(default_factory=dict)
    bristle_code: Mapping[str, Any] = field(default_factory=dict)
    effects: tuple[str, ...] = ()
    initial: Callable[[dict[str, float], dict[str, float]], dict[str, float]] | None = None
    initial_keys: Mapping[str, tuple[str, str]] = field(default_factory=dict)
    scales: Callable[[dict[str, float]], dict[str, float]] | None = None
    null: Callable[[dict[str, float]], float] | None = None
    input: tuple[str, str] | None = None  # valves: the plant input (name, unit)
    # actuators: the scenario load (name, unit), a force on the actuator; a load component
    # may take that input instead (read as ``f_ext`` by its code)
    load: tuple[str, str] | None = None
    mechanics: Mapping[str, str] | None = None  # actuators: SI units of force, velocity
    end_stop: Any = None
    check: Callable[[dict[str, float]], str | None] | None = None
    actuators: tuple[str, ...] = ()  # loads: the actuator types it applies to (empty: any)
    refuses: Mapping[str, str] = field(default_factory=dict)  # effect -> why not meaningful

    def __post_init__(self) -> None:
        if self.role not in ROLES:
            raise ValueError(f"component {self.type!r}: role {self.role!r} not in {list(ROLES)}")
        for name, functions in (*self.code.items(), *self.bristle_code.items()):
            if name not in PHASES:
                raise ValueError(f"component {self.type!r}: phase {name!r} not in {PHASES}")
            for function in functions if isinstance(functions, tuple) else (functions,):
                if not hasattr(function, "returns"):
                    raise ValueError(
                        f"component {self.type!r}: phase {name!r} is not a @phase function"
                    )
        for state in self.states:
            if state.group not in STATE_GROUPS:
                raise ValueError(
                    f"component {self.type!r}: state group {state.group!r} not in {STATE_GROUPS}"
                )
        keys = [p.key for p in self.params]
        if len(set(keys)) != len(keys):
            raise ValueError(f"component {self.type!r}: a parameter key is declared twice")

    @property
    def values(self) -> type:
        """The record of this component's parameters (``P`` in its phase functions)."""
        return record(f"{self.type}_params", tuple(p.key for p in self.params))

    @property
    def state(self) -> type:
        """The record of this component's states (``X`` in its phase functions)."""
        return record(f"{self.type}_states", tuple(s.name for s in self.states))

    def param(self, key: str) -> Param:
        for p in self.params:
            if p.key == key:
                return p
        raise KeyError(key)


@cache
def registry() -> dict[str, Component]:
    """Every component type, by name: the ``COMPONENTS`` of each ``components/library`` module."""
    from fuzzyservo.components import library

    found: dict[str, Component] = {}
    for info in sorted(pkgutil.iter_modules(library.__path__), key=lambda m: m.name):
        module = importlib.import_module(f"{library.__name__}.{info.name}")
        for component in getattr(module, "COMPONENTS", ()):
            if component.type in found:
                raise ValueError(f"component type {component.type!r} is declared twice")
            found[component.type] = component
    return found
