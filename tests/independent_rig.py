"""An independent data generator for calibration tests (issue 12, item 5).

Seed 002's open-centre valve and asymmetric cylinder under P K=10 (Dinca & Corcau,
eq. 1-19), written again here with scipy's ``solve_ivp`` (LSODA, tight
tolerances) and none of the project's kernels, so that the effects follow formulations
the library did not write:

==================  ==================================================================
library effect      formulation here
==================  ==================================================================
coulomb_friction    LuGre bristle model (Canudas de Wit et al. 1995) with a seal
                    friction that grows with pressure: Fc = F0 + k·(p3 + p4)
stribeck_friction   LuGre with Fs/Fc = 1.5 and a Stribeck velocity of 5 mm/s
line_resistance     turbulent line loss Δp = k·|q|·q (laminar below 0.1 bar) in a 1 cm³ line node
                    per port
internal_leakage    laminar cross-port leakage Kl·(p3 − p4)
valve_deadband      smooth overlap: Δi_eff = Δi − w·tanh(Δi/w)
valve_bias          a null shift of the torque motor: Δi_eff = Δi + b
valve_lag           second-order spool, ωn = 2π·100 Hz, ζ = 0.7
transport_delay     a delay of 4.3 ms, not a whole number of 10 ms samples (exact:
                    the held command switches at k·T + d)
bulk_modulus        0.45 GPa (hoses, entrained air) in the chambers
supply_droop        a 6 l/min pump into a 0.2 l supply node with a relief valve at the
                    supply pressure (no ideal pressure source)
==================  ==================================================================

Sizes are the middle of docs/modelling.md's typical ranges (cylinder, 4.9 kN stall
force, 30 mA rated current). The generator returns a :class:`Measured` like a logger's.

``mismatch`` adds a model error of the size a real bench has, which no library effect
is (issue 28): ``adc`` (the position read and logged through 16 µm ADC codes),
``sensor_filter`` (a first-order position sensor of 1 ms, 160 Hz), ``orifice`` (the valve
orifices' laminar transition at 0.3 bar instead of 0.1) or ``flow_gain`` (the valve's
flow gain 5 % above the declared one).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp

from fuzzyservo.io.measured import Measured

# Seed 002 §4 (SI)
D_P, D_R = 0.03, 0.014
S3 = math.pi / 4 * D_P**2
S4 = S3 - math.pi / 4 * D_R**2
L30, L40 = 0.02, 0.145
MASS, VISCOUS = 1.0, 5.0
V1 = V2 = 3e-6
LPM = 1e-3 / 60
A_SLOT = 0.2221 * LPM / math.sqrt(1e5)
B_SLOT = 0.0600 * LPM / 1e-3 / math.sqrt(1e5)
I_CL, I_BIAS = 3.70e-3, 2.83e-3
E_OIL = 1.8e9
R_A = 47.2298e-6 / math.sqrt(1e5)
R_R = 69.0677e-6 / math.sqrt(1e5)
P_S, P_R = 70e5, 0.0
P_LAM = 0.1e5
P30 = P40 = 36e5
# loop: P K=10 at 100 Hz, 10 mA/V converter limited to ±30 mA, U_R = 5.75 V + 0.1936 V/cm
T_S, K_P, K_UI, I_MAX = 0.01, 10.0, 10e-3, 30e-3
FB_OFFSET, FB_GAIN = 5.75, 19.36  # V, V/m

MIDDLE = {
    "coulomb_friction": {"f0": 100.0, "k_p": 1e-5},  # 100 N + 1e-5·(p3+p4): ~170 N, 3.5 %
    "stribeck_friction": {"fc": 150.0, "fs": 225.0, "vs": 5e-3},
    "line_resistance": {"k": 2e15},  # 2 bar at 10 cm³/s
    "internal_leakage": {"kl": 1e-13},  # geometric middle of 1e-14..1e-12
    "valve_deadband": {"w": 0.5e-3},  # 1.7 % of rated current
    "valve_bias": {"b": 0.45e-3},  # 1.5 % of rated current
    "valve_lag": {"wn": 2 * math.pi * 100.0, "zeta": 0.7},
    "transport_delay": {"d": 4.3e-3},
    "bulk_modulus": {"e": 0.45e9},
    "supply_droop": {"qp": 1e-4, "vs": 0.2e-3},
}


MISMATCHES = ("adc", "sensor_filter", "orifice", "flow_gain")
ADC_CODE_M = 16e-6  # position code of the "adc" mismatch [m]
SENSOR_TAU_S = 1e-3  # "sensor_filter": a 160 Hz position sensor in a 100 Hz loop [s]
ORIFICE_P_LAM = 0.3e5  # laminar transition of the "orifice" mismatch [Pa]
FLOW_GAIN_ERROR = 1.05  # the "flow_gain" mismatch


BENCH = "adc+orifice+flow_gain"  # the bench-level mismatches together (a sensor filter aside)


def mismatch_kinds(mismatch: str | None) -> frozenset[str]:
    """The kinds of ``mismatch``: one of :data:`MISMATCHES`, several joined by ``+``
    (e.g. :data:`BENCH`), or None."""
    kinds = frozenset(mismatch.split("+")) if mismatch else frozenset()
    unknown = kinds - set(MISMATCHES)
    if unknown:
        raise ValueError(f"mismatch must be made of {MISMATCHES}, but got {mismatch!r}")
    return kinds


def _sqrt_flow(k: float, dp: float, p_lam: float = P_LAM) -> float:
    return k * dp / math.sqrt(math.sqrt(dp * dp + p_lam * p_lam))


def _reference(t: float) -> float:
    """Seed 002's pulses: 6.2 V, +1 V from 2 s for 5 s every 10 s."""
    return 6.2 + (1.0 if t >= 2.0 and ((t - 2.0) % 10.0) < 5.0 else 0.0)


