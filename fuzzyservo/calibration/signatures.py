"""What each missing effect's residual looks like: one regressor per effect, built from
the nominal model's own signals (docs/modelling.md "Measured data: what the residual tells you").

The regression of the residual on these is a diagnostic shown in the report next to the
candidate fits; the decision itself rests on the fits.
"""

from __future__ import annotations

import numpy as np

from fuzzyservo.calibration.residuals import derivative, lagged
from fuzzyservo.components.effects import deadband
from fuzzyservo.rig import Rig
from fuzzyservo.simulation.result import SimResult


def _first(result: SimResult, names: tuple[str, ...]) -> np.ndarray | None:
    for name in names:
        if name in result.signals:
            return np.asarray(result.signals[name], dtype=float)
    return None


def signatures(result: SimResult, rig: Rig) -> dict[str, np.ndarray]:
    """Effect name -> its regressor on the result's time grid (effects the plant lacks
    the signals for are left out)."""
    dt = result.sample_time_s
    u = np.asarray(result.actuator, dtype=float)
    out: dict[str, np.ndarray] = {}
    v = _first(result, ("v", "w"))
    scales = rig.scales()
    if v is not None:
        vc = rig.params.friction_smoothing_velocity_si or scales.smoothing_velocity
        out["coulomb_friction"] = np.tanh(v / vc)  # tanh(v/vc)
        vs = 0.05 * scales.velocity
        out["stribeck_friction"] = np.exp(-((v / vs) ** 2)) * np.sign(v)  # exp(−(v/vs)²)·sign(v)
    if "q1" in result.signals and "q2" in result.signals:  # the open-centre valve's slots
        q = result.signals["q1"] - result.signals["q2"]
    else:
        q = _first(result, ("q_a",))  # a 4-way valve: the flow out of port A
    if q is not None:
        out["line_resistance"] = np.abs(q) * q  # |q|·q
    if "p_a" in result.signals and "p_b" in result.signals:
        dp = result.signals["p_a"] - result.signals["p_b"]
        pa = result.signals["p_a"]
        out["internal_leakage"] = dp  # pA − pB
        out["bulk_modulus"] = derivative(pa, dt)  # ṗA
    null = rig.plant.null_input(rig.params)
    out["valve_deadband"] = deadband_signature(u, null, 0.02 * scales.input)  # dz(u) − u
    out["valve_bias"] = np.ones_like(u)  # constant on u
    out["valve_lag"] = derivative(u, dt)  # u̇
    out["transport_delay"] = derivative(np.asarray(result.output, dtype=float), dt)  # ẏ
    supply = _first(result, ("q_in", "q_supply"))  # into the supply node, or drawn from it
    if supply is None and q is not None:
        supply = np.abs(q)
    if supply is not None:
        out["supply_droop"] = np.abs(supply)  # Σ|q|
    out["transport_delay_u"] = lagged(u, 1) - u  # u(t − 1) − u(t)
    return out


def deadband_signature(u: np.ndarray, null: float, width: float) -> np.ndarray:
    """``dz(u) − u`` for a dead band of half-width ``width`` around ``null``."""
    return np.array([deadband(float(x), null, width) for x in u]) - u


def mean_share(residuals: dict[str, np.ndarray]) -> float:
    """Share of residual energy in its mean (a null bias leaves a constant offset)."""
    num = den = 0.0
    for e in residuals.values():
        e = e[np.isfinite(e)]
        if e.size:
            num += e.size * float(np.mean(e)) ** 2 / max(float(np.var(e) + np.mean(e) ** 2), 1e-300)
            den += e.size
    return num / den if den else 0.0
