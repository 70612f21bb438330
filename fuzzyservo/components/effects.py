"""The effect library: physical effects a model may lack, declarable in any rig file, off by default.

Each effect is declared once, as an entry of :data:`LIBRARY`: its parameters with their
file keys, fields, units, docs and calibration bounds. The rest is made from it:
:class:`EffectParams`, the fields every plant's parameter set inherits, so the effects
travel in the packed parameter vector at the same positions for every plant, and
:data:`E`, those positions by field name (``p[E.valve_lag_s]``). A zero value switches
an effect off. Two stages:

* **input effects**, applied by the simulation loop between the actuator and the plant
  input for every plant: ``transport_delay`` → ``valve_bias`` → ``valve_lag`` →
  ``valve_deadband`` (the order of the physical chain: the command travels, the torque
  motor adds its null offset, the spool follows with its lag, the spool overlap hides
  small openings);
* **plant effects**, evaluated inside the plant kernels that list them in their
  ``EFFECTS`` (seed-002 cylinder and seed-000 motor): friction, line resistance,
  internal leakage, effective bulk modulus, entrained air, supply droop.

Formulations (SI units; "force" is N for a cylinder and N·m for a motor, "velocity"
m/s or rad/s, "input" the plant input unit, A or V). Sources: docs/modelling.md tables
"what the residual tells you" and "typical ranges"; seed 002 §5 (dry friction and
line resistance neglected), seed 003 §2 (leakage), seed 000 Table 2.

==================  =========================================================  ==============
effect              formulation                                                parameters
==================  =========================================================  ==============
coulomb_friction    F = Fc·tanh(v/vc); with a pre-sliding distance d > 0 the     Fc, d; vc fixed
                    LuGre law, which sticks (:func:`actuator_friction`)
stribeck_friction   F = (Fc + Fst·exp(−(v/vs)²))·tanh(v/vc); LuGre with d > 0    Fc, Fst, vs, d
line_resistance     laminar line Δp = R·q between each valve port and chamber  R [Pa·s/m³]
internal_leakage    q = Kl·(pA − pB) across piston or motor                    Kl [m³/(s·Pa)]
valve_deadband      i_eff = i0 + sign(Δi)·max(|Δi| − w, 0), Δi = i − i0       w [input]
valve_bias          i_eff = i + b (null bias beyond the declared one)          b [input]
valve_lag           τ1·τ2·s̈ + τ1·ṡ + s = i (spool; τ2 = 0: first order)      τ1, τ2 [s]
transport_delay     i_eff(t) = i(t − d)                                        d [s]
bulk_modulus        E_eff replaces the oil's E (air, hoses)                    E_eff [Pa]
supply_droop        q_supply = min(q_demand, Qp): pump flow limit with relief   Qp [m³/s]
external_leakage    q = Ke·p out of each chamber to the drain (seals, case)    Ke [m³/(s·Pa)]
entrained_air       E_mix(p) with free air, floor at the vapour pressure       α; n, p_v fixed
==================  =========================================================  ==============
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any, NamedTuple

from fuzzyservo._jit import njit
from fuzzyservo.components.air import ATMOSPHERE_PA, mixture_modulus
from fuzzyservo.components.orifice import signed_sqrt_flow
from fuzzyservo.params import index_of, quantity
from fuzzyservo.units import parse_unit

# unit tokens an effect parameter may use; the plant resolves them (force N or N·m, ...)
UNIT_TOKENS = ("force", "velocity", "position", "input")


# --------------------------------------------------------------------------- library


@dataclass(frozen=True)
class Scales:
    """Size of a rig, from which effect bounds follow: stall force [N or N·m], no-load
    velocity [m/s or rad/s], rated flow [m³/s], supply-to-return pressure [Pa], rated
    input [A or V], the declared bulk modulus [Pa], the controller's period [s], and
    the velocity over which friction's sign(v) is smoothed (tanh) on this plant."""

    force: float
    velocity: float
    flow: float
    pressure: float
    input: float
    bulk_modulus: float
    sample_time: float
    smoothing_velocity: float = float("nan")  # tanh smoothing of sign(v) the plant uses