class _Plant:
    """States: y, v, p1, p2, p3, p4, then the effect's own (LuGre z, spool x and ẋ,
    line-node pressures, supply-node pressure)."""

    def __init__(self, effect: str | None, params: dict[str, float], mismatch: str | None = None):
        kinds = mismatch_kinds(mismatch)
        self.effect = effect
        self.p = params
        self.e = params["e"] if effect == "bulk_modulus" else E_OIL
        self.mismatch = kinds
        self.p_lam = ORIFICE_P_LAM if "orifice" in kinds else P_LAM
        self.b_slot = B_SLOT * (FLOW_GAIN_ERROR if "flow_gain" in kinds else 1.0)

    def sensed(self, x: np.ndarray) -> float:
        """The position the sensor gives (read by the loop and logged) [m]."""
        y = x[-1] if "sensor_filter" in self.mismatch else x[0]
        if "adc" in self.mismatch:
            y = ADC_CODE_M * math.floor(y / ADC_CODE_M + 0.5)
        return y

    def x0(self) -> np.ndarray:
        x = [0.0, 0.0, P_S, P_R, P30, P40]
        if self.effect in ("coulomb_friction", "stribeck_friction"):
            x.append(0.0)
        elif self.effect == "valve_lag":
            x += [0.0, 0.0]
        elif self.effect == "line_resistance":
            x += [P30, P40]
        elif self.effect == "supply_droop":
            x.append(P_S)
        if "sensor_filter" in self.mismatch:
            x.append(0.0)
        return np.array(x)

    def current(self, i: float) -> float:
        di = i - I_BIAS
        if self.effect == "valve_deadband":
            w = self.p["w"]
            di = di - w * math.tanh(di / w)
        elif self.effect == "valve_bias":
            di = di + self.p["b"]
        return di

    def rhs(self, t: float, x: np.ndarray, i: float) -> np.ndarray:
        y, v, p1, p2, p3, p4 = x[:6]
        dx = np.zeros_like(x)
        di = self.current(i)
        if self.effect == "valve_lag":  # spool position in current units
            wn, zeta = self.p["wn"], self.p["zeta"]
            xs, vs_ = x[6], x[7]
            dx[6] = vs_
            dx[7] = wn * wn * (di - xs) - 2 * zeta * wn * vs_
            di = xs
        c14 = max(A_SLOT + self.b_slot * di, 0.0) if di > -I_CL else 0.0
        c23 = max(A_SLOT - self.b_slot * di, 0.0) if di < I_CL else 0.0
        ps = x[6] if self.effect == "supply_droop" else P_S
        qa = _sqrt_flow(R_A, ps - p1)
        qr = _sqrt_flow(R_R, p2 - P_R)
        if self.effect == "line_resistance":
            pa_, pb_ = x[6], x[7]  # line-node pressures at the valve ports
        else:
            pa_, pb_ = p3, p4
        q1 = _sqrt_flow(c14, p1 - pa_, self.p_lam)
        q2 = _sqrt_flow(c23, pa_ - p2, self.p_lam)
        q3 = _sqrt_flow(c23, p1 - pb_, self.p_lam)
        q4 = _sqrt_flow(c14, pb_ - p2, self.p_lam)
        qa3, qb4 = q1 - q2, q3 - q4  # flow into chamber 3 / 4 from the valve
        if self.effect == "line_resistance":
            k, v_line = self.p["k"], 1e-6

            def turbulent(dp: float) -> float:  # Δp = k·|q|·q, laminar below 0.1 bar
                return dp / math.sqrt(k * math.sqrt(dp * dp + P_LAM * P_LAM))

            q_a3 = turbulent(pa_ - p3)
            q_b4 = turbulent(pb_ - p4)
            dx[6] = self.e / v_line * (qa3 - q_a3)
            dx[7] = self.e / v_line * (qb4 - q_b4)
            qa3, qb4 = q_a3, q_b4
        q_leak = self.p["kl"] * (p3 - p4) if self.effect == "internal_leakage" else 0.0
        friction = 0.0
        if self.effect in ("coulomb_friction", "stribeck_friction"):
            z = x[6]
            if self.effect == "coulomb_friction":
                fc = self.p["f0"] + self.p["k_p"] * (p3 + p4)
                g = fc
            else:
                fc = self.p["fc"]
                g = fc + (self.p["fs"] - fc) * math.exp(-((v / self.p["vs"]) ** 2))
            sigma0 = 1e7  # N/m bristle stiffness: 17 µm of pre-sliding at 170 N
            sigma1 = 2.0 * math.sqrt(sigma0 * MASS)  # critically damped bristles
            dz = v - sigma0 * abs(v) * z / g
            dx[6] = dz
            friction = sigma0 * z + sigma1 * dz
        if self.effect == "supply_droop":  # pump into a supply node with a relief valve
            relief = 1e-9 * max(x[6] - P_S, 0.0)  # m³/(s·Pa): a stiff relief at 70 bar
            dx[6] = self.e / self.p["vs"] * (self.p["qp"] - qa - relief)
        v3 = S3 * (L30 + y)
        v4 = S4 * (L40 - y)
        dx[0] = v
        dx[1] = (p3 * S3 - p4 * S4 - VISCOUS * v - friction) / MASS
        dx[2] = self.e / V1 * (qa - q1 - q3)
        dx[3] = self.e / V2 * (q2 + q4 - qr)
        # the seed's mass form (eq. 8-9), as the seed-002 rig: flows are volumes at
        # reference density, so the displacement flow carries the compression (1 + p/E)
        dx[4] = self.e / v3 * (qa3 - q_leak - S3 * v * (1.0 + p3 / self.e))
        dx[5] = self.e / v4 * (qb4 + q_leak + S4 * v * (1.0 + p4 / self.e))
        if "sensor_filter" in self.mismatch:
            dx[-1] = (y - x[-1]) / SENSOR_TAU_S
        return dx


