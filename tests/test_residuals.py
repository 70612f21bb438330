"""Residual analysis: fit, noise floor, correlations and signatures against known answers.

References are analytic (sources in each test): MATLAB ``compare``'s NRMSE fit, the
variance of a second difference of white noise, the biased autocorrelation of an
alternating sequence, and a residual built from a known regressor.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from fuzzyservo.calibration.residuals import (
    Whiteness,
    autocorrelation,
    confidence_band,
    cross_correlation,
    derivative,
    fit_percent,
    lagged,
    noise_floor,
    normalised_cost,
    signature_regression,
    whiteness,
)

DT = 0.01  # s: the 100 Hz of the rigs' records
N = 2000


def _rng() -> np.random.Generator:
    return np.random.default_rng(20240607)


def _sine(n: int = N) -> np.ndarray:
    t = np.arange(n) * DT
    return np.sin(2 * np.pi * 0.5 * t)


# --- fit --------------------------------------------------------------------------------


def test_fit_percent_perfect_and_mean_model():
    # MATLAB compare: fit = 100·(1 − ‖y − ŷ‖/‖y − ȳ‖); ŷ = y → 100, ŷ = ȳ → 0.
    y = _sine() + 0.3
    assert fit_percent(y, y) == pytest.approx(100.0)
    assert fit_percent(y, np.full_like(y, y.mean())) == pytest.approx(0.0, abs=1e-12)


def test_fit_percent_of_scaled_error_and_cost_agree():
    # ŷ = y − c·(y − ȳ) has ‖y − ŷ‖ = c·‖y − ȳ‖, so fit = 100·(1 − c) and J = c².
    y = _sine() + 2.0
    yhat = y - 0.25 * (y - y.mean())
    assert fit_percent(y, yhat) == pytest.approx(75.0)
    assert normalised_cost(y, yhat) == pytest.approx(0.0625)
    assert fit_percent(y, yhat) == pytest.approx(100 * (1 - math.sqrt(normalised_cost(y, yhat))))


def test_fit_and_cost_of_diverged_and_constant_records():
    y = _sine()
    yhat = y.copy()
    yhat[100] = np.nan
    assert fit_percent(y, yhat) == -math.inf
    assert normalised_cost(y, yhat) == math.inf
    flat = np.ones(10)
    assert math.isnan(fit_percent(flat, flat))
    assert math.isnan(normalised_cost(flat, flat))


def test_fit_rejects_mismatched_lengths():
    with pytest.raises(ValueError, match="same length"):
        fit_percent(np.zeros(5), np.zeros(4))


# --- noise floor ------------------------------------------------------------------------

# The estimate is unbiased with a relative spread of about 1.37/√n (300 seeds at
# n = 2000 gave 3.1 %); 100 s at 100 Hz keeps 10 % beyond seven of those.
N_NOISE = 10_000


@pytest.mark.parametrize("sigma", [0.002, 0.01, 0.05])
def test_noise_floor_recovers_sigma_of_white_noise_on_a_sine(sigma):
    # Var(Δ²w) = 6σ² for white w; the sine's Δ² is (2π·0.5·0.01)² ≈ 1e-3 at most.
    y = _sine(N_NOISE) + sigma * _rng().standard_normal(N_NOISE)
    assert noise_floor(y) == pytest.approx(sigma, rel=0.10)


def test_noise_floor_ignores_steps_and_nan():
    sigma = 0.01
    y = _sine(N_NOISE) + sigma * _rng().standard_normal(N_NOISE)
    y[500:] += 1.0  # steps: a few huge second differences
    y[1200:] -= 2.0
    y[[50, 900, 1500]] = np.nan
    assert noise_floor(y) == pytest.approx(sigma, rel=0.10)


def test_noise_floor_of_noise_free_ramp_is_zero_and_short_record_nan():
    assert noise_floor(np.linspace(0.0, 1.0, 50)) == pytest.approx(0.0, abs=1e-12)
    assert math.isnan(noise_floor(np.array([1.0, 2.0])))


# --- correlations -----------------------------------------------------------------------


def test_autocorrelation_of_alternating_sequence():
    # e = (+1, −1, …) with even N has mean 0 and biased r(τ) = (−1)^τ·(N − τ)/N.
    n = 100
    e = np.where(np.arange(n) % 2 == 0, 1.0, -1.0)
    lags, r = autocorrelation(e, max_lag=10)
    np.testing.assert_array_equal(lags, np.arange(11))
    np.testing.assert_allclose(r, (-1.0) ** lags * (n - lags) / n, rtol=1e-12)


def test_autocorrelation_of_white_noise_stays_in_band():
    e = _rng().standard_normal(N)
    lags, r = autocorrelation(e)
    assert lags[-1] == 25
    assert r[0] == pytest.approx(1.0)
    assert np.count_nonzero(np.abs(r[1:]) > confidence_band(N)) <= 2


def test_cross_correlation_peaks_at_the_input_delay():
    # e(t) = u(t − 3): the residual lags the input, so the peak is at τ = +3 with
    # r = (N − 3)/N·(1 + O(1/√N)).
    u = _rng().standard_normal(N)
    lags, r = cross_correlation(lagged(u, 3), u)
    np.testing.assert_array_equal(lags, np.arange(-25, 26))
    assert lags[np.argmax(np.abs(r))] == 3
    assert r[lags == 3][0] == pytest.approx(1.0, abs=0.01)
    # The mirror image: a residual that leads the input peaks at a negative lag.
    lags, r = cross_correlation(u[2:], u[:-2], max_lag=5)
    assert lags[np.argmax(np.abs(r))] == -2


def test_cross_correlation_matches_numpy_correlate():
    rng = _rng()
    e, u = rng.standard_normal(300), rng.standard_normal(300)
    _, r = cross_correlation(e, u, max_lag=7)
    ec, uc = e - e.mean(), u - u.mean()
    full = np.correlate(ec, uc, mode="full")  # index N−1+τ holds Σ_t e(t+τ)·u(t)
    expected = full[299 - 7 : 299 + 8] / (300 * ec.std() * uc.std())
    np.testing.assert_allclose(r, expected, rtol=1e-12)


def test_correlations_reject_bad_input():
    with pytest.raises(ValueError, match="max_lag"):
        autocorrelation(np.zeros(10), max_lag=10)
    with pytest.raises(ValueError, match="non-finite"):
        autocorrelation(np.array([1.0, np.nan, 2.0, 3.0]), max_lag=1)
    with pytest.raises(ValueError, match="same length"):
        cross_correlation(np.zeros(10), np.zeros(9), max_lag=2)


def test_confidence_band_is_the_99_percent_band():
    # MODELLING.md / MATLAB resid: ±2.58/√N.
    assert confidence_band(10_000) == pytest.approx(0.0258)
    assert confidence_band(100, z=1.96) == pytest.approx(0.196)
    with pytest.raises(ValueError, match="n > 0"):
        confidence_band(0)


# --- whiteness --------------------------------------------------------------------------


def test_whiteness_of_independent_white_noise():
    rng = _rng()
    result = whiteness(rng.standard_normal(N), rng.standard_normal(N))
    assert isinstance(result, Whiteness)
    assert result.band == pytest.approx(2.58 / math.sqrt(N))
    assert result.autocorr_outside <= 2
    assert result.crosscorr_outside <= 2
    assert result.white == (result.autocorr_outside == 0)
    assert result.independent == (result.crosscorr_outside == 0)


def test_whiteness_flags_a_delayed_input_and_coloured_residual():
    rng = _rng()
    u = rng.standard_normal(N)
    w = rng.standard_normal(N)
    e = 0.5 * lagged(u, 4) + w + 0.8 * lagged(w, 1)  # MA(1): r(1) = 0.8/1.64 ≫ band
    result = whiteness(e, u)
    assert result.peak_crosscorr_lag == 4
    assert not result.independent
    assert not result.white


# --- signatures -------------------------------------------------------------------------


def test_signature_regression_picks_the_regressor_that_built_the_residual():
    rng = _rng()
    t = np.arange(N) * DT
    v = 0.05 * np.sin(2 * np.pi * 0.3 * t)
    coulomb = np.tanh(v / 0.005)
    residuals = {
        # Different scales and signs per channel; the normalisation weighs them equally.
        "y": 1e-3 * coulomb + 1e-5 * rng.standard_normal(N),
        "p3": -4e5 * coulomb + 1e4 * rng.standard_normal(N) + 2e5,
    }
    residuals["y"][[10, 20]] = np.nan
    unrelated = rng.standard_normal(N)
    unrelated[30] = np.inf
    scores = signature_regression(
        residuals, {"coulomb": coulomb, "unrelated": unrelated, "constant": np.ones(N)}
    )
    assert list(scores) == ["coulomb", "unrelated", "constant"]
    assert scores["coulomb"] > 0.9
    assert scores["unrelated"] < 0.1
    assert scores["constant"] == 0.0


def test_signature_regression_pools_channels_by_their_share():
    # One channel fully explained, one not at all: pooled R² ≈ 1/2 (equal weights).
    rng = _rng()
    x = rng.standard_normal(N)
    scores = signature_regression({"a": 3.0 * x + 1.0, "b": rng.standard_normal(N)}, {"x": x})
    assert scores["x"] == pytest.approx(0.5, abs=0.02)


def test_signature_regression_rejects_mismatched_lengths():
    with pytest.raises(ValueError, match="time grid"):
        signature_regression({"y": np.zeros(10)}, {"x": np.zeros(9)})


# --- signature builders -----------------------------------------------------------------


def test_lagged_delays_and_holds_the_first_value():
    u = np.array([1.0, 2.0, 3.0, 4.0])
    np.testing.assert_array_equal(lagged(u, 2), [1.0, 1.0, 1.0, 2.0])
    np.testing.assert_array_equal(lagged(u, 0), u)
    np.testing.assert_array_equal(lagged(u, 9), [1.0, 1.0, 1.0, 1.0])
    with pytest.raises(ValueError, match="k >= 0"):
        lagged(u, -1)


def test_derivative_of_a_parabola():
    # d(t²)/dt = 2t: central differences are exact for a parabola inside the record.
    t = np.arange(50) * DT
    np.testing.assert_allclose(derivative(t**2, DT)[1:-1], 2 * t[1:-1], rtol=1e-12)
    with pytest.raises(ValueError, match="dt > 0"):
        derivative(t, 0.0)