@dataclass(frozen=True)
class EffectParam:
    """One parameter of an effect, declared once: the file key (``<effect>.<key>``), the
    field of :class:`EffectParams` it is stored in, its unit, what it is, whether it may be
    negative, its bounds for calibration (from the rig's :class:`Scales`), fitted or fixed.

    ``unit`` is an SI expression (checked here) or a token the plant resolves: ``force``
    (N or N·m), ``velocity`` (m/s or rad/s), ``position`` (m or rad), ``input`` (the
    plant input's A or V).
    """

    key: str
    field: str
    unit: str
    bounds: Callable[[Scales], tuple[float, float]]
    doc: str = ""
    signed: bool = False  # may be negative (a bias); every other effect parameter is >= 0
    fitted: bool = True
    default: Callable[[Scales], float] | None = None
    log: bool = False  # search the parameter on a logarithmic grid
    maximum: float | None = None  # physical upper limit, checked when a rig is built
    # the end of its bounds at which the effect does nothing (0 when the bounds hold it;
    # a bulk modulus or a pump flow does least at its upper bound: the oil's, unlimited)
    off_at_upper: bool = False
    # the range of sizes a real rig shows (docs/modelling.md "Typical ranges"), for an
    # effect's size parameter: calibration calls a fitted size far below it negligible
    typical: Callable[[Scales], tuple[float, float]] | None = None

    def __post_init__(self) -> None:
        if self.unit not in UNIT_TOKENS:
            parse_unit(self.unit)  # raises on a misspelled unit, at import
        if not (self.field.isidentifier() and self.doc):
            raise ValueError(f"effect parameter {self.key!r}: needs a field name and a doc")

    @property
    def optional(self) -> bool:
        """A fitted parameter a rig file may leave out: it then takes its default (a
        first-order spool's second time constant, 0)."""
        return self.fitted and self.default is not None

    def value_bounds(self, scales: Scales) -> tuple[float, float]:
        lo, hi = self.bounds(scales)
        return float(lo), float(hi)


@dataclass(frozen=True)
class Effect:
    """A library entry: name, stage (``input`` or ``plant``), parameters, and what it
    models; ``screened``: a calibration tries it unless told which effects to try;
    ``lookalike``: what else a record explained by it may hold, which the data cannot
    tell from it (calibration's verdict says so when it adds the effect);
    ``special_cases``: the effects it contains (calibration prefers an established
    special case to it when the data cannot tell them apart); ``stick_slip``: friction,
    which a quantised closed loop makes stick and slip where single converter codes put
    it, so that replayed through the controller its cost is chaotic in it (calibration
    warns when a record it adds it to has its valve input)."""

    name: str
    stage: str
    params: tuple[EffectParam, ...]
    formulation: str
    source: str
    screened: bool = True
    lookalike: str = ""
    special_cases: tuple[str, ...] = ()  # effects this one becomes with a parameter at 0
    stick_slip: bool = False
    # sums a reader looks for, of parameters stored as parts: (name, parameter keys); a
    # Stribeck law stores its stiction as the part above the Coulomb level, and its
    # breakaway force is their sum
    totals: tuple[tuple[str, tuple[str, ...]], ...] = ()

    @property
    def fitted(self) -> tuple[EffectParam, ...]:
        return tuple(p for p in self.params if p.fitted)

    def param_by_field(self, field: str) -> EffectParam:
        for p in self.params:
            if p.field == field:
                return p
        raise KeyError(field)

    def param(self, key: str) -> EffectParam:
        for p in self.params:
            if p.key == key:
                return p
        raise KeyError(key)


def _presliding(field: str) -> EffectParam:
    """A friction effect's optional LuGre pre-sliding distance (0: the static law)."""
    return EffectParam(
        "presliding_distance",
        field,
        "position",
        # up to a tenth of what the actuator travels at full speed in one sample
        lambda s: (0.0, 0.1 * s.velocity * s.sample_time),
        doc="LuGre pre-sliding distance at breakaway (0: the static law)",
        log=True,
        default=lambda s: 0.0,
    )


def _smoothing() -> EffectParam:
    return EffectParam(
        "smoothing_velocity",
        "friction_smoothing_velocity_si",
        "velocity",
        lambda s: (0.0, 0.1 * s.velocity),
        doc="tanh smoothing of sign(v)",
        fitted=False,
        default=lambda s: s.smoothing_velocity,
    )