def independent_run(
    effect: str | None,
    noise: dict[str, float],
    *,
    params: dict[str, float] | None = None,
    seed: int = 0,
    duration_s: float = 22.0,
    mismatch: str | None = None,
) -> Measured:
    """Seed-002 P K=10 pulses with ``effect`` (a key of :data:`MIDDLE`, or None) at
    ``params`` (default: the middle of the typical range), sampled at 100 Hz, with white
    noise of ``noise`` (signal -> σ, SI) on the recorded channels, and the model error
    ``mismatch`` (one of :data:`MISMATCHES`, or None)."""
    (data,) = independent_draws(
        effect, noise, (seed,), params=params, duration_s=duration_s, mismatch=mismatch
    )
    return data


def independent_draws(
    effect: str | None,
    noise: dict[str, float],
    seeds: tuple[int, ...],
    *,
    params: dict[str, float] | None = None,
    duration_s: float = 22.0,
    mismatch: str | None = None,
) -> list[Measured]:
    """:func:`independent_run` with each noise seed of ``seeds``: one simulation."""
    plant = _Plant(effect, dict(params or MIDDLE.get(effect, {})), mismatch)
    delay = plant.p.get("d", 0.0) if effect == "transport_delay" else 0.0
    n = round(duration_s / T_S)
    t = np.arange(n) * T_S
    x = plant.x0()
    rows = np.empty((n, 6))
    refs = np.empty(n)
    currents = np.empty(n)
    i_prev = I_BIAS
    for k in range(n):
        rows[k] = x[:6]
        rows[k, 0] = x[-1] if "sensor_filter" in mismatch_kinds(mismatch) else x[0]
        ref = _reference(t[k])
        u = K_P * (ref - (FB_OFFSET + FB_GAIN * plant.sensed(x)))
        u = min(max(u, -10.0), 10.0)
        i_cmd = min(max(K_UI * u, -I_MAX), I_MAX)
        refs[k], currents[k] = ref, i_cmd
        # the command held over [t_k, t_k + T); a delay d switches it at t_k + d instead
        pieces = [(t[k], t[k] + T_S, i_cmd)]
        if delay > 0.0:
            pieces = [(t[k], t[k] + delay, i_prev), (t[k] + delay, t[k] + T_S, i_cmd)]
        for a, b, i_hold in pieces:
            sol = solve_ivp(
                plant.rhs, (a, b), x, method="LSODA", args=(i_hold,), rtol=1e-7, atol=_atol(x)
            )
            if not sol.success:
                raise RuntimeError(f"independent run failed at {a:.3f} s: {sol.message}")
            x = sol.y[:, -1]
        i_prev = i_cmd
    return [_record(t, rows, refs, currents, noise, seed, mismatch, effect) for seed in seeds]


