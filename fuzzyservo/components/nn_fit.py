"""Training the seed-003 valve network: Levenberg-Marquardt on (P_S, U_C, P_A, P_B) → (Q_A, Q_B).

Pure numerics (no files): the data come in as an array, the weights go out as the flat
vector of :mod:`fuzzyservo.components.valves`. As the seed (§3: MATLAB ``trainlm``,
``tansig`` hidden layer, ``purelin`` output), inputs and outputs are scaled to [−1, 1]
(``mapminmax``); several random restarts guard against a poor local minimum, and the
restart with the lowest validation error wins.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from fuzzyservo.components.valves import (
    NN_IN_OFFSET,
    NN_IN_SCALE,
    NN_INPUTS,
    NN_OUT_OFFSET,
    NN_OUT_SCALE,
    NN_OUTPUTS,
    NN_SIZE,
    NN_W1,
    nn_forward_batch,
)


@dataclass(frozen=True)
class NetworkFit:
    """Trained weights (flat vector, :mod:`~fuzzyservo.components.valves` layout) and the
    RMS error of each output [units of the data] on the training and validation rows."""

    weights: np.ndarray
    train_rms: tuple[float, ...]
    validation_rms: tuple[float, ...]
    n_train: int
    n_validation: int
    restarts: int
    seed: int


def _minmax(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = values.min(axis=0), values.max(axis=0)
    scale = 0.5 * (hi - lo)
    return 0.5 * (hi + lo), np.where(scale > 0, scale, 1.0)


def predict(weights: np.ndarray, inputs: np.ndarray) -> np.ndarray:
    """Network outputs (n×2) for input rows (n×4)."""
    out = np.empty((inputs.shape[0], NN_OUTPUTS))
    nn_forward_batch(np.ascontiguousarray(weights), np.ascontiguousarray(inputs), out)
    return out


def rms(weights: np.ndarray, inputs: np.ndarray, targets: np.ndarray) -> tuple[float, ...]:
    """RMS error of each output."""
    err = predict(weights, inputs) - targets
    return tuple(float(v) for v in np.sqrt(np.mean(err**2, axis=0)))


def fit_valve_network(
    data: np.ndarray,
    *,
    restarts: int = 6,
    validation_fraction: float = 0.25,
    seed: int = 0,
    max_evaluations: int = 4000,
    progress: Callable[[int], None] | None = None,
) -> NetworkFit:
    """Fit the 4-5-2 network to ``data`` rows (P_S, U_C, P_A, P_B, Q_A, Q_B), any consistent units.

    A seeded random split keeps ``validation_fraction`` of the rows out of training;
    each restart starts from random weights (seeded) and runs
    ``scipy.optimize.least_squares(method="lm")`` on the scaled output errors.
    ``progress`` is called with the number of each finished restart.
    """
    data = np.asarray(data, dtype=np.float64)
    if data.ndim != 2 or data.shape[1] != NN_INPUTS + NN_OUTPUTS:
        raise ValueError(
            f"data: must have {NN_INPUTS + NN_OUTPUTS} columns (P_S, U_C, P_A, P_B, Q_A, Q_B), "
            f"got shape {data.shape}"
        )
    if not 0 < validation_fraction < 1:
        raise ValueError(
            f"validation_fraction: must lie in (0, 1), got {validation_fraction}; e.g. 0.25"
        )
    if restarts < 1:
        raise ValueError(f"restarts: must be >= 1, got {restarts}")
    free = NN_OUT_OFFSET - NN_W1
    n_val = round(validation_fraction * data.shape[0])
    n_train = data.shape[0] - n_val
    if n_train < free or n_val < 1:
        raise ValueError(
            f"data: {data.shape[0]} rows are too few for {free} weights and a validation set; "
            f"give at least {int(np.ceil(free / (1 - validation_fraction))) + 1} rows"
        )
    rng = np.random.default_rng(seed)
    order = rng.permutation(data.shape[0])
    train, val = data[order[:n_train]], data[order[n_train:]]
    x_train, t_train = train[:, :NN_INPUTS], train[:, NN_INPUTS:]
    x_val, t_val = val[:, :NN_INPUTS], val[:, NN_INPUTS:]

    template = np.zeros(NN_SIZE)
    in_off, in_scale = _minmax(x_train)
    out_off, out_scale = _minmax(t_train)
    template[NN_IN_OFFSET : NN_IN_OFFSET + NN_INPUTS] = in_off
    template[NN_IN_SCALE : NN_IN_SCALE + NN_INPUTS] = in_scale
    template[NN_OUT_OFFSET : NN_OUT_OFFSET + NN_OUTPUTS] = out_off
    template[NN_OUT_SCALE : NN_OUT_SCALE + NN_OUTPUTS] = out_scale
    out = np.empty((n_train, NN_OUTPUTS))
    x_train_c = np.ascontiguousarray(x_train)

    def residual(w: np.ndarray) -> np.ndarray:
        full = template.copy()
        full[NN_W1:NN_OUT_OFFSET] = w
        nn_forward_batch(full, x_train_c, out)
        return ((out - t_train) / out_scale).ravel()

    best, best_score = None, np.inf
    for k in range(restarts):
        if k and progress is not None:
            progress(k)
        w0 = rng.normal(0.0, 0.5, free)
        sol = least_squares(residual, w0, method="lm", max_nfev=max_evaluations)
        full = template.copy()
        full[NN_W1:NN_OUT_OFFSET] = sol.x
        score = float(np.sum(((predict(full, x_val) - t_val) / out_scale) ** 2))
        if np.isfinite(score) and score < best_score:
            best, best_score = full, score
    if progress is not None:
        progress(restarts)
    if best is None:
        raise ValueError("data: every restart diverged; check the data for outliers")
    return NetworkFit(
        weights=best,
        train_rms=rms(best, x_train, t_train),
        validation_rms=rms(best, x_val, t_val),
        n_train=n_train,
        n_validation=n_val,
        restarts=restarts,
        seed=seed,
    )