LIBRARY: dict[str, Effect] = {
    e.name: e
    for e in (
        Effect(
            "coulomb_friction",
            "plant",
            (
                EffectParam("force", "coulomb_force_si", "force", lambda s: (0.0, 0.1 * s.force), doc="Coulomb friction force or torque",
                    typical=lambda s: (0.01 * s.force, 0.1 * s.force)),
                _presliding("coulomb_presliding_si"),
                _smoothing(),
            ),
            "F = Fc·tanh(v/vc) opposing the motion [N or N·m]; vc the plant's smoothing velocity; "
            "with a pre-sliding distance d > 0 the LuGre law (bristles of stiffness Fc/d, "
            "critically damped on the moving mass), which sticks",
            "docs/modelling.md Friction (smooth form); seed 002 §5 names dry friction as neglected",
            stick_slip=True,
        ),
        Effect(
            "stribeck_friction",
            "plant",
            (
                EffectParam(
                    "coulomb_force", "stribeck_coulomb_force_si", "force",
                    lambda s: (0.0, 0.1 * s.force), doc="Coulomb level",
                    typical=lambda s: (0.01 * s.force, 0.1 * s.force)),
                EffectParam(
                    "stiction_force", "stribeck_stiction_force_si", "force",
                    lambda s: (0.0, 0.1 * s.force), doc="breakaway minus Coulomb"),
                EffectParam(
                    "stribeck_velocity", "stribeck_velocity_si", "velocity",
                    lambda s: (1e-3 * s.velocity, 0.2 * s.velocity), log=True, doc="Stribeck velocity"),
                _presliding("stribeck_presliding_si"),
                _smoothing(),
            ),
            "F = (Fc + Fst·exp(−(v/vs)²))·tanh(v/vc): breakaway Fc + Fst at rest, Fc in "
            "motion; with a pre-sliding distance d > 0 the LuGre law: bristles of stiffness "
            "σ0 = (Fc + Fst)/d, critically damped on the moving mass, which stick",
            "docs/modelling.md Friction and typical ranges (Fs/Fc 1.1-1.5, vs 1-10 mm/s); "
            "Canudas de Wit, Olsson, Åström and Lischinsky 1995 (LuGre)",
            special_cases=("coulomb_friction",),  # Fst = 0
            stick_slip=True,
            totals=(("breakaway", ("coulomb_force", "stiction_force")),),
        ),
        Effect(
            "line_resistance",
            "plant",
            (
                EffectParam(
                    "resistance", "line_resistance_pa_s_m3", "Pa*s/m^3",
                    lambda s: (0.0, s.pressure / s.flow), log=True, doc="laminar line resistance",
                    # 1-10 % of the supply pressure lost at the rated flow
                    typical=lambda s: (0.01 * s.pressure / s.flow, 0.1 * s.pressure / s.flow)),
            ),
            "laminar line between each valve port and its chamber: Δp = R·q [Pa], "
            "R = 128·μ·L/(π·d⁴)",
            "docs/modelling.md line loss; seed 002 §5 names the valve-cylinder line as neglected",
        ),
        Effect(
            "internal_leakage",
            "plant",
            (
                EffectParam(
                    # up to the rated flow at the full supply pressure: a worn piston seal;
                    # a tenth of it (the earlier bound) was below the cylinder range's top
                    # on seed 002 (8.8e-13 < 1e-12 m³/(s·Pa))
                    "coefficient", "internal_leakage_m3_s_pa", "m^3/(s*Pa)",
                    lambda s: (0.0, s.flow / s.pressure), log=True, doc="cross-port leakage",
                    # 0.1-10 % of the rated flow at the full supply pressure (1e-14..1e-12
                    # m³/(s·Pa) on seed 002's cylinder, 1e-12..1e-11 on a motor)
                    typical=lambda s: (1e-3 * s.flow / s.pressure, 0.1 * s.flow / s.pressure)),
            ),
            "q = Kl·(pA − pB) across the piston or motor [m³/s]",
            "docs/modelling.md typical ranges (1e-14..1e-12 cylinders, 1e-12..1e-11 motors); "
            "seed 003 §2, seed 001 eq. 1-9",
        ),
        Effect(
            "valve_deadband",
            "input",
            (
                EffectParam(
                    "width", "valve_deadband_si", "input", lambda s: (0.0, 0.1 * s.input), doc="dead band half-width",
                    typical=lambda s: (0.005 * s.input, 0.05 * s.input)),
            ),
            "i_eff = i0 + sign(Δi)·max(|Δi| − w, 0) around the valve null i0",
            "docs/modelling.md dead band / overlap",
        ),
        Effect(
            "valve_bias",
            "input",
            (
                EffectParam(
                    "offset", "valve_bias_si", "input",
                    lambda s: (-0.05 * s.input, 0.05 * s.input), doc="null bias offset", signed=True,
                    typical=lambda s: (0.005 * s.input, 0.03 * s.input)),
            ),
            "i_eff = i + b: a null bias beyond the declared one [A or V]",
            "docs/modelling.md null bias (≤ 2-3 % of rated current)",
        ),
        Effect(
            "valve_lag",
            "input",
            (EffectParam("time_constant", "valve_lag_s", "s", lambda s: (0.0, 0.02), doc="spool time constant",
                         typical=lambda s: (0.8e-3, 3.2e-3)),
             EffectParam("second_time_constant", "valve_lag2_s", "s", lambda s: (0.0, 0.01),
                         doc="second time constant of a second-order spool (0: first order)",
                         default=lambda s: 0.0)),
            "τ1·τ2·s̈ + τ1·ṡ + s = i: spool dynamics [s]; τ2 = 0 first order, else second "
            "order of ωn = 1/√(τ1·τ2), ζ = ½·√(τ1/τ2)",
            "docs/modelling.md typical ranges (spool bandwidth 50-200 Hz: τ 0.8-3.2 ms); seed 000 eq. 8 "
            "(first order); Merritt 1967 §5 (a servo valve's spool as second order)",
            lookalike=(
                "a transport delay of about its time constant: a lag much faster than the "
                "loop acts as a delay"
            ),
        ),
        Effect(
            "transport_delay",
            "input",
            (
                EffectParam(
                    "delay", "transport_delay_s", "s",
                    lambda s: (0.0, max(0.05, 5.0 * s.sample_time)), doc="input delay",
                    # a computation and converter delay of up to a sample period
                    typical=lambda s: (0.1 * s.sample_time, s.sample_time)),
            ),
            "i_eff(t) = i(t − d): computation, bus and converter delay [s]",
            "docs/modelling.md transport delay (cross-correlation peak at lag > 0)",
            lookalike=(
                "a first-order lag of about the same time constant elsewhere in the loop, "
                "e.g. the position sensor's or the converter's filter: a lag much shorter "
                "than the sample period acts in the loop as a delay of its time constant "
                "(a 1 ms sensor filter on seed 002's bench comes back as a 0.99 ms delay, "
                "docs/calibration.md); or the valve's spool, whose second-order response "
                "acts as a delay of about 2ζ/ωn (a 100 Hz spool of damping 0.7 comes back "
                "as a 1.8 ms delay, docs/calibration-power.md); check the sensor's and the "
                "valve's bandwidth before reading it as a delay"
            ),
        ),
        Effect(
            "bulk_modulus",
            "plant",
            (
                EffectParam(
                    "effective", "effective_bulk_modulus_pa", "Pa",
                    lambda s: (0.1e9, s.bulk_modulus), doc="effective bulk modulus (0: the oil's)",
                    off_at_upper=True),
            ),
            "E_eff replaces the oil's bulk modulus in every chamber [Pa]",
            "docs/modelling.md typical ranges (oil 1.4-1.8 GPa; hoses or air 0.2-0.7 GPa)",
        ),
        Effect(
            "supply_droop",
            "plant",
            (
                EffectParam(
                    "pump_flow", "pump_flow_m3_s", "m^3/s",
                    lambda s: (0.1 * s.flow, 4.0 * s.flow), doc="pump flow limit (0: unlimited)",
                    off_at_upper=True),
            ),
            "q_supply = min(q_demand, Qp): a pump of limited flow behind the relief valve; "
            "the supply pressure sags when the valve asks for more",
            "docs/modelling.md supply droop; seed 003 eq. 1 (pump with relief)",
        ),
        Effect(
            "external_leakage",
            "plant",
            (
                EffectParam(
                    "coefficient", "external_leakage_m3_s_pa", "m^3/(s*Pa)",
                    lambda s: (0.0, 0.1 * s.flow / s.pressure), log=True, doc="leakage to the drain",
                    typical=lambda s: (1e-3 * s.flow / s.pressure, 0.1 * s.flow / s.pressure)),
            ),
            "q = Ke·p out of each chamber to the drain (rod seals, a motor's case drain) "
            "[m³/s]; composed cylinders and motors",
            "docs/modelling.md typical ranges (leakage 1e-14..1e-11 m³/(s·Pa)); seed 000 eq. 17 "
            "(a motor's external leakage), seed 001 eq. 1-9",
        ),
        Effect(
            "entrained_air",
            "plant",
            (
                EffectParam(
                    "air_fraction", "air_fraction", "1", lambda s: (0.0, 0.02), maximum=0.5,
                    doc="free air per oil volume at 1 atm (0: no air; 0.001-0.01 typical)",
                    typical=lambda s: (0.001, 0.01)),
                EffectParam(
                    "polytropic_index", "air_polytropic_index", "1", lambda s: (1.0, 1.4),
                    doc="polytropic index n of the air (1-1.4)", fitted=False,
                    default=lambda s: 1.0, maximum=1.4),
                EffectParam(
                    "vapour_pressure", "air_vapour_pressure_pa", "Pa",
                    lambda s: (100.0, 1.0e4), doc="vapour pressure, absolute (the floor)",
                    fitted=False, default=lambda s: 1.0e3, maximum=0.5e5),
            ),
            "E_mix(p) = (1 + r)/(1/E + r/(n·p)), r = α·(p_atm/p)^(1/n), in every chamber, "
            "line and supply volume (p absolute); no pressure falls below the vapour pressure",
            "docs/modelling.md \"Entrained air and cavitation\" (Merritt 1967 §2.5; "
            "Gholizadeh, Bitner, Burton & Schoenau, ASME JDSMC 136(5), 2014)",
            # only data that reaches low pressures tells α from the bulk_modulus effect
            screened=False,
        ),
    )
}  # fmt: skip


