"""Dispatch from a plant's ``kind`` code to its compiled right-hand side and signals.

One place lists every plant family the compiled loop knows; a new plant adds its
three kernels here. Dispatch on an integer keeps the loop cacheable by numba.
"""

from __future__ import annotations

import math

import numpy as np

from fuzzyservo._jit import njit
from fuzzyservo.plants import ahc_cylinder, ahc_motor, cylinder, hydroprax, motor

KIND_CYLINDER = 0
KIND_MOTOR = 1
KIND_HYDROPRAX = 2
KIND_AHC_CYLINDER = 3
KIND_AHC_MOTOR = 4


@njit(cache=True)
def plant_rhs(
    kind: int, x: np.ndarray, u: float, load: float, p: np.ndarray, dx: np.ndarray
) -> None:
    """dx/dt of plant ``kind`` for input ``u`` and load ``load``; writes ``dx``."""
    if kind == KIND_CYLINDER:
        cylinder.rhs(x, u, load, p, dx)
    elif kind == KIND_MOTOR:
        motor.rhs(x, u, load, p, dx)
    elif kind == KIND_HYDROPRAX:
        hydroprax.rhs(x, u, load, p, dx)
    elif kind == KIND_AHC_CYLINDER:
        ahc_cylinder.rhs(x, u, load, p, dx)
    elif kind == KIND_AHC_MOTOR:
        ahc_motor.rhs(x, u, load, p, dx)
    else:
        dx[:] = np.nan


@njit(cache=True)
def plant_signals(
    kind: int, x: np.ndarray, u: float, load: float, p: np.ndarray, out: np.ndarray
) -> None:
    """All named signals of plant ``kind`` at state ``x``; writes ``out``."""
    if kind == KIND_CYLINDER:
        cylinder.signals(x, u, load, p, out)
    elif kind == KIND_MOTOR:
        motor.signals(x, u, load, p, out)
    elif kind == KIND_HYDROPRAX:
        hydroprax.signals(x, u, load, p, out)
    elif kind == KIND_AHC_CYLINDER:
        ahc_cylinder.signals(x, u, load, p, out)
    elif kind == KIND_AHC_MOTOR:
        ahc_motor.signals(x, u, load, p, out)
    else:
        out[:] = np.nan


@njit(cache=True)
def plant_signal_table(
    kind: int,
    states: np.ndarray,
    inputs: np.ndarray,
    loads: np.ndarray,
    p: np.ndarray,
    out: np.ndarray,
) -> None:
    """Signals of every recorded sample (rows of ``states``); rows with a NaN state stay NaN."""
    row = np.empty(out.shape[1])
    for k in range(states.shape[0]):
        finite = True
        for i in range(states.shape[1]):
            if not math.isfinite(states[k, i]):
                finite = False
        if finite:
            plant_signals(kind, states[k], inputs[k], loads[k], p, row)
            out[k, :] = row
        else:
            out[k, :] = np.nan


@njit(cache=True)
def plant_in_end_stop(kind: int, x: np.ndarray, p: np.ndarray) -> bool:
    """True when the plant sits beyond a mechanical end stop."""
    if kind == KIND_CYLINDER:
        return cylinder.in_end_stop(x, p)
    if kind == KIND_MOTOR:
        return motor.in_end_stop(x, p)
    if kind == KIND_HYDROPRAX:
        return hydroprax.in_end_stop(x, p)
    if kind == KIND_AHC_CYLINDER:
        return ahc_cylinder.in_end_stop(x, p)
    if kind == KIND_AHC_MOTOR:
        return ahc_motor.in_end_stop(x, p)
    return False
