"""Servo-valve driving a hydraulic motor with a cable drum: the compensator of seed 001's AHC stand.

States (SI): ``spool`` the valve opening as a fraction of full opening [1], ``w`` drum
speed [rad/s], ``theta`` drum angle [rad] (positive pays cable out), ``p_a`` and
``p_b`` the motor port pressures [Pa].

    τ_v · dspool/dt = u / u_rated − spool                      (first-order spool, not in the seed)
    Q_a = port_flow(+spool, p_a),  Q_b = port_flow(−spool, p_b)          (seed 001 eq. 3-4)
    Q_lea = k_lea·(p_a − p_b)                   volumetric losses (eq. 12-13, k_lea)
    (V_a/E)·dp_a/dt = Q_a − D_m·w − Q_lea
    (V_b/E)·dp_b/dt = Q_b + D_m·w + Q_lea
    (J + m·r²)·dw/dt = η_hm·D_m·(p_a − p_b) − b_w·w − T_c·tanh(w/w_c) + m·g·r   (eq. 14-15, motor eq.)
    dtheta/dt = w

``D_m`` is the displacement per radian (V_m/2π of eq. 10-11). The hydro-mechanical
efficiency ``η_hm`` of eq. 15 is a constant factor on the ideal torque, applied in both
directions of power flow (a simplification: a back-driven motor loses torque the
other way); ``b_w`` and ``T_c`` are the speed-dependent and constant terms of the
seed's hydro-mechanical losses (b_ω, b), smoothed over ``w_c``.

The 5 kg load hangs on a rigid cable from the drum of radius r: its weight pulls the
cable out (+m·g·r) and its inertia adds m·r². The plant's load input is the platform
(cylinder rod) position z_w [m], which carries the motor; the load's absolute height
is ``z_load = z_w − r·theta`` (signal). The platform's acceleration is left out of the
cable tension: for the 0.05-0.2 Hz waves of the heave scenario it stays below
0.2 m/s², 2 % of g.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fuzzyservo._jit import njit
from fuzzyservo.components.effects import EffectParams
from fuzzyservo.params import name_index, param_index, quantity
from reference_plants.kernels import port_flow, return_flow, supply_flow

STATES = ("spool", "w", "theta", "p_a", "p_b")
SIGNALS = (
    "spool", "w", "theta", "p_a", "p_b", "q_a", "q_b", "q_lea",
    "q_supply", "q_return", "t_loss", "payout", "z_load",
)  # fmt: skip
SIGNAL_UNITS = {
    "spool": "1", "w": "rad/s", "theta": "rad", "p_a": "Pa", "p_b": "Pa", "q_a": "m^3/s",
    "q_b": "m^3/s", "q_lea": "m^3/s", "q_supply": "m^3/s", "q_return": "m^3/s",
    "t_loss": "N*m", "payout": "m", "z_load": "m",
}  # fmt: skip
INPUT = ("u_valve", "V")  # the plant input: valve amplifier command
LOAD = ("z_wave", "m")  # height of the platform (cylinder rod) carrying the motor
PRESSURES = ("p_a", "p_b")  # gauge chamber pressures (simulation/validity.py)


@dataclass(frozen=True)
class AhcMotorParams(EffectParams):
    """Seed 001 §2.2 and §3-4 parameters, SI units (the rig file gives each with its source)."""

    valve_time_constant_s: float = quantity("valve_time_constant", "s", positive=True)
    rated_command_v: float = quantity("rated_command", "V", positive=True)
    rated_flow_m3_s: float = quantity("rated_flow", "m^3/s", positive=True)
    rated_pressure_drop_pa: float = quantity("rated_pressure_drop", "Pa", positive=True)
    valve_leakage_m3_s_pa: float = quantity("valve_leakage", "m^3/(s*Pa)", nonnegative=True)
    supply_pressure_pa: float = quantity("supply_pressure", "Pa", positive=True)
    tank_pressure_pa: float = quantity("tank_pressure", "Pa", nonnegative=True)
    displacement_m3_rad: float = quantity("motor_displacement", "m^3/rad", positive=True)
    port_volume_m3: float = quantity("port_volume", "m^3", positive=True)
    motor_leakage_m3_s_pa: float = quantity("motor_leakage", "m^3/(s*Pa)", nonnegative=True)
    hydromechanical_efficiency: float = quantity(
        "hydromechanical_efficiency", "1", positive=True, maximum=1.0
    )
    viscous_friction_n_m_s: float = quantity("viscous_friction", "N*m*s/rad", nonnegative=True)
    coulomb_torque_n_m: float = quantity("coulomb_torque", "N*m", nonnegative=True)
    coulomb_velocity_rad_s: float = quantity("coulomb_velocity", "rad/s", positive=True)
    inertia_kg_m2: float = quantity("inertia", "kg*m^2", positive=True)
    drum_radius_m: float = quantity("drum_radius", "m", positive=True)
    load_mass_kg: float = quantity("load_mass", "kg", nonnegative=True)
    gravity_m_s2: float = quantity("gravity", "m/s^2", nonnegative=True)
    bulk_modulus_pa: float = quantity("bulk_modulus", "Pa", positive=True)
    laminar_pressure_pa: float = quantity("laminar_pressure", "Pa", positive=True)

    def __post_init__(self) -> None:
        if self.supply_pressure_pa <= self.tank_pressure_pa:
            raise ValueError(
                f"supply_pressure: must exceed tank_pressure "
                f"(got {self.supply_pressure_pa} Pa <= {self.tank_pressure_pa} Pa); "
                f"check both values and their units"
            )

    @property
    def valve_coeff(self) -> float:
        """Fully open land K = Q_n / sqrt(Δp_n/2) [m³/(s·sqrt(Pa))]: Δp_n over two lands."""
        return self.rated_flow_m3_s / math.sqrt(0.5 * self.rated_pressure_drop_pa)

    @property
    def load_torque_n_m(self) -> float:
        """Torque of the hanging load on the drum, m·g·r [N·m]."""
        return self.load_mass_kg * self.gravity_m_s2 * self.drum_radius_m


PARAMS = AhcMotorParams
P = param_index(PARAMS)  # p[P.<field>]: positions generated from the dataclass
S = name_index(SIGNALS)  # out[S.<signal>]: positions generated from SIGNALS
X = name_index(STATES, "States")  # x[X.<state>], dx[X.<state>]


@njit(cache=True, inline="always")
def _evaluate(
    x: np.ndarray, u: float, z_wave: float, p: np.ndarray, dx: np.ndarray, out: np.ndarray
) -> None:
    """The whole model in one flat function; writes dx/dt and, when ``out`` has room, SIGNALS."""
    s = x[X.spool]
    w = x[X.w]
    pa = x[X.p_a]
    pb = x[X.p_b]
    k = p[P.rated_flow_m3_s] / math.sqrt(0.5 * p[P.rated_pressure_drop_pa])
    ps = p[P.supply_pressure_pa]
    pt = p[P.tank_pressure_pa]
    lam = p[P.laminar_pressure_pa]
    kl = p[P.valve_leakage_m3_s_pa]
    dm = p[P.displacement_m3_rad]
    r = p[P.drum_radius_m]
    qa = port_flow(s, k, kl, ps, pt, pa, lam)
    qb = port_flow(-s, k, kl, ps, pt, pb, lam)
    qlea = p[P.motor_leakage_m3_s_pa] * (pa - pb)  # volumetric losses (eq. 12-13)
    t_loss = p[P.viscous_friction_n_m_s] * w + p[P.coulomb_torque_n_m] * math.tanh(
        w / p[P.coulomb_velocity_rad_s]
    )
    t_load = p[P.load_mass_kg] * p[P.gravity_m_s2] * r
    e_v = p[P.bulk_modulus_pa] / p[P.port_volume_m3]
    dx[X.spool] = (u / p[P.rated_command_v] - s) / p[P.valve_time_constant_s]
    dx[X.w] = (p[P.hydromechanical_efficiency] * dm * (pa - pb) - t_loss + t_load) / (
        p[P.inertia_kg_m2] + p[P.load_mass_kg] * r * r
    )
    dx[X.theta] = w
    dx[X.p_a] = e_v * (qa - dm * w - qlea)
    dx[X.p_b] = e_v * (qb + dm * w + qlea)
    if out.size >= 13:
        out[S.spool] = s
        out[S.w] = w
        out[S.theta] = x[X.theta]
        out[S.p_a] = pa
        out[S.p_b] = pb
        out[S.q_a] = qa
        out[S.q_b] = qb
        out[S.q_lea] = qlea
        out[S.q_supply] = supply_flow(s, k, kl, ps, pa, lam) + supply_flow(-s, k, kl, ps, pb, lam)
        out[S.q_return] = return_flow(s, k, kl, pt, pa, lam) + return_flow(-s, k, kl, pt, pb, lam)
        out[S.t_loss] = t_loss
        out[S.payout] = r * x[X.theta]
        out[S.z_load] = z_wave - r * x[X.theta]


@njit(cache=True, inline="always")
def rhs(x: np.ndarray, u: float, z_wave: float, p: np.ndarray, dx: np.ndarray) -> None:
    """Right-hand side dx/dt of the seed-001 compensator motor (module docstring).

    ``x`` states (STATES), ``u`` valve command [V], ``z_wave`` platform height [m]
    (enters only the signals: the cable is rigid), ``p`` packed :class:`AhcMotorParams`.
    """
    _evaluate(x, u, z_wave, p, dx, dx)


@njit(cache=True)
def signals(x: np.ndarray, u: float, z_wave: float, p: np.ndarray, out: np.ndarray) -> None:
    """Every signal of SIGNALS for state ``x``; writes ``out``."""
    dx = np.empty(x.size)
    _evaluate(x, u, z_wave, p, dx, out)


@njit(cache=True)
def in_end_stop(x: np.ndarray, p: np.ndarray) -> bool:
    """A motor has no end stop."""
    return False


def state_scale(params: AhcMotorParams) -> np.ndarray:
    """Unit of local error per state: 1e-4 of spool, 0.01 rad/s, 0.1 mrad, 1 kPa."""
    return np.array([1e-4, 1e-2, 1e-4, 1e3, 1e3])


def typical_state(params: AhcMotorParams) -> np.ndarray:
    """Typical magnitude of each state (finite-difference increments): 0.1, 10 rad/s, 1 rad, 1 MPa."""
    return np.array([0.1, 10.0, 1.0, 1e6, 1e6])


INITIAL_KEYS = {"angle": ("theta_rad", "rad")}


def holding_pressures(params: AhcMotorParams) -> tuple[float, float]:
    """Port pressures (p_a, p_b) [Pa] whose torque holds the load at rest: symmetric about
    the valve's null pressure, p_b − p_a = m·g·r/(η_hm·D_m) (eq. 15). The flows balance
    with a spool opening of a fraction of a percent, which the loop finds."""
    null = 0.5 * (params.supply_pressure_pa + params.tank_pressure_pa)
    dp = params.load_torque_n_m / (params.hydromechanical_efficiency * params.displacement_m3_rad)
    return null - 0.5 * dp, null + 0.5 * dp


def initial_state(params: AhcMotorParams, *, theta_rad: float = 0.0) -> np.ndarray:
    """At rest at ``theta_rad``, spool centred, port pressures holding the load."""
    pa, pb = holding_pressures(params)
    return np.array([0.0, 0.0, theta_rad, pa, pb])
