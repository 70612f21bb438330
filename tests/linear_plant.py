"""A linear test plant for the loop analysis tests: a force lag driving a mass-spring-damper.

    τ·dF/dt = k_f·u − F,   m·dv/dt = F − c·v − k·y − f_load,   dy/dt = v

so ``Y(s)/U(s) = k_f / ((τs + 1)(m s² + c s + k))``. Not a product plant: it exists so
that the measured margins and frequency response can be held against python-control.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fuzzyservo._jit import njit
from fuzzyservo.components.effects import EffectParams
from fuzzyservo.params import param_index, quantity

STATES = ("force", "y", "v")
SIGNALS = ("y_out", "v_out")
SIGNAL_UNITS = {"y_out": "m", "v_out": "m/s"}
INPUT = ("u_force", "V")
LOAD = ("f_load", "N")
INITIAL_KEYS = {"position": ("y_m", "m")}


@dataclass(frozen=True)
class LinearParams(EffectParams):
    force_gain: float = quantity("force_gain", "N/V", positive=True)
    force_lag_s: float = quantity("force_lag", "s", positive=True)
    mass_kg: float = quantity("mass", "kg", positive=True)
    damping: float = quantity("damping", "N*s/m", nonnegative=True)
    stiffness: float = quantity("stiffness", "N/m", nonnegative=True)


PARAMS = LinearParams
P = param_index(PARAMS)


@njit(cache=True)
def rhs(x: np.ndarray, u: float, f_load: float, p: np.ndarray, dx: np.ndarray) -> None:
    kf, tau, m = p[P.force_gain], p[P.force_lag_s], p[P.mass_kg]
    c, k = p[P.damping], p[P.stiffness]
    dx[0] = (kf * u - x[0]) / tau
    dx[1] = x[2]
    dx[2] = (x[0] - c * x[2] - k * x[1] - f_load) / m


@njit(cache=True)
def signals(x: np.ndarray, u: float, f_load: float, p: np.ndarray, out: np.ndarray) -> None:
    out[0] = x[1]
    out[1] = x[2]


@njit(cache=True)
def in_end_stop(x: np.ndarray, p: np.ndarray) -> bool:
    return False


def state_scale(params: LinearParams) -> np.ndarray:
    return np.array([1e-6, 1e-8, 1e-7])


def typical_state(params: LinearParams) -> np.ndarray:
    return np.array([1.0, 1e-3, 1e-2])


def initial_state(params: LinearParams, *, y_m: float = 0.0) -> np.ndarray:
    return np.array([params.stiffness * y_m, y_m, 0.0])
