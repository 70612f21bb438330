"""Open-centre servo-valve driving an asymmetric cylinder (seed 002, Dinca & Corcau).

States (SI): ``y`` piston position [m] (0 at the seed's initial chamber lengths),
``v`` velocity [m/s], and the liquid volumes at reference density ``xi1..xi4`` [m³]
of the valve chambers 1 (supply side), 2 (return side) and the cylinder chambers 3
(piston side) and 4 (rod side). The liquid mass is ``m = ρ0·xi`` (seed eq. 3-4, 8-9);
pressures follow from the compressible-liquid law ρ = ρ0(1 + p/E) (eq. 1):

    p = E·(xi / V − 1)                                         (eq. 5, 6, 10, 11)
    V1, V2 constant;  V3 = S3·(l30 + y),  V4 = S4·(l40 − y)     (eq. 7)

Mass form: ``d(xi)/dt`` is the net volume flow at reference density, so the total
liquid mass is a linear invariant that any integrator conserves exactly.

    dxi1/dt = Qa − Q1 − Q3          (eq. 3)
    dxi2/dt = Q2 + Q4 − Qr          (eq. 4)
    dxi3/dt = Q1 − Q2               (eq. 8)
    dxi4/dt = Q3 − Q4               (eq. 9)
    m·dv/dt = p3·S3 − p4·S4 − f·v − k_L·y − F_load + F_stop   (eq. 12; k_L = 0 in seed 002)

Valve slot flows (eq. 13-16) with Δi = i − I_bias:

    Q1 = (a + b·Δi)·√(p1 − p3),  Q2 = (a − b·Δi)·√(p3 − p2)
    Q3 = (a − b·Δi)·√(p1 − p4),  Q4 = (a + b·Δi)·√(p4 − p2)
    Qa = Ra·√(pa − p1),          Qr = Rr·√(p2 − pr)             (eq. 17-18)

Closing-current logic: beyond Δi ≥ +I_cl slots 2 and 3 are shut, beyond Δi ≤ −I_cl
slots 1 and 4 (the seed's formulas close each slot where its opening coefficient
reaches zero, I_cl = a/b = 3.70 mA; its prose swaps the two pairs). Every √ is the
regularised orifice law of :func:`~fuzzyservo.components.orifice.signed_sqrt_flow`.

Effects (components/effects.py, off unless a rig file declares them): friction
``F_fric(v)`` joins eq. 12; ``line_resistance`` puts a laminar line between each valve
port and its chamber (the port pressure balances slot and line flows); ``internal_leakage``
moves Kl·(p3 − p4) from chamber 3 to 4; ``bulk_modulus`` replaces E; ``supply_droop`` caps
Qa at the pump's flow. The input effects act before ``i`` reaches eq. 13-16.

End stops: the chamber lengths never fall below ``dead_length_m``; a stiff
spring-damper acts beyond that point (the seed is silent; docs/modelling.md "chamber
volumes must never reach zero").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fuzzyservo._jit import njit
from fuzzyservo.components.effects import (
    E,
    EffectParams,
    Scales,
    bulk_modulus,
    friction_force,
    port_pressure,
    pump_limited,
)
from fuzzyservo.components.orifice import signed_sqrt_flow
from fuzzyservo.params import name_index, param_index, quantity
from reference_plants.kernels import FIRST_EFFECTS, circle_area, effective_bulk_modulus

STATES = ("y", "v", "xi1", "xi2", "xi3", "xi4")
SIGNALS = (
    "y", "v", "p1", "p2", "p3", "p4",
    "q_a", "q_r", "q1", "q2", "q3", "q4", "f_stop", "f_friction", "q_leak",
)  # fmt: skip
SIGNAL_UNITS = {
    "y": "m", "v": "m/s", "p1": "Pa", "p2": "Pa", "p3": "Pa", "p4": "Pa",
    "q_a": "m^3/s", "q_r": "m^3/s", "q1": "m^3/s", "q2": "m^3/s", "q3": "m^3/s",
    "q4": "m^3/s", "f_stop": "N", "f_friction": "N", "q_leak": "m^3/s",
}  # fmt: skip
INPUT = ("i", "A")  # the plant input: servo-valve current
LOAD = ("f_load", "N")  # external force opposing extension (+y)
PRESSURES = ("p1", "p2", "p3", "p4")  # gauge chamber pressures (simulation/validity.py)


@dataclass(frozen=True)
class CylinderParams(EffectParams):
    """Seed 002 section 4 parameters, SI units (the rig file gives each with its source)."""

    piston_diameter_m: float = quantity("piston_diameter", "m", positive=True)
    rod_diameter_m: float = quantity("rod_diameter", "m", positive=True)
    chamber_length_3_m: float = quantity("initial_chamber_length_3", "m", positive=True)
    chamber_length_4_m: float = quantity("initial_chamber_length_4", "m", positive=True)
    piston_mass_kg: float = quantity("piston_mass", "kg", positive=True)
    viscous_friction_n_s_m: float = quantity("viscous_friction", "N*s/m", nonnegative=True)
    valve_volume_1_m3: float = quantity("valve_chamber_volume_1", "m^3", positive=True)
    valve_volume_2_m3: float = quantity("valve_chamber_volume_2", "m^3", positive=True)
    slot_coeff_a_m3_s_sqrtpa: float = quantity(
        "slot_coefficient_a", "m^3/(s*sqrt(Pa))", positive=True
    )
    slot_coeff_b_m3_s_a_sqrtpa: float = quantity(
        "slot_coefficient_b", "m^3/(s*A*sqrt(Pa))", positive=True
    )
    closing_current_a: float = quantity("closing_current", "A", positive=True)
    bias_current_a: float = quantity("bias_current", "A")
    density_kg_m3: float = quantity("density", "kg/m^3", positive=True)
    bulk_modulus_pa: float = quantity("bulk_modulus", "Pa", positive=True)
    supply_resistance_m3_s_sqrtpa: float = quantity(
        "supply_resistance", "m^3/(s*sqrt(Pa))", positive=True
    )
    return_resistance_m3_s_sqrtpa: float = quantity(
        "return_resistance", "m^3/(s*sqrt(Pa))", positive=True
    )
    supply_pressure_pa: float = quantity("supply_pressure", "Pa", positive=True)
    return_pressure_pa: float = quantity("return_pressure", "Pa", nonnegative=True)
    laminar_pressure_pa: float = quantity("laminar_pressure", "Pa", positive=True)
    dead_length_m: float = quantity("dead_length", "m", positive=True)
    end_stop_stiffness_n_m: float = quantity("end_stop_stiffness", "N/m", positive=True)
    end_stop_damping_n_s_m: float = quantity("end_stop_damping", "N*s/m", nonnegative=True)
    load_stiffness_n_m: float = quantity(
        "load_stiffness", "N/m", nonnegative=True, default=0.0,
        doc="a spring-like load (e.g. a beam) pushing back against extension",
    )  # fmt: skip

    def __post_init__(self) -> None:
        if self.rod_diameter_m >= self.piston_diameter_m:
            raise ValueError(
                f"rod_diameter: must be smaller than piston_diameter "
                f"(rod {self.rod_diameter_m} m >= piston {self.piston_diameter_m} m); "
                f"check that the two are not swapped"
            )
        if self.supply_pressure_pa <= self.return_pressure_pa:
            raise ValueError(
                f"supply_pressure: must exceed return_pressure "
                f"(got {self.supply_pressure_pa} Pa <= {self.return_pressure_pa} Pa); "
                f"check both values and their units"
            )
        for key, length in (
            ("initial_chamber_length_3", self.chamber_length_3_m),
            ("initial_chamber_length_4", self.chamber_length_4_m),
        ):
            if self.dead_length_m >= length:
                raise ValueError(
                    f"dead_length: must be shorter than {key} ({self.dead_length_m} m >= {length} m); "
                    f"give the few millimetres of port and end-cap length"
                )

    @property
    def area_3_m2(self) -> float:
        """Piston-side area S3 = π·dp²/4 [m²] (seed 002 §4: 7.068 cm²)."""
        return circle_area(self.piston_diameter_m)

    @property
    def area_4_m2(self) -> float:
        """Rod-side annulus S4 = π·(dp² − dt²)/4 [m²] (seed 002 §4: 5.529 cm²)."""
        return circle_area(self.piston_diameter_m) - circle_area(self.rod_diameter_m)

    @property
    def stroke_limits_m(self) -> tuple[float, float]:
        """Positions where the end stops engage: chamber 3 or 4 at its dead length."""
        return (
            self.dead_length_m - self.chamber_length_3_m,
            self.chamber_length_4_m - self.dead_length_m,
        )


PARAMS = CylinderParams
P = param_index(PARAMS)  # p[P.<field>]: positions generated from the dataclass
S = name_index(SIGNALS)  # out[S.<signal>]: positions generated from SIGNALS
X = name_index(STATES, "States")  # x[X.<state>], dx[X.<state>]

# Chamber lengths never fall below this fraction of the dead length, even deep in an
# end stop, so that a volume can never reach zero whatever the integrator tries.
_MIN_LENGTH_FRACTION = 0.05


@njit(cache=True, inline="always")
def _stop_force(y: float, v: float, p: np.ndarray) -> float:
    """End-stop force [N]: spring-damper beyond the dead length, zero inside the stroke."""
    lo = p[P.dead_length_m] - p[P.chamber_length_3_m]
    hi = p[P.chamber_length_4_m] - p[P.dead_length_m]
    if y < lo:
        return p[P.end_stop_stiffness_n_m] * (lo - y) - (
            p[P.end_stop_damping_n_s_m] * v if v < 0.0 else 0.0
        )
    if y > hi:
        return -p[P.end_stop_stiffness_n_m] * (y - hi) - (
            p[P.end_stop_damping_n_s_m] * v if v > 0.0 else 0.0
        )
    return 0.0


@njit(cache=True, inline="always")
def _evaluate(
    x: np.ndarray, i: float, f_load: float, p: np.ndarray, dx: np.ndarray, out: np.ndarray
) -> None:
    """The whole model in one flat function (helpers returning tuples cost 2x in numba).

    Writes dx/dt into ``dx`` and, when ``out`` has room, every signal of SIGNALS.
    """
    y = x[X.y]
    v = x[X.v]
    # geometry (eq. 7); chamber lengths floored so that no volume reaches zero
    s3 = circle_area(p[P.piston_diameter_m])
    s4 = s3 - circle_area(p[P.rod_diameter_m])
    lmin = _MIN_LENGTH_FRACTION * p[P.dead_length_m]
    l3 = max(p[P.chamber_length_3_m] + y, lmin)
    l4 = max(p[P.chamber_length_4_m] - y, lmin)
    # pressures from liquid volumes (eq. 5, 6, 10, 11)
    e = bulk_modulus(p, p[P.bulk_modulus_pa])
    p1 = e * (x[X.xi1] / p[P.valve_volume_1_m3] - 1.0)
    p2 = e * (x[X.xi2] / p[P.valve_volume_2_m3] - 1.0)
    p3 = e * (x[X.xi3] / (s3 * l3) - 1.0)
    p4 = e * (x[X.xi4] / (s4 * l4) - 1.0)
    # slot coefficients with the closing-current logic (eq. 13-16)
    di = i - p[P.bias_current_a]
    c14 = p[P.slot_coeff_a_m3_s_sqrtpa] + p[P.slot_coeff_b_m3_s_a_sqrtpa] * di
    c23 = p[P.slot_coeff_a_m3_s_sqrtpa] - p[P.slot_coeff_b_m3_s_a_sqrtpa] * di
    if di >= p[P.closing_current_a]:
        c23 = 0.0
    if di <= -p[P.closing_current_a]:
        c14 = 0.0
    c14 = max(c14, 0.0)
    c23 = max(c23, 0.0)
    lam = p[P.laminar_pressure_pa]
    qa = pump_limited(
        signed_sqrt_flow(p[P.supply_resistance_m3_s_sqrtpa], p[P.supply_pressure_pa] - p1, lam), p
    )  # supply_droop
    qr = signed_sqrt_flow(p[P.return_resistance_m3_s_sqrtpa], p2 - p[P.return_pressure_pa], lam)
    # valve ports: the chambers themselves, or line_resistance's port nodes
    pa_port = p3
    pb_port = p4
    r_line = p[E.line_resistance_pa_s_m3]
    if r_line > 0.0:
        pa_port = port_pressure(c14, p1, c23, p2, p3, r_line, lam)
        pb_port = port_pressure(c23, p1, c14, p2, p4, r_line, lam)
    q1 = signed_sqrt_flow(c14, p1 - pa_port, lam)
    q2 = signed_sqrt_flow(c23, pa_port - p2, lam)
    q3 = signed_sqrt_flow(c23, p1 - pb_port, lam)
    q4 = signed_sqrt_flow(c14, pb_port - p2, lam)
    q_leak = p[E.internal_leakage_m3_s_pa] * (p3 - p4)  # internal_leakage across the piston
    f_fric = friction_force(v, p)  # coulomb_friction, stribeck_friction
    f_stop = _stop_force(y, v, p)
    dx[X.y] = v
    f_spring = p[P.load_stiffness_n_m] * y  # a spring-like load (0 in seed 002)
    dx[X.v] = (
        p3 * s3 - p4 * s4 - p[P.viscous_friction_n_s_m] * v - f_fric - f_spring - f_load + f_stop
    ) / p[P.piston_mass_kg]  # eq. 12
    dx[X.xi1] = qa - q1 - q3  # eq. 3
    dx[X.xi2] = q2 + q4 - qr  # eq. 4
    dx[X.xi3] = q1 - q2 - q_leak  # eq. 8
    dx[X.xi4] = q3 - q4 + q_leak  # eq. 9
    if out.size >= 15:
        out[S.y] = y
        out[S.v] = v
        out[S.p1] = p1
        out[S.p2] = p2
        out[S.p3] = p3
        out[S.p4] = p4
        out[S.q_a] = qa
        out[S.q_r] = qr
        out[S.q1] = q1
        out[S.q2] = q2
        out[S.q3] = q3
        out[S.q4] = q4
        out[S.f_stop] = f_stop
        out[S.f_friction] = f_fric
        out[S.q_leak] = q_leak


@njit(cache=True, inline="always")
def rhs(x: np.ndarray, i: float, f_load: float, p: np.ndarray, dx: np.ndarray) -> None:
    """Right-hand side dx/dt of the seed-002 servo-actuator (module docstring, eq. 1-18).

    ``x`` states (STATES), ``i`` valve current [A], ``f_load`` external force [N]
    opposing extension, ``p`` packed :class:`CylinderParams`; writes ``dx``.
    """
    _evaluate(x, i, f_load, p, dx, dx)


@njit(cache=True)
def signals(x: np.ndarray, i: float, f_load: float, p: np.ndarray, out: np.ndarray) -> None:
    """Every signal of SIGNALS for state ``x``; writes ``out``."""
    dx = np.empty(x.size)
    _evaluate(x, i, f_load, p, dx, out)


def pressures(x: np.ndarray, p: np.ndarray) -> tuple[float, float, float, float]:
    """Pressures p1..p4 [Pa] from the liquid volumes (seed 002 eq. 5, 6, 10, 11)."""
    out = np.empty(len(SIGNALS))
    signals(np.asarray(x, dtype=np.float64), 0.0, 0.0, p, out)
    return out[S.p1], out[S.p2], out[S.p3], out[S.p4]


def flows(
    x: np.ndarray, i: float, p: np.ndarray
) -> tuple[float, float, float, float, float, float]:
    """Flows (Qa, Qr, Q1, Q2, Q3, Q4) [m³/s] for state ``x`` and valve current ``i`` [A]."""
    out = np.empty(len(SIGNALS))
    signals(np.asarray(x, dtype=np.float64), i, 0.0, p, out)
    return tuple(out[6:12])


@njit(cache=True)
def in_end_stop(x: np.ndarray, p: np.ndarray) -> bool:
    """True when the piston is beyond either end-stop position."""
    return (
        x[X.y] < p[P.dead_length_m] - p[P.chamber_length_3_m]
        or x[X.y] > p[P.chamber_length_4_m] - p[P.dead_length_m]
    )


def state_scale(params: CylinderParams) -> np.ndarray:
    """Unit of local error per state: 1 µm, 1 mm/s, and 1 kPa of pressure in each chamber."""
    e = effective_bulk_modulus(params)
    dp = 1e3
    v3 = params.area_3_m2 * params.chamber_length_3_m
    v4 = params.area_4_m2 * params.chamber_length_4_m
    return np.array(
        [1e-6, 1e-3, params.valve_volume_1_m3 * dp / e, params.valve_volume_2_m3 * dp / e,
         v3 * dp / e, v4 * dp / e]
    )  # fmt: skip


# Initial conditions a rig file may set: file key -> (keyword of initial_state, SI unit)
INITIAL_KEYS = {
    "position": ("y_m", "m"),
    "pressure_1": ("p1_pa", "Pa"),
    "pressure_2": ("p2_pa", "Pa"),
    "pressure_3": ("p3_pa", "Pa"),
    "pressure_4": ("p4_pa", "Pa"),
    "mass_3": ("m3_kg", "kg"),
    "mass_4": ("m4_kg", "kg"),
}


def initial_state(
    params: CylinderParams,
    *,
    y_m: float = 0.0,
    p1_pa: float | None = None,
    p2_pa: float | None = None,
    p3_pa: float | None = None,
    p4_pa: float | None = None,
    m3_kg: float | None = None,
    m4_kg: float | None = None,
) -> np.ndarray:
    """State at rest at position ``y_m`` with the given pressures or chamber masses.

    Defaults (seed 002 eq. 2): p1 = pa, p2 = pr; p3 = p4 = (pa + pr)/2 unless given.
    A chamber mass m3 or m4 is the mass at y = 0, where the chambers have the seed's
    lengths l30, l40 (seed 002 §4: m30 = 12.040 g, m40 = 68.280 g): it sets the held
    pressure through m = ρ0·V(0)·(1 + p/E), and a start at another ``y_m`` holds that
    pressure in the chamber's volume there. (Keeping the y = 0 mass in a volume 3.5
    times larger at y = 5 cm would put p3 at −12 847 bar.)
    """
    pa, pr = params.supply_pressure_pa, params.return_pressure_pa
    e = effective_bulk_modulus(params)
    v3 = params.area_3_m2 * (params.chamber_length_3_m + y_m)
    v4 = params.area_4_m2 * (params.chamber_length_4_m - y_m)
    if m3_kg is not None:
        v30 = params.area_3_m2 * params.chamber_length_3_m
        p3_pa = pressure_from_mass(m3_kg, v30, params)
    if m4_kg is not None:
        v40 = params.area_4_m2 * params.chamber_length_4_m
        p4_pa = pressure_from_mass(m4_kg, v40, params)
    p1 = pa if p1_pa is None else p1_pa
    p2 = pr if p2_pa is None else p2_pa
    p3 = 0.5 * (pa + pr) if p3_pa is None else p3_pa
    p4 = 0.5 * (pa + pr) if p4_pa is None else p4_pa
    return np.array(
        [y_m, 0.0, params.valve_volume_1_m3 * (1 + p1 / e), params.valve_volume_2_m3 * (1 + p2 / e),
         v3 * (1 + p3 / e), v4 * (1 + p4 / e)]
    )  # fmt: skip


def pressure_from_mass(mass_kg: float, volume_m3: float, params: CylinderParams) -> float:
    """Invert m = ρ0·V·(1 + p/E) for p [Pa] (seed 002 §4 gives m30, m40 this way)."""
    return effective_bulk_modulus(params) * (mass_kg / (params.density_kg_m3 * volume_m3) - 1.0)


def typical_state(params: CylinderParams) -> np.ndarray:
    """Typical magnitude of each state (finite-difference increments): 1 mm, 0.1 m/s, volumes."""
    return np.array(
        [1e-3, 0.1, params.valve_volume_1_m3, params.valve_volume_2_m3,
         params.area_3_m2 * params.chamber_length_3_m, params.area_4_m2 * params.chamber_length_4_m]
    )  # fmt: skip


# The effects this plant's kernel reads: the first ten of the library, so that an effect
# added later is refused here until the kernel reads it.
EFFECTS = FIRST_EFFECTS
MECHANICS = {"force": "N", "velocity": "m/s"}


def null_input(params: CylinderParams) -> float:
    """The valve current of hydraulic null [A]: the bias current (seed 002 eq. 13-16)."""
    return params.bias_current_a


def effect_scales(params: CylinderParams, input_a: float, sample_time_s: float) -> Scales:
    """Sizes the effect bounds scale with: stall force pa·S3, rated flow at full opening
    (slot coefficient a + b·I_cl across the whole supply drop), its piston speed."""
    dp = params.supply_pressure_pa - params.return_pressure_pa
    opening = (
        params.slot_coeff_a_m3_s_sqrtpa
        + params.slot_coeff_b_m3_s_a_sqrtpa * params.closing_current_a
    )
    flow = opening * dp**0.5
    return Scales(
        force=params.supply_pressure_pa * params.area_3_m2,
        velocity=flow / params.area_3_m2,
        flow=flow,
        pressure=dp,
        input=input_a,
        bulk_modulus=params.bulk_modulus_pa,
        sample_time=sample_time_s,
        # 0.5 % of the no-load speed: smooth enough that the fitted cost is not rough
        # where the P loop sticks (0.44 mm/s on seed 002)
        smoothing_velocity=5e-3 * flow / params.area_3_m2,
    )
