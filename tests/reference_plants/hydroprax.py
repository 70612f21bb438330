"""Proportional directional control valve + single-rod cylinder with a spring load, fed by a
fixed pump with a relief valve: the Hydroprax 2 prop bench of seed 003 (Table 1).

States (SI): ``y`` piston position from the retracted end [m], ``v`` velocity [m/s],
``p_s`` supply pressure between pump and valve, ``p_a`` and ``p_b`` chamber pressures [Pa].

    dp_s/dt = β/V_t · (Q_pump − Q_relief(p_s) − Q_L)                       (eq. 1)
    dp_a/dt = β/V_a · (Q_A − A_a·v),  dp_b/dt = β/V_b · (Q_B + A_b·v)      (eq. 3-4)
    M_p·dv/dt = p_a·A_a − p_b·A_b − F_vo·v − F_co·tanh(v/v_c) − K_L·y
                − F_load + F_stop                                          (eq. 5-6)

``Q_A``, ``Q_B`` are the valve flows into chambers A and B, ``Q_L`` the flow the valve
draws from the supply. The seed clamps p_s with a limited integrator; here the relief
valve is a steep, regularised characteristic: it opens at the cracking pressure and
passes the whole pump flow at the nominal supply pressure,
``Q_relief = K_r·(d + sqrt(d² + δ²))/2`` with d = p_s − p_crack, K_r = Q_pump/(p_nom − p_crack),
so a stroke that draws more than Q_pump lets p_s sag and the relief closes.

The valve (plant parameter ``valve_model``, unit 1):

1. the measured characteristic (eq. 7, 4th-order polynomial in U_C, ±6 V) scaled by the
   orifice law ``sqrt(Δp/Δp_nom)`` on each metering edge of a critically lapped 4-way valve;
2. the seed's feed-forward network (P_S, U_C, P_A, P_B → Q_A, Q_B; 4-5-2, tanh/linear),
   whose weights are appended to the parameter vector (``nn_weights``); the supply flow
   is Q_A for U_C ≥ 0 and Q_B otherwise (the edge P→A or P→B that is open);
3. the ideal orifice valve ``Q = C·(U_C/U_max)·sqrt(Δp)`` on the same four edges.

A volume never reaches zero (dead volumes, floored), and a stiff spring-damper end stop
acts beyond 0 and the stroke (as :mod:`fuzzyservo.plants.cylinder`). Leakage is neglected,
as in the seed (§2-3-2).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from fuzzyservo._jit import njit
from fuzzyservo.components.effects import EffectParams
from fuzzyservo.components.valves import NN_SIZE, nn_forward, polynomial_flow
from fuzzyservo.params import name_index, pack, param_index, quantity, vector, vector_offset
from reference_plants.kernels import circle_area, four_way_flows

STATES = ("y", "v", "p_s", "p_a", "p_b")
SIGNALS = (
    "y", "v", "p_s", "p_a", "p_b", "q_pump", "q_relief", "q_supply",
    "q_a", "q_b", "q_tank", "f_friction", "f_stop",
)  # fmt: skip
SIGNAL_UNITS = {
    "y": "m", "v": "m/s", "p_s": "Pa", "p_a": "Pa", "p_b": "Pa",
    "q_pump": "m^3/s", "q_relief": "m^3/s", "q_supply": "m^3/s", "q_a": "m^3/s",
    "q_b": "m^3/s", "q_tank": "m^3/s", "f_friction": "N", "f_stop": "N",
}  # fmt: skip
INPUT = ("u_c", "V")  # the plant input: control voltage of the valve amplifier
LOAD = ("f_load", "N")  # external force opposing extension (+y)
PRESSURES = ("p_s", "p_a", "p_b")  # gauge chamber pressures (simulation/validity.py)

VALVE_POLYNOMIAL = 1
VALVE_NETWORK = 2
VALVE_ORIFICE = 3
VALVE_MODELS = {
    VALVE_POLYNOMIAL: "polynomial",
    VALVE_NETWORK: "neural_network",
    VALVE_ORIFICE: "orifice",
}


@dataclass(frozen=True)
class HydropraxParams(EffectParams):
    """Seed 003 Table 1 and the values it lacks, SI units (the rig file gives the sources)."""

    piston_area_m2: float = quantity("piston_area", "m^2", positive=True)
    rod_diameter_m: float = quantity("rod_diameter", "m", nonnegative=True)
    stroke_m: float = quantity("stroke", "m", positive=True)
    piston_mass_kg: float = quantity("piston_mass", "kg", positive=True)
    viscous_friction_n_s_m: float = quantity("viscous_friction", "N*s/m", nonnegative=True)
    coulomb_friction_n: float = quantity("coulomb_friction", "N", nonnegative=True)
    coulomb_velocity_m_s: float = quantity("coulomb_velocity", "m/s", positive=True)
    load_stiffness_n_m: float = quantity("load_stiffness", "N/m", nonnegative=True)
    bulk_modulus_pa: float = quantity("bulk_modulus", "Pa", positive=True)
    supply_volume_m3: float = quantity("supply_volume", "m^3", positive=True)
    pump_flow_m3_s: float = quantity("pump_flow", "m^3/s", positive=True)
    supply_pressure_pa: float = quantity("supply_pressure", "Pa", positive=True)
    relief_cracking_pressure_pa: float = quantity("relief_cracking_pressure", "Pa", positive=True)
    relief_knee_pa: float = quantity("relief_knee", "Pa", positive=True)
    tank_pressure_pa: float = quantity("tank_pressure", "Pa", nonnegative=True)
    dead_volume_a_m3: float = quantity("dead_volume_a", "m^3", positive=True)
    dead_volume_b_m3: float = quantity("dead_volume_b", "m^3", positive=True)
    valve_model: float = quantity(
        "valve_model",
        "1",
        minimum=1,
        maximum=3,
        doc="give 1 (polynomial, eq. 7), 2 (neural network) or 3 (ideal orifice)",
    )
    control_voltage_max_v: float = quantity("control_voltage_max", "V", positive=True)
    flow_c0_m3_s: float = quantity("flow_c0", "m^3/s")
    flow_c1_m3_s_v: float = quantity("flow_c1", "m^3/(s*V)")
    flow_c2_m3_s_v2: float = quantity("flow_c2", "m^3/(s*V^2)")
    flow_c3_m3_s_v3: float = quantity("flow_c3", "m^3/(s*V^3)")
    flow_c4_m3_s_v4: float = quantity("flow_c4", "m^3/(s*V^4)")
    nominal_pressure_drop_pa: float = quantity("nominal_pressure_drop", "Pa", positive=True)
    orifice_coefficient_m3_s_sqrtpa: float = quantity(
        "orifice_coefficient", "m^3/(s*sqrt(Pa))", positive=True
    )
    laminar_pressure_pa: float = quantity("laminar_pressure", "Pa", positive=True)
    end_stop_stiffness_n_m: float = quantity("end_stop_stiffness", "N/m", positive=True)
    end_stop_damping_n_s_m: float = quantity("end_stop_damping", "N*s/m", nonnegative=True)
    nn_weights: tuple[float, ...] = vector(
        "nn_weights",
        NN_SIZE,
        fmt="valve_network",
        doc="name the JSON file written by `fuzzyservo fit-valve`",
    )

    def __post_init__(self) -> None:
        if self.valve_model not in VALVE_MODELS:
            raise ValueError(
                f"valve_model: must be one of {sorted(VALVE_MODELS)} "
                f"({', '.join(f'{k} {v}' for k, v in VALVE_MODELS.items())}), "
                f"got {self.valve_model!r}; give the integer"
            )
        if self.valve_model == VALVE_NETWORK and not self.nn_weights:
            raise ValueError(
                "nn_weights: valve_model 2 (neural network) needs trained weights; "
                "name the JSON file written by `fuzzyservo fit-valve` under nn_weights"
            )
        if circle_area(self.rod_diameter_m) >= self.piston_area_m2:
            raise ValueError(
                f"rod_diameter: the rod ({self.rod_diameter_m} m) must be thinner than the "
                f"piston (area {self.piston_area_m2} m^2); check both values"
            )
        if not self.relief_cracking_pressure_pa < self.supply_pressure_pa:
            raise ValueError(
                f"relief_cracking_pressure: `relief_cracking_pressure < supply_pressure` must "
                f"hold, but got ({self.relief_cracking_pressure_pa} Pa, {self.supply_pressure_pa} Pa); "
                f"the relief passes the whole pump flow at the nominal supply pressure"
            )

    @property
    def area_a_m2(self) -> float:
        """Piston-side area A_a = A_p [m²] (seed 003 Table 1)."""
        return self.piston_area_m2

    @property
    def area_b_m2(self) -> float:
        """Rod-side annulus A_b = A_p − π·d_rod²/4 [m²]."""
        return self.piston_area_m2 - circle_area(self.rod_diameter_m)

    @property
    def stroke_limits_m(self) -> tuple[float, float]:
        """Positions where the end stops engage."""
        return (0.0, self.stroke_m)

    @property
    def relief_gain_m3_s_pa(self) -> float:
        """K_r = Q_pump / (p_nom − p_crack) [m³/(s·Pa)]."""
        return self.pump_flow_m3_s / (self.supply_pressure_pa - self.relief_cracking_pressure_pa)

    def resting_supply_pressure_pa(self) -> float:
        """p_s where the relief passes the whole pump flow (no valve flow): the root of
        K_r·(d + sqrt(d² + δ²))/2 = Q_pump, d = (a² − δ²)/(2a) with a = 2·Q_pump/K_r."""
        a = 2.0 * self.pump_flow_m3_s / self.relief_gain_m3_s_pa
        return self.relief_cracking_pressure_pa + (a * a - self.relief_knee_pa**2) / (2.0 * a)


PARAMS = HydropraxParams
P = param_index(PARAMS)  # p[P.<field>]: positions generated from the dataclass
S = name_index(SIGNALS)  # out[S.<signal>]: positions generated from SIGNALS
X = name_index(STATES, "States")  # x[X.<state>], dx[X.<state>]
P_NN = vector_offset(HydropraxParams, "nn_weights")

# Chamber volumes never fall below this fraction of their dead volume (cylinder.py)
_MIN_VOLUME_FRACTION = 0.05


@njit(cache=True, inline="always")
def _evaluate(
    x: np.ndarray, u: float, f_load: float, p: np.ndarray, dx: np.ndarray, out: np.ndarray
) -> None:
    """The whole model in one flat function; writes dx/dt and, when ``out`` has room, SIGNALS."""
    y = x[X.y]
    v = x[X.v]
    ps = x[X.p_s]
    pa = x[X.p_a]
    pb = x[X.p_b]
    pt = p[P.tank_pressure_pa]
    aa = p[P.piston_area_m2]
    ab = aa - circle_area(p[P.rod_diameter_m])
    va = max(p[P.dead_volume_a_m3] + aa * y, _MIN_VOLUME_FRACTION * p[P.dead_volume_a_m3])
    vb = max(
        p[P.dead_volume_b_m3] + ab * (p[P.stroke_m] - y),
        _MIN_VOLUME_FRACTION * p[P.dead_volume_b_m3],
    )
    # valve (eq. 7 / Fig. 7 / ideal orifice)
    umax = p[P.control_voltage_max_v]
    uc = min(max(u, -umax), umax)
    vm = p[P.valve_model]
    if vm > 1.5 and vm < 2.5:
        q_a, q_b = nn_forward(p, P_NN, ps, uc, pa, pb)
        q_l = q_a if uc >= 0.0 else q_b
    else:
        if vm < 1.5:
            k = polynomial_flow(
                uc,
                umax,
                p[P.flow_c0_m3_s],
                p[P.flow_c1_m3_s_v],
                p[P.flow_c2_m3_s_v2],
                p[P.flow_c3_m3_s_v3],
                p[P.flow_c4_m3_s_v4],
            ) / math.sqrt(p[P.nominal_pressure_drop_pa])
        else:
            k = p[P.orifice_coefficient_m3_s_sqrtpa] * uc / umax
        q_pa, q_bt, q_pb, q_at = four_way_flows(k, ps, pa, pb, pt, p[P.laminar_pressure_pa])
        q_a = q_pa - q_at
        q_b = q_pb - q_bt
        q_l = q_pa + q_pb
    q_t = q_l - q_a - q_b
    # pump and relief (eq. 1)
    d = ps - p[P.relief_cracking_pressure_pa]
    kr = p[P.pump_flow_m3_s] / (p[P.supply_pressure_pa] - p[P.relief_cracking_pressure_pa])
    q_r = 0.5 * kr * (d + math.sqrt(d * d + p[P.relief_knee_pa] * p[P.relief_knee_pa]))
    # piston (eq. 6) with smooth Coulomb friction and the end stops
    f_fric = p[P.viscous_friction_n_s_m] * v + p[P.coulomb_friction_n] * math.tanh(
        v / p[P.coulomb_velocity_m_s]
    )
    f_stop = 0.0
    if y < 0.0:
        f_stop = -p[P.end_stop_stiffness_n_m] * y - (
            p[P.end_stop_damping_n_s_m] * v if v < 0.0 else 0.0
        )
    elif y > p[P.stroke_m]:
        f_stop = -p[P.end_stop_stiffness_n_m] * (y - p[P.stroke_m]) - (
            p[P.end_stop_damping_n_s_m] * v if v > 0.0 else 0.0
        )
    e = p[P.bulk_modulus_pa]
    dx[X.y] = v
    dx[X.v] = (pa * aa - pb * ab - f_fric - p[P.load_stiffness_n_m] * y - f_load + f_stop) / p[
        P.piston_mass_kg
    ]
    dx[X.p_s] = e / p[P.supply_volume_m3] * (p[P.pump_flow_m3_s] - q_r - q_l)
    dx[X.p_a] = e / va * (q_a - aa * v)
    dx[X.p_b] = e / vb * (q_b + ab * v)
    if out.size >= 13:
        out[S.y] = y
        out[S.v] = v
        out[S.p_s] = ps
        out[S.p_a] = pa
        out[S.p_b] = pb
        out[S.q_pump] = p[P.pump_flow_m3_s]
        out[S.q_relief] = q_r
        out[S.q_supply] = q_l
        out[S.q_a] = q_a
        out[S.q_b] = q_b
        out[S.q_tank] = q_t
        out[S.f_friction] = f_fric
        out[S.f_stop] = f_stop


@njit(cache=True, inline="always")
def rhs(x: np.ndarray, u: float, f_load: float, p: np.ndarray, dx: np.ndarray) -> None:
    """Right-hand side dx/dt of the seed-003 bench (module docstring, eq. 1-7).

    ``x`` states (STATES), ``u`` control voltage [V], ``f_load`` external force [N]
    opposing extension, ``p`` packed :class:`HydropraxParams`; writes ``dx``.
    """
    _evaluate(x, u, f_load, p, dx, dx)


@njit(cache=True)
def signals(x: np.ndarray, u: float, f_load: float, p: np.ndarray, out: np.ndarray) -> None:
    """Every signal of SIGNALS for state ``x``; writes ``out``."""
    dx = np.empty(x.size)
    _evaluate(x, u, f_load, p, dx, out)


@njit(cache=True)
def in_end_stop(x: np.ndarray, p: np.ndarray) -> bool:
    """True when the piston is beyond either end of its stroke."""
    return x[X.y] < 0.0 or x[X.y] > p[P.stroke_m]


def state_scale(params: HydropraxParams) -> np.ndarray:
    """Unit of local error per state: 1 µm, 1 mm/s and 1 kPa in each pressure."""
    return np.array([1e-6, 1e-3, 1e3, 1e3, 1e3])


def typical_state(params: HydropraxParams) -> np.ndarray:
    """Typical magnitude of each state (finite-difference increments): 1 mm, 0.1 m/s, 1 MPa."""
    return np.array([1e-3, 0.1, 1e6, 1e6, 1e6])


# Initial conditions a rig file may set: file key -> (keyword of initial_state, SI unit)
INITIAL_KEYS = {
    "position": ("y_m", "m"),
    "pressure_s": ("ps_pa", "Pa"),
    "pressure_a": ("pa_pa", "Pa"),
    "pressure_b": ("pb_pa", "Pa"),
}


def initial_state(
    params: HydropraxParams,
    *,
    y_m: float = 0.0,
    ps_pa: float | None = None,
    pa_pa: float | None = None,
    pb_pa: float | None = None,
) -> np.ndarray:
    """State at rest at ``y_m``: p_s where the relief passes the whole pump flow, p_b half
    of it, and p_a balancing the spring, p_a·A_a = p_b·A_b + K_L·y (unless given)."""
    ps = params.resting_supply_pressure_pa() if ps_pa is None else ps_pa
    pb = 0.5 * ps if pb_pa is None else pb_pa
    pa = (
        (pb * params.area_b_m2 + params.load_stiffness_n_m * y_m) / params.area_a_m2
        if pa_pa is None
        else pa_pa
    )
    return np.array([y_m, 0.0, ps, pa, pb])


def valve_flows(
    params: HydropraxParams, ps: np.ndarray, u: np.ndarray, pa: np.ndarray, pb: np.ndarray
) -> np.ndarray:
    """Valve flows (Q_A, Q_B) [m³/s] of the rig's valve model at each operating point (n×2)."""
    p = pack(params)
    out = np.empty(len(SIGNALS))
    x = initial_state(params, y_m=0.5 * params.stroke_m)
    flows = np.empty((np.size(ps), 2))
    for i, row in enumerate(np.broadcast(ps, u, pa, pb)):
        x[X.p_s], x[X.p_a], x[X.p_b] = row[0], row[2], row[3]
        signals(x, row[1], 0.0, p, out)
        flows[i] = out[S.q_a], out[S.q_b]
    return flows


def generate_valve_data(params: HydropraxParams, n: int, seed: int) -> np.ndarray:
    """``n`` operating points of valve model 1 (eq. 7 with the orifice law), SI columns
    (p_s, u_c, p_a, p_b, q_a, q_b): the data the seed measured on its bench, from the model.

    p_s uniform in [0.3, 1.05]·p_nom (sagged to nominal), U_C uniform in ±U_max,
    p_a and p_b uniform in [p_T, p_s]. Seeded: the same ``seed`` gives the same rows.
    """
    if n < 1:
        raise ValueError(f"n: must be >= 1, got {n}; ask for at least one sample")
    rng = np.random.default_rng(seed)
    poly = dataclasses.replace(params, valve_model=float(VALVE_POLYNOMIAL))
    pt = params.tank_pressure_pa
    ps = rng.uniform(0.3, 1.05, n) * params.supply_pressure_pa
    u = rng.uniform(-1.0, 1.0, n) * params.control_voltage_max_v
    pa = pt + rng.uniform(0.0, 1.0, n) * (ps - pt)
    pb = pt + rng.uniform(0.0, 1.0, n) * (ps - pt)
    return np.column_stack([ps, u, pa, pb, valve_flows(poly, ps, u, pa, pb)])
