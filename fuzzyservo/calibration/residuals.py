"""Residual analysis of a model against measured data: fit, noise floor, whiteness.

Pure functions of arrays. The definitions follow MATLAB's System Identification
Toolbox: ``compare`` for the fit and ``resid`` for the correlation tests (biased
estimators, 99 % band ``±2.58/√N``); docs/modelling.md, "Measured data: what the residual
tells you", lists which missing effect leaves which signature in the residual.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

# Standard deviation of a normal distribution per unit of median absolute deviation,
# 1/Φ⁻¹(3/4) (Hampel 1974; Rousseeuw & Croux 1993).
_MAD_TO_SIGMA = 1.4826


def _as_1d(name: str, values: np.ndarray) -> np.ndarray:
    array = np.asarray(values, dtype=float)
    if array.ndim != 1:
        raise ValueError(f"{name} must be one-dimensional, but got shape {array.shape}")
    return array


def _same_length(names: str, a: np.ndarray, b: np.ndarray) -> None:
    if a.shape != b.shape:
        raise ValueError(
            f"{names} must have the same length, but got {a.size} and {b.size}; "
            "pass samples of one record on one time grid"
        )


def _require_finite(name: str, values: np.ndarray) -> None:
    bad = int(np.count_nonzero(~np.isfinite(values)))
    if bad:
        raise ValueError(
            f"{name} has {bad} non-finite samples of {values.size}; correlation needs an "
            "unbroken record, so cut the record to a finite stretch first"
        )


def fit_percent(y: np.ndarray, yhat: np.ndarray) -> float:
    """Normalised root-mean-square fit of ``yhat`` to ``y`` in percent.

    ``fit = 100·(1 − ‖y − ŷ‖ / ‖y − mean(y)‖)`` (MATLAB ``compare``, NRMSE fit;
    docs/modelling.md). 100 is a perfect fit, 0 is no better than the mean of ``y``, and
    the value is unbounded below. A model output with any non-finite sample (a
    diverged replay) scores ``-inf``; a constant ``y`` gives NaN (nothing to explain).
    """
    y = _as_1d("y", y)
    yhat = _as_1d("yhat", yhat)
    _same_length("y and yhat", y, yhat)
    if not np.all(np.isfinite(yhat)):
        return -math.inf
    spread = float(np.linalg.norm(y - np.mean(y)))
    if spread == 0.0:
        return math.nan
    return 100.0 * (1.0 - float(np.linalg.norm(y - yhat)) / spread)


def normalised_cost(y: np.ndarray, yhat: np.ndarray) -> float:
    """Squared error of ``yhat`` relative to the variation of ``y`` (dimensionless).

    ``J = ‖y − ŷ‖² / ‖y − mean(y)‖²``, so ``fit = 100·(1 − √J)`` (MATLAB ``compare``).
    0 is a perfect fit, 1 is the mean of ``y``. A model output with any non-finite
    sample scores ``inf``; a constant ``y`` gives NaN.
    """
    y = _as_1d("y", y)
    yhat = _as_1d("yhat", yhat)
    _same_length("y and yhat", y, yhat)
    if not np.all(np.isfinite(yhat)):
        return math.inf
    spread = float(np.sum((y - np.mean(y)) ** 2))
    if spread == 0.0:
        return math.nan
    return float(np.sum((y - yhat) ** 2)) / spread


def noise_floor(y: np.ndarray) -> float:
    """Standard deviation of white measurement noise on ``y``, from the data alone.

    ``σ = 1.4826·median(|Δ²y − median(Δ²y)|) / √6`` with ``Δ²y(t) = y(t+1) − 2y(t) +
    y(t−1)``. For white noise of variance σ² the second difference has variance
    ``(1 + 4 + 1)·σ² = 6σ²``; 1.4826 turns a median absolute deviation into a normal
    standard deviation. The second difference of the smooth part of a signal sampled
    at 100 Hz is small except around fast transients (steps, breakaway), and the
    median ignores those few samples, so what remains is the noise. Slow signals
    (``y'' · dt²`` well below σ) are needed.

    Two logger habits are handled (docs/modelling.md "Sensors"):

    * **held samples**: when more than half of the samples repeat the previous one
      (a logger that holds the last value between sensor updates), the estimate is
      taken on the updates alone — from changes, not from all samples — else the
      median of the second differences is 0 and the estimate collapses;
    * **quantisation**: when every change is a whole multiple of one step ``q`` (the
      smallest change), the estimate is at least the quantisation noise ``q/√12``; a
      record whose changes are mostly single codes (a converter step above the noise)
      repeats because of its rounding, not a logger, and is taken whole.

    Non-finite samples are skipped (every second difference touching one). In the
    units of ``y``; NaN when fewer than three finite samples are in a row. A noise-free
    smooth signal (a ramp) gives 0.
    """
    y = _as_1d("y", y)
    dy = np.diff(y)
    q = quantisation_step(dy)
    moves = np.abs(dy[np.isfinite(dy) & (dy != 0.0)])
    # a record that mostly repeats: a logger holding values, unless its changes are
    # mostly one code (a still signal read through a converter whose step exceeds the
    # noise repeats too, and its updates alone are code flips of a full step)
    flips = q > 0.0 and moves.size and float(np.median(moves)) <= 1.5 * q
    if dy.size and np.count_nonzero(dy == 0.0) > 0.5 * dy.size and not flips:
        y = y[np.concatenate(([True], dy != 0.0))]  # the updates, each once
    d2 = y[2:] - 2.0 * y[1:-1] + y[:-2]
    d2 = d2[np.isfinite(d2)]
    if d2.size == 0:
        return math.nan
    mad = float(np.median(np.abs(d2 - np.median(d2))))
    sigma = _MAD_TO_SIGMA * mad / math.sqrt(6.0)
    return max(sigma, q / math.sqrt(12.0))


def quantisation_step(dy: np.ndarray) -> float:
    """The step ``q`` of a quantised record from its changes ``dy`` (0 if not quantised).

    ``q`` is the smallest non-zero ``|dy|``; the record counts as quantised when every
    change is a whole multiple of it (to 1 %) and the changes are not all one size (a
    noise-free ramp is not quantisation).
    """
    dy = np.abs(np.asarray(dy, dtype=float))
    dy = dy[np.isfinite(dy) & (dy > 0.0)]
    if dy.size < 3:
        return 0.0
    q = float(dy.min())
    ratio = dy / q
    if np.ptp(ratio) < 0.5:  # all changes of one size: a ramp
        return 0.0
    if np.max(np.abs(ratio - np.round(ratio))) > 0.01:
        return 0.0
    return q


def _check_lag(max_lag: int, n: int) -> None:
    if not 0 <= max_lag < n:
        raise ValueError(
            f"0 <= max_lag < N must hold, but got (max_lag={max_lag}, N={n}); "
            "use a longer record or fewer lags"
        )


def autocorrelation(e: np.ndarray, max_lag: int = 25) -> tuple[np.ndarray, np.ndarray]:
    """Lags ``0..max_lag`` and the normalised autocorrelation of ``e`` at each.

    ``r(τ) = Σ_{t=0}^{N−1−τ} ẽ(t)·ẽ(t+τ) / Σ_t ẽ(t)²`` with ``ẽ = e − mean(e)``: the
    biased estimator (divided by N, not N − τ) that MATLAB ``resid`` plots, so
    ``r(0) = 1``. A white residual stays inside ``±confidence_band(N)`` for τ ≥ 1.
    A constant ``e`` gives NaN at every lag. ``e`` must be finite.
    """
    e = _as_1d("e", e)
    _require_finite("e", e)
    _check_lag(max_lag, e.size)
    lags = np.arange(max_lag + 1)
    centred = e - np.mean(e)
    power = float(np.dot(centred, centred))
    if power == 0.0:
        return lags, np.full(lags.size, np.nan)
    r = np.array([np.dot(centred[: e.size - k], centred[k:]) for k in lags]) / power
    return lags, r


def cross_correlation(
    e: np.ndarray, u: np.ndarray, max_lag: int = 25
) -> tuple[np.ndarray, np.ndarray]:
    """Lags ``−max_lag..max_lag`` and the normalised cross-correlation of ``e`` with ``u``.

    ``r_eu(τ) = Σ_t ẽ(t+τ)·ũ(t) / (N·σe·σu)`` over the ``t`` where both samples exist,
    with means removed and ``σ² = Σ x̃²/N`` (biased, as MATLAB ``resid``).

    Sign convention: a peak at **positive** τ means the residual at ``t + τ`` follows
    the input at ``t`` — the input leads, the residual lags it. ``e(t) = u(t − 3)``
    peaks at τ = +3: a missing transport delay or valve lag shows up at τ > 0.
    A peak at negative τ means the residual leads the input (feedback of the error
    into the command, as in closed-loop data). A constant ``e`` or ``u`` gives NaN.
    Both must be finite.
    """
    e = _as_1d("e", e)
    u = _as_1d("u", u)
    _same_length("e and u", e, u)
    _require_finite("e", e)
    _require_finite("u", u)
    _check_lag(max_lag, e.size)
    n = e.size
    lags = np.arange(-max_lag, max_lag + 1)
    e_c = e - np.mean(e)
    u_c = u - np.mean(u)
    scale = math.sqrt(float(np.dot(e_c, e_c)) * float(np.dot(u_c, u_c)))
    if scale == 0.0:
        return lags, np.full(lags.size, np.nan)
    r = np.empty(lags.size)
    for j, k in enumerate(lags):
        if k >= 0:
            r[j] = np.dot(e_c[k:], u_c[: n - k])
        else:
            r[j] = np.dot(e_c[: n + k], u_c[-k:])
    # N·σe·σu = √(Σẽ²·Σũ²) with the biased σ.
    return lags, r / scale


def confidence_band(n: int, z: float = 2.58) -> float:
    """Half-width ``z/√n`` of the band a white residual's correlations stay inside.

    With ``z = 2.58`` this is the 99 % band of MATLAB ``resid`` (docs/modelling.md): for a
    white sequence of ``n`` samples each normalised correlation at lag ≠ 0 is
    approximately normal with standard deviation ``1/√n``.
    """
    if n <= 0:
        raise ValueError(f"n > 0 must hold, but got n={n}; pass the number of samples")
    return z / math.sqrt(n)


@dataclass(frozen=True)
class Whiteness:
    """Outcome of the ``resid`` tests on one residual against one input.

    ``autocorr_outside`` counts lags ``1..max_lag`` of the residual's autocorrelation
    outside ``±band``; ``crosscorr_outside`` counts lags ``−max_lag..max_lag`` of its
    cross-correlation with the input outside ``±band``; ``peak_crosscorr_lag`` is the
    lag of the largest ``|r_eu|`` (positive: the input leads, see
    :func:`cross_correlation`). ``white`` and ``independent`` say no lag was outside.
    """

    autocorr_outside: int
    crosscorr_outside: int
    band: float
    peak_crosscorr_lag: int
    white: bool
    independent: bool


def whiteness(e: np.ndarray, u: np.ndarray, max_lag: int = 25) -> Whiteness:
    """Whiteness of residual ``e`` and its independence of input ``u`` (MATLAB ``resid``).

    Uses :func:`autocorrelation`, :func:`cross_correlation` and the 99 % band
    ``2.58/√N``. NaN correlations (a constant ``e`` or ``u``) count as inside the band,
    and the peak lag is then 0.
    """
    e = _as_1d("e", e)
    band = confidence_band(e.size)
    _, acf = autocorrelation(e, max_lag)
    lags, xcf = cross_correlation(e, u, max_lag)
    auto_out = int(np.count_nonzero(np.abs(acf[1:]) > band))
    cross_out = int(np.count_nonzero(np.abs(xcf) > band))
    magnitude = np.abs(xcf)
    peak = int(lags[np.nanargmax(magnitude)]) if np.isfinite(magnitude).any() else 0
    return Whiteness(
        autocorr_outside=auto_out,
        crosscorr_outside=cross_out,
        band=band,
        peak_crosscorr_lag=peak,
        white=auto_out == 0,
        independent=cross_out == 0,
    )


def signature_regression(
    residuals: Mapping[str, np.ndarray], regressors: Mapping[str, np.ndarray]
) -> dict[str, float]:
    """Share of the residual variance each regressor explains, pooled over channels.

    For regressor ``x`` and every channel ``c``, the residual ``r_c`` (divided by its
    own standard deviation, so channels weigh equally) is fitted by least squares as
    ``a·x + b``; the result is ``R² = 1 − Σ_c SSres_c / Σ_c SStot_c`` in ``[0, 1]``.
    A high value says the residual carries that regressor's signature, i.e. the
    matching missing effect of docs/modelling.md's table (``tanh(v/vc)`` for Coulomb
    friction, ``u(t−k)`` for a delay …).

    Only rows where the channel's residual and the regressor are both finite are
    used. A regressor that is constant or has no finite samples scores 0.0, and so
    does one with no channel to explain. All arrays must have one length.
    """
    channels = {name: _as_1d(f"residual {name!r}", r) for name, r in residuals.items()}
    lengths = {r.size for r in channels.values()}
    if len(lengths) > 1:
        sizes = {name: r.size for name, r in channels.items()}
        raise ValueError(f"residuals must have one length, but got {sizes}")
    scores: dict[str, float] = {}
    for reg_name, values in regressors.items():
        x = _as_1d(f"regressor {reg_name!r}", values)
        if lengths and x.size not in lengths:
            raise ValueError(
                f"regressor {reg_name!r} has {x.size} samples but the residuals have "
                f"{lengths.pop()}; build regressors on the residuals' time grid"
            )
        finite_x = x[np.isfinite(x)]
        if finite_x.size == 0 or float(np.std(finite_x)) == 0.0:
            scores[reg_name] = 0.0
            continue
        ss_res = 0.0
        ss_tot = 0.0
        for r in channels.values():
            rows = np.isfinite(r) & np.isfinite(x)
            if np.count_nonzero(rows) < 2:
                continue
            rc = r[rows] - np.mean(r[rows])
            sd = float(np.std(rc))
            if sd == 0.0:
                continue
            rc = rc / sd
            xc = x[rows] - np.mean(x[rows])
            tot = float(np.dot(rc, rc))
            sxx = float(np.dot(xc, xc))
            # Least squares on [x, 1]: the intercept removes the means, the slope
            # explains (Σ x̃·r̃)² / Σ x̃² of the residual's sum of squares.
            explained = float(np.dot(xc, rc)) ** 2 / sxx if sxx > 0.0 else 0.0
            ss_tot += tot
            ss_res += tot - explained
        r2 = 1.0 - ss_res / ss_tot if ss_tot > 0.0 else 0.0
        scores[reg_name] = float(min(1.0, max(0.0, r2)))
    return scores


def lagged(u: np.ndarray, k: int) -> np.ndarray:
    """``u(t − k)``: ``u`` delayed by ``k ≥ 0`` samples, the first ``k`` held at ``u(0)``.

    The regressor for a missing transport delay (docs/modelling.md). A lead (``k < 0``)
    is not causal and is refused.
    """
    u = _as_1d("u", u)
    if k < 0:
        raise ValueError(f"k >= 0 must hold (a delay in samples), but got k={k}")
    if k == 0 or u.size == 0:
        return u.copy()
    out = np.empty_like(u)
    head = min(k, u.size)
    out[:head] = u[0]
    out[head:] = u[: u.size - head]
    return out


def derivative(y: np.ndarray, dt: float) -> np.ndarray:
    """``dy/dt`` by central differences (one-sided at the ends), ``numpy.gradient``.

    In units of ``y`` per second for ``dt`` in seconds; the regressor for valve lag
    (``u̇``) and for a wrong bulk modulus (``ṗ``) in docs/modelling.md.
    """
    y = _as_1d("y", y)
    if not dt > 0.0:
        raise ValueError(f"dt > 0 must hold, but got dt={dt}; pass the sample time in s")
    return np.gradient(y, dt)
