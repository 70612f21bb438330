"""How a component is declared: once, with its parameters, states, signals and code.

A rig file composes a plant from components (``plant.components``), as Hopsan and
Simscape Fluids build a circuit. Each component type is one module under
``components/library/`` that defines ``COMPONENTS``, a tuple of :class:`Component`;
:func:`registry` finds them, so a new component is that one file plus its test.

A component's compiled code is a few lines of Python (``code``, by phase) written
against the circuit's shared variables (the names :data:`PHASES` defines) and five
prefixes that the composer (:mod:`fuzzyservo.plants.composed`) resolves on the code's
syntax tree, to positions derived from the declarations:

``P.key``    the component's parameter ``key`` (an entry of the packed vector)
``X.name``   its state ``name``;  ``DX.name = ...`` sets that state's derivative
``L.name``   a variable local to this instance (prefixed with the instance name)
``E.field``  an effect parameter (a field of :data:`~fuzzyservo.components.effects.E`)

Signals are expressions in the same vocabulary, written to the signal table by name,
so no table has to agree with another by position.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from functools import cache

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
    """One recorded signal: name (unique in a composition), unit, and the expression."""

    name: str
    unit: str
    expr: str
    doc: str = ""


@dataclass(frozen=True)
class Component:
    """A component type: everything the composer, the rig reader and the docs need.

    ``initial``: SI state values at rest from the parameter values (by key) and the
    circuit so far (``p_s``, ``p_t``, the rig's initial keys); ``scales``: what this
    component tells about the rig's size (``pressure``, ``flow``, ``area``, ``input``
    ...); ``null``: the valve input of hydraulic null; ``effects``: the effects of
    components/effects.py its code reads; ``initial_keys``: rig-file initial keys ->
    (circuit name, SI unit); ``end_stop``: an expression true beyond a mechanical stop;
    ``check``: a problem with the values as ``"key: what is wrong; the fix"``, or None.
    ``bristle_code``: the phases whose code differs in a composition that carries the
    ``bristles`` states (LuGre friction), in place of ``code``'s.
    """

    type: str
    role: str
    doc: str
    source: str
    params: tuple[Param, ...] = ()
    states: tuple[State, ...] = ()
    signals: tuple[Signal, ...] = ()
    code: Mapping[str, str] = field(default_factory=dict)
    bristle_code: Mapping[str, str] = field(default_factory=dict)
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
    end_stop: str = ""
    check: Callable[[dict[str, float]], str | None] | None = None
    actuators: tuple[str, ...] = ()  # loads: the actuator types it applies to (empty: any)
    refuses: Mapping[str, str] = field(default_factory=dict)  # effect -> why not meaningful

    def __post_init__(self) -> None:
        if self.role not in ROLES:
            raise ValueError(f"component {self.type!r}: role {self.role!r} not in {list(ROLES)}")
        for phase in (*self.code, *self.bristle_code):
            if phase not in PHASES:
                raise ValueError(f"component {self.type!r}: phase {phase!r} not in {PHASES}")
        for state in self.states:
            if state.group not in STATE_GROUPS:
                raise ValueError(
                    f"component {self.type!r}: state group {state.group!r} not in {STATE_GROUPS}"
                )
        keys = [p.key for p in self.params]
        if len(set(keys)) != len(keys):
            raise ValueError(f"component {self.type!r}: a parameter key is declared twice")

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
