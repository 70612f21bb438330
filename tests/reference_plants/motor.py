"""Servo-valve driving an axial-piston motor: the EHS 160 rig of seed 000 (Selim et al.).

States (SI): ``spool`` the valve's spool position expressed as its equivalent input
voltage [V], ``w`` motor speed [rad/s], ``theta`` motor angle [rad], ``p_load`` load
pressure P_x [Pa].

    τ_x · dspool/dt = K_a·u − spool                                  (eq. 8)
    Q = K_x · spool · sqrt((P_s − sgn(Q)·P_x) / P_s)                   (eq. 9)
    (V_c / (4·K_h)) · dP_x/dt = Q − V_m·w − L_e·P_x                   (eq. 17)
    J · dw/dt = V_m·P_x − B_e·w − T_f·tanh(w/w_c) − T_L·tanh(w/w_c)   (eq. 14-15)
    dtheta/dt = w

``u`` is the amplifier input [V]; K_a = −1 and K_x < 0 (Table 2) so that a positive
input drives the motor forward. Eq. 9 is printed as sqrt(P_s − |P_x|): for a
motoring load (P_x with the sign of the flow, every scenario of the seed) the two
are the same; the signed form above keeps the flow physical when the load overruns.
Effects (components/effects.py, off unless declared) add friction to T_f, leakage to
L_e, a line drop 2·R·Q to the load pressure the valve sees, E_eff for K_h, and the
pump's cap on |Q|. The square root is regularised near zero (``laminar_pressure_pa``), and the Coulomb
friction is smoothed over ``coulomb_velocity_rad_s`` so the right-hand side is
Lipschitz (docs/modelling.md "Friction").

The load T_L is the scenario's ``load``: the torque of the shoe brake, the rig's only load
(seed 000 §2, item 8: "mechanical brake (acting as a variable load)"). A brake only
opposes motion, so it acts like the Coulomb friction, T_L·tanh(w/w_c): it slows the
motor, holds it near standstill, and never drives it backwards.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fuzzyservo._jit import njit
from fuzzyservo.components.effects import (
    E,
    EffectParams,
    Scales,
    bulk_modulus,
    friction_force,
    pump_limited,
)
from fuzzyservo.params import name_index, param_index, quantity
from reference_plants.kernels import FIRST_EFFECTS

STATES = ("spool", "w", "theta", "p_load")
SIGNALS = ("spool", "w", "theta", "p_load", "q_valve", "t_friction", "q_leak", "p_a", "p_b")
SIGNAL_UNITS = {
    "spool": "V",
    "w": "rad/s",
    "theta": "rad",
    "p_load": "Pa",
    "q_valve": "m^3/s",
    "t_friction": "N*m",
    "q_leak": "m^3/s",
    "p_a": "Pa",
    "p_b": "Pa",
}
INPUT = ("u_valve", "V")  # the plant input: servo-amplifier input voltage
LOAD = ("t_load", "N*m")  # the shoe brake's torque: it opposes motion, whichever the direction
# Port pressures of the symmetric valve (§3 ii): p_a + p_b = P_s, p_a − p_b = P_x. They are
# what the vapour-pressure check reads (simulation/validity.py).
PRESSURES = ("p_a", "p_b")


@dataclass(frozen=True)
class MotorParams(EffectParams):
    """Seed 000 Table 2, SI units (the rig file gives each with its source)."""

    valve_time_constant_s: float = quantity("valve_time_constant", "s", positive=True)
    amplifier_gain: float = quantity("amplifier_gain", "1", nonzero=True)
    valve_flow_gain_m3_s_v: float = quantity("valve_flow_gain", "m^3/(s*V)", nonzero=True)
    supply_pressure_pa: float = quantity("supply_pressure", "Pa", positive=True)
    motor_displacement_m3_rad: float = quantity("motor_displacement", "m^3/rad", positive=True)
    oil_volume_m3: float = quantity("oil_volume", "m^3", positive=True)
    leakage_m5_n_s: float = quantity("leakage_coefficient", "m^5/(N*s)", nonnegative=True)
    bulk_modulus_pa: float = quantity("bulk_modulus", "Pa", positive=True)
    viscous_friction_n_m_s: float = quantity("viscous_friction", "N*m*s/rad", nonnegative=True)
    inertia_kg_m2: float = quantity("inertia", "N*m*s^2/rad", positive=True)
    coulomb_torque_n_m: float = quantity("coulomb_torque", "N*m", nonnegative=True)
    coulomb_velocity_rad_s: float = quantity("coulomb_velocity", "rad/s", positive=True)
    laminar_pressure_pa: float = quantity("laminar_pressure", "Pa", positive=True)


PARAMS = MotorParams
P = param_index(PARAMS)  # p[P.<field>]: positions generated from the dataclass
S = name_index(SIGNALS)  # out[S.<signal>]: positions generated from SIGNALS
X = name_index(STATES, "States")  # x[X.<state>], dx[X.<state>]


@njit(cache=True)
def valve_flow(spool: float, p_load: float, p: np.ndarray) -> float:
    """Servo-valve flow Q [m³/s] (seed 000 eq. 9), regularised near P_x = ±P_s."""
    q0 = p[P.valve_flow_gain_m3_s_v] * spool
    dp = p[P.supply_pressure_pa] - (p_load if q0 >= 0.0 else -p_load)
    lam = p[P.laminar_pressure_pa]
    # dp/(dp²+lam²)^(1/4) ≈ sqrt(dp) for dp ≫ lam, linear through zero below
    return q0 * dp / math.sqrt(math.sqrt(dp * dp + lam * lam) * p[P.supply_pressure_pa])


@njit(cache=True)
def line_flow(spool: float, p_load: float, p: np.ndarray) -> float:
    """Valve flow Q [m³/s] through the lines to the motor, with the pump's limit.

    With ``line_resistance`` R the valve sees the load pressure plus the drop of both
    lines, ``Q = valve_flow(spool, P_x + 2·R·Q)``; the right side falls as Q rises, so
    the root lies between 0 and ``valve_flow(spool, P_x)`` and bisection finds it.
    ``supply_droop`` then caps |Q| at the pump's flow (components/effects.py).
    """
    q = valve_flow(spool, p_load, p)
    r2 = 2.0 * p[E.line_resistance_pa_s_m3]
    if r2 > 0.0 and q != 0.0:
        lo = min(0.0, q)
        hi = max(0.0, q)
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            if mid - valve_flow(spool, p_load + r2 * mid, p) > 0.0:
                hi = mid
            else:
                lo = mid
            if hi - lo <= 1e-13 * abs(q):
                break
        q = 0.5 * (lo + hi)
    return pump_limited(q, p)


@njit(cache=True)
def friction_torque(w: float, p: np.ndarray) -> float:
    """Viscous plus smoothed Coulomb friction torque [N·m] (seed 000 eq. 10, Table 2),
    plus the friction effects when declared."""
    return (
        p[P.viscous_friction_n_m_s] * w
        + p[P.coulomb_torque_n_m] * math.tanh(w / p[P.coulomb_velocity_rad_s])
        + friction_force(w, p)
    )


@njit(cache=True)
def rhs(x: np.ndarray, u: float, t_load: float, p: np.ndarray, dx: np.ndarray) -> None:
    """Right-hand side dx/dt of the EHS 160 servo motor (module docstring).

    ``x`` states (STATES), ``u`` amplifier input [V], ``t_load`` brake torque [N·m],
    ``p`` packed :class:`MotorParams`; writes ``dx``.
    """
    spool = x[X.spool]
    w = x[X.w]
    pl = x[X.p_load]
    q = line_flow(spool, pl, p)
    dx[X.spool] = (p[P.amplifier_gain] * u - spool) / p[P.valve_time_constant_s]
    brake = t_load * math.tanh(w / p[P.coulomb_velocity_rad_s])
    dx[X.w] = (p[P.motor_displacement_m3_rad] * pl - friction_torque(w, p) - brake) / p[
        P.inertia_kg_m2
    ]
    dx[X.theta] = w
    leak = (
        p[P.leakage_m5_n_s] + p[E.internal_leakage_m3_s_pa]
    ) * pl  # eq. 17 plus internal_leakage
    dx[X.p_load] = (
        4.0
        * bulk_modulus(p, p[P.bulk_modulus_pa])
        / p[P.oil_volume_m3]
        * (q - p[P.motor_displacement_m3_rad] * w - leak)
    )


@njit(cache=True)
def signals(x: np.ndarray, u: float, t_load: float, p: np.ndarray, out: np.ndarray) -> None:
    """Every signal of SIGNALS for state ``x``; writes ``out``."""
    out[S.spool] = x[X.spool]
    out[S.w] = x[X.w]
    out[S.theta] = x[X.theta]
    out[S.p_load] = x[X.p_load]
    out[S.q_valve] = line_flow(x[X.spool], x[X.p_load], p)
    out[S.t_friction] = friction_torque(x[X.w], p)
    out[S.q_leak] = p[E.internal_leakage_m3_s_pa] * x[X.p_load]
    out[S.p_a] = 0.5 * (p[P.supply_pressure_pa] + x[X.p_load])
    out[S.p_b] = 0.5 * (p[P.supply_pressure_pa] - x[X.p_load])


@njit(cache=True)
def in_end_stop(x: np.ndarray, p: np.ndarray) -> bool:
    """A motor has no end stop."""
    return False


def state_scale(params: MotorParams) -> np.ndarray:
    """Unit of local error per state: 1 mV of spool, 0.01 rad/s, 1 mrad, 1 kPa."""
    return np.array([1e-3, 1e-2, 1e-3, 1e3])


def typical_state(params: MotorParams) -> np.ndarray:
    """Typical magnitude of each state (finite-difference increments): 1 V, 10 rad/s, 1 rad, 1 MPa."""
    return np.array([1.0, 10.0, 1.0, 1e6])


INITIAL_KEYS = {"speed": ("w_rad_s", "rad/s"), "angle": ("theta_rad", "rad")}


def initial_state(
    params: MotorParams, *, w_rad_s: float = 0.0, theta_rad: float = 0.0
) -> np.ndarray:
    """State at rest (spool centred, no load pressure) unless a speed is given."""
    return np.array([0.0, w_rad_s, theta_rad, 0.0])


# The effects this plant's kernel reads: the first ten of the library, so that an effect
# added later is refused here until the kernel reads it.
EFFECTS = FIRST_EFFECTS
MECHANICS = {"force": "N*m", "velocity": "rad/s"}


def null_input(params: MotorParams) -> float:
    """The amplifier input of hydraulic null [V]: zero (seed 000 eq. 8)."""
    return 0.0


def effect_scales(params: MotorParams, input_v: float, sample_time_s: float) -> Scales:
    """Sizes the effect bounds scale with: stall torque V_m·P_s, the valve's flow at the
    rated input, and the no-load speed it gives."""
    flow = abs(params.valve_flow_gain_m3_s_v * params.amplifier_gain) * input_v
    return Scales(
        force=params.motor_displacement_m3_rad * params.supply_pressure_pa,
        velocity=flow / params.motor_displacement_m3_rad,
        flow=flow,
        pressure=params.supply_pressure_pa,
        input=input_v,
        bulk_modulus=params.bulk_modulus_pa,
        sample_time=sample_time_s,
        smoothing_velocity=params.coulomb_velocity_rad_s,  # as the seed's own T_f
    )