def _declared_fields() -> dict[str, tuple[str, EffectParam]]:
    """Field -> (the first effect declaring it, its declaration), in library order (a
    field two effects share, friction's smoothing velocity, is one entry)."""
    out: dict[str, tuple[str, EffectParam]] = {}
    for effect in LIBRARY.values():
        for prm in effect.params:
            out.setdefault(prm.field, (effect.name, prm))
    return out


def _make_effect_params() -> type:
    fields = [
        (name, float, quantity(f"{effect}.{prm.key}", prm.unit, default=0.0, doc=prm.doc,
                               effect=True, nonnegative=not prm.signed, maximum=prm.maximum))
        for name, (effect, prm) in _declared_fields().items()
    ]  # fmt: skip
    cls = dataclasses.make_dataclass("EffectParams", fields, frozen=True, kw_only=True)
    cls.__module__ = __name__
    cls.__doc__ = (
        "Effect parameters every plant parameter set carries (made from :data:`LIBRARY`); "
        "0 switches an effect off.\n\nUnits of ``*_si`` fields depend on the plant: force "
        "N (cylinder) or N·m (motor), velocity m/s or rad/s, input A or V (the plant's input)."
    )
    return cls


EffectParams = _make_effect_params()
# Where each effect parameter sits in every plant's packed vector (the inherited fields
# come first): ``p[E.valve_lag_s]`` in a kernel, ``E.valve_lag_s`` in a component's code.
EffectIndex = NamedTuple("EffectIndex", [(name, int) for name in _declared_fields()])
E = EffectIndex(*(index_of(EffectParams, name) for name in _declared_fields()))