def _record(t, rows, refs, currents, noise, seed, mismatch, effect) -> Measured:
    """One logged record of a simulated run: its states ``rows`` with noise of ``seed``."""
    n = t.size
    rng = np.random.default_rng(seed)
    names = {"y": 0, "p_s": 2, "p_t": 3, "p_a": 4, "p_b": 5}  # the rig's names of p1..p4
    signals = {"ref": (refs - FB_OFFSET) / FB_GAIN, "i": currents}
    units = {"ref": "m", "i": "A"}
    for name, sigma in noise.items():
        signals[name] = rows[:, names[name]] + rng.normal(0.0, sigma, n)
        if name == "y" and "adc" in mismatch_kinds(
            mismatch
        ):  # the logger reads the noisy sensor's codes
            signals[name] = ADC_CODE_M * np.floor(signals[name] / ADC_CODE_M + 0.5)
        units[name] = "m" if name == "y" else "Pa"
    return Measured(
        t=t,
        signals=signals,
        units=units,
        source=f"independent seed-002 generator, {effect or 'no effect'}",
        sample_period_s=T_S,
    )


def _atol(x: np.ndarray) -> np.ndarray:
    scale = np.full(x.size, 1.0)  # pressures [Pa]: 1 Pa
    scale[0], scale[1] = 1e-8, 1e-7  # y [m], v [m/s]
    if x.size > 6 and abs(x[6]) < 1.0:  # LuGre z [m] or spool [A]
        scale[6:] = 1e-10
    return scale
