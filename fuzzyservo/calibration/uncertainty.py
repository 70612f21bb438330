"""How well the data pin down each fitted value: a 95 % interval and an at-bound flag.

Linearised (Jacobian) confidence intervals, as MATLAB's ``nlgreyest`` reports a
parameter covariance: with ``e = (y − ŷ)/σ`` on the training part (``M`` samples over
all channels), the Fisher information of the parameters ``z`` (on the unit box of the
search) is ``JᵀJ`` with ``J = ∂e/∂z``; the covariance

    cov(z) = c · (M / M_eff) · (JᵀJ)⁻¹

inflates it by the training cost ``c`` (a model that leaves more than noise, c > 1,
is less sure of its values) and by the ratio of samples to effective samples, ``M_eff =
Σ_c N·(1 − ρ_c)/(1 + ρ_c)`` from each channel's lag-one residual autocorrelation
``ρ_c`` (correlated residuals carry less information; docs/modelling.md). The interval
``z ± 1.96·√cov_zz`` is mapped back through the search's scaling and clipped to the
bounds. A value within 0.1 % of the box of a bound is flagged ``at_bound``: the data
wanted it further out, and its interval is one-sided.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fuzzyservo.calibration.replay import Replay

Z95 = 1.959964  # two-sided 95 % normal quantile
AT_BOUND = 1e-3  # distance to a bound on the unit box that counts as "at the bound"


@dataclass(frozen=True)
class Estimate:
    """A fitted value [SI], its 95 % interval [SI] and whether it sits on a bound."""

    value: float
    interval: tuple[float, float]
    bounds: tuple[float, float]
    at_bound: bool


def effective_samples(replay: Replay, model: dict[str, np.ndarray]) -> tuple[int, float]:
    """Training samples and effective samples (AR(1) per channel), summed over channels."""
    part = slice(0, replay.split)
    total, effective = 0, 0.0
    for channel in replay.channels:
        e = (replay.measured(channel) - model[channel])[part]
        e = e[np.isfinite(e)] - np.mean(e[np.isfinite(e)]) if np.isfinite(e).any() else e
        n = e.size
        total += n
        power = float(e @ e)
        rho = float(e[1:] @ e[:-1]) / power if power > 0 and n > 1 else 0.0
        rho = min(max(rho, 0.0), 0.999)
        effective += n * (1.0 - rho) / (1.0 + rho)
    return total, max(effective, 1.0)


def estimates(
    jacobian: np.ndarray,
    z: np.ndarray,
    values: list[float],
    to_value,
    bounds: list[tuple[float, float]],
    cost_train: float,
    samples: int,
    effective: float,
) -> list[Estimate]:
    """Intervals from the Jacobian of the residual vector whose sum of squares is the
    training cost (``Replay.residual_vector``: ``e/√M``), at the unit-box point ``z``.

    ``to_value(j, z_j)`` maps a unit-box coordinate to the SI value of parameter ``j``.
    A parameter the data do not inform (a zero column) gets its whole bounds.
    """
    j_e = jacobian * math.sqrt(samples)  # ∂e/∂z
    info = j_e.T @ j_e
    scale = max(cost_train, 1.0) * samples / effective
    try:
        cov = np.linalg.pinv(info) * scale
    except np.linalg.LinAlgError:
        cov = np.full(info.shape, np.inf)
    out = []
    for j, value in enumerate(values):
        lo_b = bounds[j][0]
        var = cov[j, j] if np.all(np.isfinite(info[j])) and info[j, j] > 0 else math.inf
        half = Z95 * math.sqrt(var) if math.isfinite(var) else math.inf
        zl, zh = max(z[j] - half, 0.0), min(z[j] + half, 1.0)
        a, b = to_value(j, zl), to_value(j, zh)
        # an effect parameter at 0 is "off": a bound only when 0 is not its natural floor
        at_bound = (z[j] <= AT_BOUND and lo_b != 0.0) or z[j] >= 1.0 - AT_BOUND
        out.append(
            Estimate(float(value), (float(min(a, b)), float(max(a, b))), bounds[j], at_bound)
        )
    return out