# --------------------------------------------------------------------------- kernels


@njit(cache=True, inline="always")
def bulk_modulus(p: Any, declared: float) -> float:
    """E_eff [Pa] when the ``bulk_modulus`` effect is on, else the declared oil modulus."""
    e = p[E.effective_bulk_modulus_pa]
    return e if e > 0.0 else declared


@njit(cache=True)
def chamber_modulus(p_gauge: float, inflow: float, beta: float, p: Any) -> float:
    """The bulk modulus [Pa] a volume at gauge pressure ``p_gauge`` [Pa] integrates with.

    ``beta`` itself unless the ``entrained_air`` effect is on; then the mixture's
    E_mix(p) (:func:`~fuzzyservo.components.air.mixture_modulus`, at the absolute
    pressure, floored at the vapour pressure p_v) and, while the net ``inflow`` [m³/s]
    is negative, the floor: between 2·p_v and p_v the modulus falls linearly to zero,
    so the volume's pressure settles onto p_v (the oil vaporises at constant pressure)
    and rises again as soon as oil flows in.
    """
    alpha = p[E.air_fraction]
    if alpha <= 0.0:
        return beta
    index = max(p[E.air_polytropic_index], 1.0)
    p_v = p[E.air_vapour_pressure_pa]
    if p_v <= 0.0:
        p_v = 1.0e3
    p_abs = p_gauge + ATMOSPHERE_PA
    e = mixture_modulus(max(p_abs, p_v), beta, alpha, index)
    if inflow < 0.0 and p_abs < 2.0 * p_v:
        e *= max(p_abs / p_v - 1.0, 0.0)
    return e


