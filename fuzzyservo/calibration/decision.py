"""Is one model better than another on the held-out data, beyond what noise can do?

The held-out log-likelihood ratio of two models fitted on the training part, for
Gaussian measurement noise of the estimated level σ_c on each channel c:

    ln L_b − ln L_a = ½·Σ_c Σ_t (e_a² − e_b²),   e = (y − ŷ)/σ_c   (held-out samples t)

Both models are fixed by the time the held-out part is seen, so with δ = e_a − e_b
(the models' difference) the ratio is ``½·Σ(2·e_b·δ + δ²)``: the systematic part
``½·Σδ²`` when model b is right, and a noise part ``Σ e_b·δ`` whose spread is what
noise alone can do. That spread is computed from the data: the variance of
``Σ_t w_t`` with ``w = e_b·δ``, with the long-run (Bartlett, lags up to the residual's
correlation time) autocovariance of ``w``, so residuals correlated in time count as
fewer samples (the effective sample size ``N_eff = N·γ_w(0)/LRV_w``;
docs/modelling.md "Deciding whether an effect is real"). The statistic
``z = (ln L_b − ln L_a) / spread`` is compared with the normal quantile of the error
rate; over K candidates the rate is split K ways (Bonferroni), so on data without a
missing effect an effect is added in at most ``ALPHA`` of the runs. The rate is
measured on null data in ``tests/test_calibration_decision.py`` and in docs/calibration.md.

The statistic does not depend on the noise levels' absolute size (a channel's σ
scales both the ratio and its spread), so a poor noise estimate changes how the
channels are weighed, never the error rate.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

# the normal law from scipy.special: scipy.stats alone would double a worker's start
from scipy.special import ndtr, ndtri

from fuzzyservo.calibration.replay import Replay

ALPHA = 0.05  # the rate at which an effect is added on data without one (per round)
CORRELATION_TIME_S = 0.25  # longest lag the long-run variance looks at [s] (at least 25 samples)


@dataclass(frozen=True)
class Evidence:
    """Held-out evidence that model b beats model a.

    ``log_lr``: ln L_b − ln L_a; ``z``: that over its noise-driven standard deviation;
    ``n_eff``: effective number of held-out samples behind the spread (summed over
    channels); ``samples``: held-out samples (summed over channels).
    """

    log_lr: float
    z: float
    n_eff: float
    samples: int

    def p_value(self) -> float:
        """One-sided probability that noise alone gives at least this ``z``."""
        return float(ndtr(-self.z))


def threshold(candidates: int, alpha: float = ALPHA) -> float:
    """The ``z`` the best of ``candidates`` must exceed: ``Φ⁻¹(1 − α/K)``."""
    return float(-ndtri(alpha / max(candidates, 1)))


def held_out_lags(replay: Replay) -> int:
    """Longest lag the long-run variance of ``replay``'s held-out residuals looks at."""
    dt = float(replay.data.sample_period_s)
    return max(25, round(CORRELATION_TIME_S / dt)) if dt > 0 else 25


def long_run_variance(w: np.ndarray, lags: int) -> float | np.ndarray:
    """``Var(Σ w)`` of a series with serial correlation: ``N·(γ0 + 2·Σ_k (1 − k/(L+1))·γk)``
    (Newey-West, Bartlett weights, autocovariances about 0), never below 0. Of each row
    of a 2-D ``w`` at once (one per surrogate record, null.py)."""
    rows = np.atleast_2d(w)
    n = rows.shape[1]
    if n == 0:
        return 0.0 if w.ndim == 1 else np.zeros(rows.shape[0])
    total = np.einsum("ij,ij->i", rows, rows) / n
    for k in range(1, min(lags, n - 1) + 1):
        total += 2.0 * (1.0 - k / (lags + 1)) * np.einsum("ij,ij->i", rows[:, k:], rows[:, :-k]) / n
    total = np.maximum(total, 0.0) * n
    return float(total[0]) if w.ndim == 1 else total


def held_out_evidence(
    replay: Replay, model_a: Mapping[str, np.ndarray], model_b: Mapping[str, np.ndarray]
) -> Evidence:
    """Evidence on the held-out part that ``model_b`` (channels on the data grid) beats
    ``model_a``. A model with non-finite samples (a diverged replay) always loses."""
    part = slice(replay.split, None)
    finite_a = all(np.isfinite(model_a[c][part]).all() for c in replay.channels)
    finite_b = all(np.isfinite(model_b[c][part]).all() for c in replay.channels)
    if not finite_b or not finite_a:
        z = -math.inf if not finite_b else math.inf
        return Evidence(log_lr=z, z=z, n_eff=0.0, samples=0)
    e_a, e_b = {}, {}
    for channel in replay.channels:
        y = replay.measured(channel)[part]
        sigma = replay.sigma[channel]
        e_a[channel] = (y - model_a[channel][part]) / sigma
        e_b[channel] = (y - model_b[channel][part]) / sigma
    return evidence(e_a, e_b, held_out_lags(replay))


def evidence(e_a: Mapping[str, np.ndarray], e_b: Mapping[str, np.ndarray], lags: int) -> Evidence:
    """The test on held-out residuals in noise units of model a (``e_a``) and model b
    (``e_b``), channel -> samples; the long-run variance looks ``lags`` samples back."""
    log_lr = 0.0
    variance = 0.0
    gamma = 0.0
    samples = 0
    for channel, ea in e_a.items():
        eb = e_b[channel]
        log_lr += 0.5 * float(ea @ ea - eb @ eb)
        w = eb * (ea - eb)
        variance += long_run_variance(w, min(lags, max(w.size // 4, 1)))
        gamma += float(w @ w)
        samples += int(w.size)
    spread = math.sqrt(variance)
    z = log_lr / spread if spread > 0.0 else 0.0
    n_eff = samples * gamma / variance if variance > 0.0 else float(samples)
    return Evidence(log_lr=log_lr, z=z, n_eff=min(n_eff, float(samples)), samples=samples)
