"""Servo-valve driving a double-acting cylinder: the wave simulator of seed 001's AHC stand.

States (SI): ``spool`` the valve opening as a fraction of full opening [1], ``y`` rod
extension from the retracted end [m], ``v`` velocity [m/s], ``p_a`` and ``p_b`` the
piston-side and rod-side chamber pressures [Pa].

    τ_v · dspool/dt = u / u_rated − spool                     (first-order spool, not in the seed)
    Q_a = port_flow(+spool, p_a),  Q_b = port_flow(−spool, p_b)         (eq. 3-4)
    Q_v = K_v·(p_a − p_b)   across the piston,  Q_vb = K_vb·p_b  along the rod   (eq. 7-8)
    (V_a/E)·dp_a/dt = Q_a − A·v − Q_v                          (eq. 1, 5, 6)
    (V_b/E)·dp_b/dt = Q_b + a·A·v + Q_v − Q_vb                 (eq. 2, 5, 6)
    m·dv/dt = A·(p_a − a·p_b) − D·v − F_load + F_stop          (eq. 9)
    V_a = V_a0 + A·y,   V_b = V_b0 + a·A·(stroke − y)

``port_flow`` is the critically lapped 4-way valve of
:mod:`reference_plants.kernels` (regularised orifice law and the K_l land
leakage). The supply is an ideal pressure source (seed 001 §4: a 100 dm³/min, 37 kW
unit; pressure droop is not modelled). End stops: a stiff spring-damper beyond the
stroke; the chamber volumes never fall below a fraction of the dead volumes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fuzzyservo._jit import njit
from fuzzyservo.components.effects import EffectParams
from fuzzyservo.params import name_index, param_index, quantity
from reference_plants.kernels import circle_area, port_flow, return_flow, supply_flow

STATES = ("spool", "y", "v", "p_a", "p_b")
SIGNALS = (
    "spool", "y", "v", "p_a", "p_b", "q_a", "q_b", "q_v", "q_vb",
    "q_supply", "q_return", "f_stop",
)  # fmt: skip
SIGNAL_UNITS = {
    "spool": "1", "y": "m", "v": "m/s", "p_a": "Pa", "p_b": "Pa", "q_a": "m^3/s",
    "q_b": "m^3/s", "q_v": "m^3/s", "q_vb": "m^3/s", "q_supply": "m^3/s",
    "q_return": "m^3/s", "f_stop": "N",
}  # fmt: skip
INPUT = ("u_valve", "V")  # the plant input: valve amplifier command
LOAD = ("f_load", "N")  # external force opposing extension (+y), e.g. the weight carried
PRESSURES = ("p_a", "p_b")  # gauge chamber pressures (simulation/validity.py)


@dataclass(frozen=True)
class AhcCylinderParams(EffectParams):
    """Seed 001 §2.1 and §3 parameters, SI units (the rig file gives each with its source)."""

    valve_time_constant_s: float = quantity("valve_time_constant", "s", positive=True)
    rated_command_v: float = quantity("rated_command", "V", positive=True)
    rated_flow_m3_s: float = quantity("rated_flow", "m^3/s", positive=True)
    rated_pressure_drop_pa: float = quantity("rated_pressure_drop", "Pa", positive=True)
    valve_leakage_m3_s_pa: float = quantity("valve_leakage", "m^3/(s*Pa)", nonnegative=True)
    supply_pressure_pa: float = quantity("supply_pressure", "Pa", positive=True)
    tank_pressure_pa: float = quantity("tank_pressure", "Pa", nonnegative=True)
    piston_diameter_m: float = quantity("piston_diameter", "m", positive=True)
    rod_diameter_m: float = quantity("rod_diameter", "m", positive=True)
    stroke_m: float = quantity("stroke", "m", positive=True)
    dead_volume_a_m3: float = quantity("dead_volume_a", "m^3", positive=True)
    dead_volume_b_m3: float = quantity("dead_volume_b", "m^3", positive=True)
    mass_kg: float = quantity("reduced_mass", "kg", positive=True)
    viscous_friction_n_s_m: float = quantity("viscous_friction", "N*s/m", nonnegative=True)
    piston_leakage_m3_s_pa: float = quantity("piston_leakage", "m^3/(s*Pa)", nonnegative=True)
    rod_leakage_m3_s_pa: float = quantity("rod_leakage", "m^3/(s*Pa)", nonnegative=True)
    bulk_modulus_pa: float = quantity("bulk_modulus", "Pa", positive=True)
    laminar_pressure_pa: float = quantity("laminar_pressure", "Pa", positive=True)
    end_stop_stiffness_n_m: float = quantity("end_stop_stiffness", "N/m", positive=True)
    end_stop_damping_n_s_m: float = quantity("end_stop_damping", "N*s/m", nonnegative=True)

    def __post_init__(self) -> None:
        if self.rod_diameter_m >= self.piston_diameter_m:
            raise ValueError(
                f"rod_diameter: must be smaller than piston_diameter "
                f"(rod {self.rod_diameter_m} m >= piston {self.piston_diameter_m} m); "
                f"check that the two are not swapped (seed 001 prints them swapped)"
            )
        if self.supply_pressure_pa <= self.tank_pressure_pa:
            raise ValueError(
                f"supply_pressure: must exceed tank_pressure "
                f"(got {self.supply_pressure_pa} Pa <= {self.tank_pressure_pa} Pa); "
                f"check both values and their units"
            )

    @property
    def area_a_m2(self) -> float:
        """Piston area A = π·D²/4 [m²]."""
        return circle_area(self.piston_diameter_m)

    @property
    def area_b_m2(self) -> float:
        """Annulus a·A = π·(D² − d²)/4 [m²]."""
        return circle_area(self.piston_diameter_m) - circle_area(self.rod_diameter_m)

    @property
    def valve_coeff(self) -> float:
        """Fully open land K = Q_n / sqrt(Δp_n/2) [m³/(s·sqrt(Pa))]: Δp_n over two lands."""
        return self.rated_flow_m3_s / math.sqrt(0.5 * self.rated_pressure_drop_pa)

    @property
    def stroke_limits_m(self) -> tuple[float, float]:
        return (0.0, self.stroke_m)


PARAMS = AhcCylinderParams
P = param_index(PARAMS)  # p[P.<field>]: positions generated from the dataclass
S = name_index(SIGNALS)  # out[S.<signal>]: positions generated from SIGNALS
X = name_index(STATES, "States")  # x[X.<state>], dx[X.<state>]

# Chamber volumes never fall below this fraction of their dead volume, even deep in an
# end stop, so that no volume reaches zero whatever the integrator tries.
_MIN_VOLUME_FRACTION = 0.05


@njit(cache=True, inline="always")
def _evaluate(
    x: np.ndarray, u: float, f_load: float, p: np.ndarray, dx: np.ndarray, out: np.ndarray
) -> None:
    """The whole model in one flat function; writes dx/dt and, when ``out`` has room, SIGNALS."""
    s = x[X.spool]
    y = x[X.y]
    v = x[X.v]
    pa = x[X.p_a]
    pb = x[X.p_b]
    area_a = circle_area(p[P.piston_diameter_m])
    area_b = area_a - circle_area(p[P.rod_diameter_m])
    va = max(p[P.dead_volume_a_m3] + area_a * y, _MIN_VOLUME_FRACTION * p[P.dead_volume_a_m3])
    vb = max(
        p[P.dead_volume_b_m3] + area_b * (p[P.stroke_m] - y),
        _MIN_VOLUME_FRACTION * p[P.dead_volume_b_m3],
    )
    k = p[P.rated_flow_m3_s] / math.sqrt(0.5 * p[P.rated_pressure_drop_pa])
    ps = p[P.supply_pressure_pa]
    pt = p[P.tank_pressure_pa]
    lam = p[P.laminar_pressure_pa]
    kl = p[P.valve_leakage_m3_s_pa]
    qa = port_flow(s, k, kl, ps, pt, pa, lam)  # eq. 3
    qb = port_flow(-s, k, kl, ps, pt, pb, lam)  # eq. 4
    qv = p[P.piston_leakage_m3_s_pa] * (pa - pb)  # eq. 7
    qvb = p[P.rod_leakage_m3_s_pa] * (pb - pt)  # eq. 8 (pressures over tank = atmosphere)
    if y < 0.0:
        f_stop = -p[P.end_stop_stiffness_n_m] * y - (
            p[P.end_stop_damping_n_s_m] * v if v < 0.0 else 0.0
        )
    elif y > p[P.stroke_m]:
        f_stop = -p[P.end_stop_stiffness_n_m] * (y - p[P.stroke_m]) - (
            p[P.end_stop_damping_n_s_m] * v if v > 0.0 else 0.0
        )
    else:
        f_stop = 0.0
    e = p[P.bulk_modulus_pa]
    dx[X.spool] = (u / p[P.rated_command_v] - s) / p[P.valve_time_constant_s]
    dx[X.y] = v
    dx[X.v] = (area_a * pa - area_b * pb - p[P.viscous_friction_n_s_m] * v - f_load + f_stop) / p[
        P.mass_kg
    ]  # eq. 9
    dx[X.p_a] = e / va * (qa - area_a * v - qv)  # eq. 1, 5, 6
    dx[X.p_b] = e / vb * (qb + area_b * v + qv - qvb)  # eq. 2, 5, 6
    if out.size >= 12:
        out[S.spool] = s
        out[S.y] = y
        out[S.v] = v
        out[S.p_a] = pa
        out[S.p_b] = pb
        out[S.q_a] = qa
        out[S.q_b] = qb
        out[S.q_v] = qv
        out[S.q_vb] = qvb
        out[S.q_supply] = supply_flow(s, k, kl, ps, pa, lam) + supply_flow(-s, k, kl, ps, pb, lam)
        out[S.q_return] = return_flow(s, k, kl, pt, pa, lam) + return_flow(-s, k, kl, pt, pb, lam)
        out[S.f_stop] = f_stop


@njit(cache=True, inline="always")
def rhs(x: np.ndarray, u: float, f_load: float, p: np.ndarray, dx: np.ndarray) -> None:
    """Right-hand side dx/dt of the seed-001 wave-simulator cylinder (module docstring).

    ``x`` states (STATES), ``u`` valve command [V], ``f_load`` force opposing extension
    [N], ``p`` packed :class:`AhcCylinderParams`; writes ``dx``.
    """
    _evaluate(x, u, f_load, p, dx, dx)


@njit(cache=True)
def signals(x: np.ndarray, u: float, f_load: float, p: np.ndarray, out: np.ndarray) -> None:
    """Every signal of SIGNALS for state ``x``; writes ``out``."""
    dx = np.empty(x.size)
    _evaluate(x, u, f_load, p, dx, out)


@njit(cache=True)
def in_end_stop(x: np.ndarray, p: np.ndarray) -> bool:
    """True when the rod is beyond either end of the stroke."""
    return x[X.y] < 0.0 or x[X.y] > p[P.stroke_m]


def state_scale(params: AhcCylinderParams) -> np.ndarray:
    """Unit of local error per state: 1e-4 of spool, 1 µm, 1 mm/s, 1 kPa."""
    return np.array([1e-4, 1e-6, 1e-3, 1e3, 1e3])


def typical_state(params: AhcCylinderParams) -> np.ndarray:
    """Typical magnitude of each state (finite-difference increments): 0.1, 1 mm, 0.1 m/s, 1 MPa."""
    return np.array([0.1, 1e-3, 0.1, 1e6, 1e6])


INITIAL_KEYS = {
    "position": ("y_m", "m"),
    "pressure_a": ("pa_pa", "Pa"),
    "pressure_b": ("pb_pa", "Pa"),
}


def initial_state(
    params: AhcCylinderParams,
    *,
    y_m: float = 0.0,
    pa_pa: float | None = None,
    pb_pa: float | None = None,
) -> np.ndarray:
    """State at rest at ``y_m``, spool centred; chambers at the null pressure
    (p_s + p_t)/2 of the closed valve unless given."""
    null = 0.5 * (params.supply_pressure_pa + params.tank_pressure_pa)
    return np.array(
        [0.0, y_m, 0.0, null if pa_pa is None else pa_pa, null if pb_pa is None else pb_pa]
    )