@njit(cache=True, inline="always")
def friction_force(v: float, p: Any) -> float:
    """Coulomb plus Stribeck friction [N or N·m] opposing velocity ``v`` [m/s or rad/s].

    ``F = (Fc + Fc_s + Fst·exp(−(v/vs)²))·tanh(v/vc)`` (docs/modelling.md "Friction", smooth
    form; Armstrong-Hélouvry's Stribeck curve without its viscous part, which every
    plant already has). Zero when both friction effects are off.
    """
    fc = p[E.coulomb_force_si] + p[E.stribeck_coulomb_force_si]
    fst = p[E.stribeck_stiction_force_si]
    if fc == 0.0 and fst == 0.0:
        return 0.0
    vc = p[E.friction_smoothing_velocity_si]
    if vc <= 0.0:
        vc = 1e-4
    return friction_level(v, p) * math.tanh(v / vc)


@njit(cache=True, inline="always")
def friction_level(v: float, p: Any) -> float:
    """The Stribeck curve's level ``Fc + Fst·exp(−(v/vs)²)`` [N or N·m] at velocity ``v``
    (``Fc`` both friction effects' Coulomb parts)."""
    level = p[E.coulomb_force_si] + p[E.stribeck_coulomb_force_si]
    fst = p[E.stribeck_stiction_force_si]
    vs = p[E.stribeck_velocity_si]
    if fst > 0.0 and vs > 0.0:
        r = v / vs
        level += fst * math.exp(-r * r)
    return level


@njit(cache=True, inline="always")
def breakaway(p: Any) -> float:
    """The friction at rest's limit Fc + Fst [N or N·m] (both effects' Coulomb parts)."""
    return p[E.coulomb_force_si] + p[E.stribeck_coulomb_force_si] + p[E.stribeck_stiction_force_si]


@njit(cache=True, inline="always")
def presliding(p: Any) -> float:
    """The LuGre pre-sliding distance [m or rad]: the friction effects' own, added (as
    their Coulomb levels are); 0, the static law, unless one of them gives one."""
    return p[E.coulomb_presliding_si] + p[E.stribeck_presliding_si]


def has_bristles(params: Any) -> bool:
    """Whether the parameters ``params`` (an :class:`EffectParams`) give a friction
    effect a pre-sliding distance (:func:`presliding` > 0): the LuGre law, whose bristle
    state a composition then carries (``compose``'s ``bristles``)."""
    return params.coulomb_presliding_si + params.stribeck_presliding_si > 0.0


@njit(cache=True, inline="always")
def bristle_rate(v: float, z: float, p: Any) -> float:
    """dz/dt of the LuGre bristles' mean deflection ``z`` [m or rad] at velocity ``v``:
    ``v − σ0·|v|·z/g(v)``, σ0 = (Fc + Fst)/d, g the Stribeck curve
    (:func:`friction_level`); 0 unless the pre-sliding distance d > 0
    (Canudas de Wit et al. 1995, eq. 2-3; d from :func:`presliding`)."""
    d = presliding(p)
    if d <= 0.0:
        return 0.0
    g = friction_level(v, p)
    top = breakaway(p)
    if g <= 0.0 or top <= 0.0:
        return 0.0
    return v - (top / d) * abs(v) * z / g


@njit(cache=True, inline="always")
def actuator_friction(v: float, z: float, mass: float, p: Any) -> float:
    """Friction [N or N·m] on an actuator moving at ``v`` with bristle deflection ``z``
    and moving mass ``mass`` [kg or kg·m²].

    The static law (:func:`friction_force`) unless a friction effect's pre-sliding
    distance d > 0 (:func:`presliding`); then LuGre's ``σ0·z + σ1·dz/dt`` (:func:`bristle_rate`), with
    σ1 = 2·√(σ0·m) (the bristles critically damped on the mass, as Canudas de Wit et
    al. advise) and no viscous term (every actuator has its own). In steady sliding it
    is the Stribeck curve; at rest the bristles hold up to the breakaway Fc + Fst after
    at most d of elastic pre-sliding: the actuator sticks instead of creeping.
    """
    d = presliding(p)
    if d <= 0.0:
        return friction_force(v, p)
    top = breakaway(p)
    if top <= 0.0:
        return 0.0
    sigma0 = top / d
    return sigma0 * z + 2.0 * math.sqrt(sigma0 * mass) * bristle_rate(v, z, p)


@njit(cache=True, inline="always")
def deadband(i: float, null: float, width: float) -> float:
    """Spool overlap: ``i0 + sign(Δi)·max(|Δi| − w, 0)`` with Δi = i − i0 (no flow change
    for |Δi| ≤ w; docs/modelling.md "dead band / overlap")."""
    if width <= 0.0:
        return i
    d = i - null
    if d > width:
        return i - width
    if d < -width:
        return i + width
    return null


@njit(cache=True, inline="always")
def _sqrt_flow_slope(coeff: float, dp: float, p_lam: float) -> float:
    """d/dΔp of :func:`signed_sqrt_flow`: K·(Δp²/2 + λ²)/(Δp² + λ²)^(5/4)."""
    s = dp * dp + p_lam * p_lam
    return coeff * (0.5 * dp * dp + p_lam * p_lam) / (s * math.sqrt(math.sqrt(s)))


@njit(cache=True)
def port_pressure(
    c_in: float,
    p_in: float,
    c_out: float,
    p_out: float,
    p_chamber: float,
    resistance: float,
    p_lam: float,
) -> float:
    """Pressure [Pa] of a valve port joined to a chamber by a laminar line (``line_resistance``).

    Solves the port's flow balance ``c_in·√(p_in − x) − c_out·√(x − p_out) = (x − p_c)/R``
    (turbulent valve slots in and out, laminar line Δp = R·q; docs/modelling.md "line loss")
    by Newton's method inside a bracket; the left side falls and the right side rises
    with x, so the root is unique and lies between the smallest and largest pressure.
    """
    lo = min(p_in, p_out, p_chamber)
    hi = max(p_in, p_out, p_chamber)
    x = p_chamber
    g = 1.0 / resistance
    for _ in range(60):
        f = (
            signed_sqrt_flow(c_in, p_in - x, p_lam)
            - signed_sqrt_flow(c_out, x - p_out, p_lam)
            - (x - p_chamber) * g
        )
        if f > 0.0:
            lo = x
        else:
            hi = x
        slope = (
            _sqrt_flow_slope(c_in, p_in - x, p_lam) + _sqrt_flow_slope(c_out, x - p_out, p_lam) + g
        )
        step = f / slope
        x_new = x + step
        if x_new <= lo or x_new >= hi:
            x_new = 0.5 * (lo + hi)
        if abs(x_new - x) <= 1e-10 * (abs(x) + 1e5) or hi - lo <= 1e-10 * (abs(x) + 1e5):
            return x_new
        x = x_new
    return x


@njit(cache=True, inline="always")
def pump_limited(q: float, p: Any) -> float:
    """Supply flow [m³/s] limited to the pump's delivery Qp (``supply_droop``); when the
    demand exceeds Qp the relief valve closes and the supply pressure sags."""
    qp = p[E.pump_flow_m3_s]
    if qp <= 0.0:
        return q
    if q > qp:
        return qp
    if q < -qp:
        return -qp
    return q


INPUT_EFFECTS = tuple(name for name, e in LIBRARY.items() if e.stage == "input")


def fixed_defaults(
    name: str, params: Any, scales: Scales, given: Iterable[str] = ()
) -> dict[str, float]:
    """Field -> library default for the parameters of effect ``name`` that have one, are
    not among the keys ``given`` and are still 0 in ``params`` (e.g. friction smoothing)."""
    given = set(given)
    return {
        p.field: float(p.default(scales))
        for p in LIBRARY[name].params
        if p.key not in given and p.default is not None and not getattr(params, p.field)
    }


def owner(field: str) -> str | None:
    """The effect a parameter field belongs to, or None for a plant's own parameter."""
    for name, effect in LIBRARY.items():
        if any(p.field == field for p in effect.params):
            return name
    return None
