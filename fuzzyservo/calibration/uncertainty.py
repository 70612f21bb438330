"""How well the data pin down each fitted value: a 95 % interval and an at-bound flag.

Every fitted value gets two intervals, and the one reported spans both (and the value):

* **Linearised, robust to correlated residuals** (:func:`sandwich`). With ``r`` the
  training residual in noise units and ``J = ∂r/∂z`` its Jacobian on the unit box of
  the search, a parameter's error is ``−(JᵀJ)⁻¹Jᵀr`` to first order, so

      cov(z) = (JᵀJ)⁻¹ · Ω · (JᵀJ)⁻¹

  with ``Ω`` the long-run covariance of the score ``g_t = Σ_c J_ct·r_ct`` (summed over
  the channels at each sample): Newey and West's estimate (1987; Bartlett weights) up to
  ``HAC_SPAN`` correlation times of the residual, at most a quarter of the samples.
  Unlike ``(JᵀJ)⁻¹`` scaled by the noise, it holds whatever the residual holds (noise,
  model error, both) and however it is correlated, as long as the cost is smooth in the
  parameter over the Jacobian's step.
* **Profile** (:func:`profile_interval`). Where the cost is rough in a parameter the
  sandwich is not enough: a piston that sticks and slips with a 16-bit position
  converter in the loop makes the training cost of the shipped friction example jump
  between 5 and 13 (noise units) from one newton to the next, and the fit lands in a
  valley under 1 N wide, 10 N below the 300 N the record was made with; a Jacobian
  there sees only the valley. So each parameter's training cost is also evaluated on a
  grid of ``PROFILE_POINTS`` points each side of the fit and a cubic fitted through it
  by least squares: the *envelope*, whose lowest point estimates
  where the cost bottoms out under its roughness. Two spreads place that bottom, added
  in quadrature: the costs' scatter about the cubic (Student's t on its degrees of
  freedom, the delta method for the position of the bottom), and a moving-block
  bootstrap of the training part (``RESAMPLES`` resamples of about ``BLOCKS`` blocks,
  each at least the residual's correlation time long; the 2.5 and 97.5 % percentiles of
  each resample's envelope bottom). To them it adds every value at which the cubic
  lies within the 95 % quantile of the costs' scatter about it (Rice's estimate from
  neighbouring points, blind to a smooth misfit; never deeper than the lowest point's
  height above a perfect model's cost) of its lowest point: on
  a rough cost the bottom places only the envelope, and a needle as deep as the fit's
  may lie wherever the envelope has not risen by more than its roughness (about a
  smooth cost's cubic the scatter is next to nothing, and so is what this adds). The grid leaves out the fit itself,
  whose cost is the least a search found (low by selection where the cost is rough).
  At each grid point every other parameter takes one Gauss-Newton step from where it
  was fitted (:func:`gauss_newton_step`), kept where it lowers the cost. That follows a
  curved valley, as a profile likelihood does, where holding them cuts across it (a
  second-order spool's two time constants trade along one; with a spool's second time
  constant at 0 the first must shorten as the second grows). Following only the values
  strongly correlated with it (|ρ| ≥ 0.5 in ``(JᵀJ)⁻¹``) held a weakly correlated one,
  and on rig-like sticking Stribeck records the stiction's and pre-sliding distance's
  intervals then cut across the valley (docs/calibration-intervals.md). Its spacing
  starts at half the sandwich's half-width, never under the search's Jacobian step, and
  doubles (``DOUBLINGS`` times at most) until the bottom lies inside the grid, or at a
  bound of the box, the scatter places it within ``SETTLED`` of the grid's half-span,
  and the cubic rises above the scatter before each end of the grid (or the end is a
  bound); a grid still unsettled at its widest is part of the interval. The
  envelope is a cubic, not a parabola, because a valley steeper on one side (a delay's)
  moves a parabola's bottom off the true one; and its bottom, not each resample's lowest
  grid point, because a rough cost's lowest point jumps between valleys that resampling
  the record does not reshape (on the Coulomb draws of docs/calibration.md, the lowest
  point's percentiles held the truth in 14 of the first 20, the envelope's in 19).

Both are mapped back through the search's scaling and clipped to the bounds. A value
within 0.1 % of the box of a bound is flagged ``at_bound``: the data wanted it further
out, and its interval is one-sided. docs/calibration.md gives their coverage.

:func:`held_interval` is the cheaper interval the decision's prediction band uses
(search.frozen_ends, null.py): one parameter with the others held, ``(JᵀJ)⁻¹`` inflated
by the training cost and by the residual's lag-one autocorrelation (:func:`effective_samples`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.special import stdtrit  # Student's t quantile: stdtrit(dof, q)

from fuzzyservo.calibration.replay import DIVERGED_COST, Replay

Z95 = 1.959964  # two-sided 95 % normal quantile
AT_BOUND = 1e-3  # distance to a bound on the unit box that counts as "at the bound"
# a correlation of two fitted values beyond which the record trades one against the other
# (a value on its bound then reports what it cannot be told from)
TRADES = 0.7
UNCORRELATED = 0.05  # autocorrelation below which residual samples count as uncorrelated
HAC_SPAN = 3  # Newey-West lags, in correlation times of the residual
BLOCKS = 20  # blocks of the training part in a bootstrap resample (fewer if longer)
RESAMPLES = 400  # bootstrap resamples of each profile
PROFILE_POINTS = 5  # grid points on each side of the fit
DEGREE = 3  # of the polynomial fitted to a profile (its envelope)
SETTLED = 0.5  # the envelope's bottom is placed when its 95 % half-width is under
# this share of the grid's half-span
DOUBLINGS = 3  # at most this many times the profile's spacing doubles
SEED = 40  # of the bootstrap's resampling (the intervals are reproducible)


@dataclass(frozen=True)
class Estimate:
    """A fitted value [SI], its 95 % interval [SI] and whether it sits on a bound."""

    value: float
    interval: tuple[float, float]
    bounds: tuple[float, float]
    at_bound: bool
    # the other fitted value it is most correlated with (estimates' ``names``) and the
    # correlation, where that exceeds TRADES: what the record cannot tell it from
    trades_with: str = ""
    correlation: float = math.nan


def correlation_time(residuals: np.ndarray) -> int:
    """Samples after which the residual (channels × samples) is uncorrelated: the first
    lag at which each channel's autocorrelation falls below ``UNCORRELATED``, the
    largest over channels, at least 1."""
    longest = 1
    for row in np.atleast_2d(residuals):
        e = row[np.isfinite(row)]
        n = e.size
        if n < 3:
            continue
        e = e - e.mean()
        spectrum = np.fft.rfft(e, 2 * n)
        acf = np.fft.irfft(spectrum * np.conj(spectrum))[:n]
        if acf[0] <= 0.0:
            continue
        below = np.flatnonzero(acf / acf[0] < UNCORRELATED)
        longest = max(longest, int(below[0]) if below.size else n)
    return longest


def long_run_lags(residuals: np.ndarray) -> int:
    """The Newey-West lags for residuals (channels × samples): ``HAC_SPAN`` correlation
    times, at most a quarter of the samples (with 3, the sandwich's variance of a slope
    through AR(1) noise of ρ 0.5-0.95 is 0.9-1.0 of its spread over noise draws; with
    1, 0.7-0.8)."""
    return min(HAC_SPAN * correlation_time(residuals), residuals.shape[-1] // 4)


def sandwich(jacobian: np.ndarray, residuals: np.ndarray, lags: int) -> np.ndarray:
    """The covariance ``(JᵀJ)⁻¹ Ω (JᵀJ)⁻¹`` of the parameters on the unit box, ``Ω`` the
    Newey-West estimate (Bartlett weights up to ``lags``) of the long-run covariance of
    the score. ``jacobian``: ∂r/∂z with the rows of the channels end to end, as
    ``Replay.residual_vector``; ``residuals``: r as channels × samples."""
    channels, n = residuals.shape
    jac = jacobian.reshape(channels, n, -1)
    score = np.einsum("ctp,ct->tp", jac, residuals)
    omega = score.T @ score
    for lag in range(1, min(lags, n - 1) + 1):
        gamma = score[lag:].T @ score[:-lag]
        omega += (1.0 - lag / (lags + 1.0)) * (gamma + gamma.T)
    inverse = np.linalg.pinv(jacobian.T @ jacobian)
    return inverse @ omega @ inverse


def profile_interval(
    cost: Callable[[float], np.ndarray],
    z: float,
    step: float,
    block: int,
    seed: int = SEED,
    floor: float = 0.0,
) -> tuple[float, float]:
    """The 95 % interval (unit box) of the bottom of a parameter's training-cost profile
    about the fit ``z``; see the module docstring.

    ``cost(v)``: the training cost of each sample (summed over channels) with the
    parameter at ``v`` on the unit box and the others held; ``step``: the grid's first
    spacing; ``block``: the bootstrap's block length [samples]."""
    seen: dict[float, np.ndarray] = {}
    spacing = step
    for _ in range(DOUBLINGS + 1):
        for k in range(1, PROFILE_POINTS + 1):
            for v in (z - k * spacing, z + k * spacing):
                v = round(min(max(v, 0.0), 1.0), 12)
                if abs(v - z) > 1e-12 and v not in seen:
                    seen[v] = np.concatenate([[0.0], np.cumsum(cost(v))])
        # a run that failed (replay.py's DIVERGED_COST on its samples) tells nothing
        points = np.array([v for v in sorted(seen) if seen[v][-1] < 0.01 * DIVERGED_COST])
        if points.size < DEGREE + 2:
            envelope = None
        else:
            cumulative = np.array([seen[v] for v in points])
            x, scale = points - z, max(abs(points[0] - z), abs(points[-1] - z))
            envelope = _Envelope.fit(x / scale, cumulative[:, -1], floor)
            if envelope.settled(points[0] <= 0.0, points[-1] >= 1.0):
                break
        spacing *= 2.0
    if envelope is None:
        return (float(points[0]), float(points[-1])) if points.size else (z, z)
    minima = _Envelope.resampled_minima(x / scale, cumulative, block, seed)
    bottom = envelope.bottom
    lo, hi = np.percentile(minima, [2.5, 97.5])
    rough = stdtrit(envelope.dof, 0.975) * envelope.error  # its spread over the grid
    lo = bottom - math.hypot(max(bottom - lo, 0.0), rough)
    hi = bottom + math.hypot(max(hi - bottom, 0.0), rough)
    # where the envelope rises less than the costs scatter about it, a value is as good
    # as the bottom: a needle as deep as the fit's may lie there (a rough cost)
    near = envelope.below(envelope.needle())
    lo, hi = min(lo, near[0]), max(hi, near[1])
    if not envelope.settled(points[0] <= 0.0, points[-1] >= 1.0):  # the grid at its widest
        lo, hi = min(lo, x[0] / scale), max(hi, x[-1] / scale)
    return float(max(z + scale * lo, 0.0)), float(min(z + scale * hi, 1.0))


@dataclass(frozen=True)
class _Envelope:
    """A cubic ``a·x³ + b·x² + c·x + d`` fitted by least squares to a cost profile on
    ``x`` in [-1, 1] (a quadratic misplaces the bottom of a valley steeper on one side):
    its lowest point there, the standard error of that point's position from the
    scatter of the costs about the cubic (zero at an end of the grid), and its degrees
    of freedom."""

    bottom: float
    error: float
    dof: int
    interior: bool
    at_lower: bool
    coef: tuple[float, float, float, float]
    span: tuple[float, float]  # the grid's ends
    roughness: float  # the costs' scatter about the cubic, from point to point
    floor: float  # the least a cost can be (a perfect model's)

    @staticmethod
    def fit(x: np.ndarray, y: np.ndarray, floor: float = 0.0) -> _Envelope:
        design = np.vander(x, DEGREE + 1)
        coef, *_ = np.linalg.lstsq(design, y, rcond=None)
        dof = x.size - DEGREE - 1
        scatter = y - design @ coef
        cov = float(scatter @ scatter) / dof * np.linalg.pinv(design.T @ design)
        bottom = float(_lowest(coef[:, None], x[0], x[-1])[0])
        interior = x[0] < bottom < x[-1]
        error = 0.0
        if interior:
            a, b = coef[0], coef[1]
            curvature = 6.0 * a * bottom + 2.0 * b
            gradient = -np.array([3.0 * bottom**2, 2.0 * bottom, 1.0, 0.0]) / curvature
            error = math.sqrt(max(float(gradient @ cov @ gradient), 0.0))
        # Rice's difference estimator on the points in order: a smooth misfit of the cubic
        # (a wide grid over a cost that is not a cubic) changes little from point to
        # point and counts next to nothing; a rough cost's jumps count whole
        jumps = np.diff(scatter)
        roughness = math.sqrt(float(jumps @ jumps) / (2 * jumps.size)) if jumps.size else 0.0
        return _Envelope(bottom, error, dof, interior, bottom <= x[0],
                         tuple(float(c) for c in coef), (float(x[0]), float(x[-1])),
                         roughness, floor)  # fmt: skip

    def needle(self) -> float:
        """How far below the cubic a needle of the rough cost may reach: the 95 %
        quantile of the scatter, but never below the floor (a model cannot beat the
        noise, so where the cubic bottoms out at the floor no needle is deeper)."""
        lowest = float(np.polyval(self.coef, self.bottom))
        depth = stdtrit(self.dof, 0.975) * self.roughness if self.dof > 0 else 0.0
        return min(depth, max(lowest - self.floor, 0.0))

    def below(self, rise: float) -> tuple[float, float]:
        """The span of the grid where the cubic lies within ``rise`` of its lowest point
        there (the bottom itself when ``rise`` is 0)."""
        grid = np.linspace(self.span[0], self.span[1], 401)
        values = np.polyval(self.coef, grid)
        lowest = float(np.polyval(self.coef, self.bottom))
        inside = grid[values <= lowest + rise]
        if not inside.size:
            return self.bottom, self.bottom
        return min(float(inside[0]), self.bottom), max(float(inside[-1]), self.bottom)

    def settled(self, lower_is_bound: bool, upper_is_bound: bool) -> bool:
        """The grid shows the bottom: inside it (or at a bound of the box), placed by
        the costs' scatter to within ``SETTLED`` of its half-span; and the cubic rises
        by more than that scatter before each end of the grid (or the end is a bound)."""
        near = self.below(self.needle())
        if (near[0] <= self.span[0] and not lower_is_bound) or (
            near[1] >= self.span[1] and not upper_is_bound
        ):
            return False
        if not self.interior:
            return lower_is_bound if self.at_lower else upper_is_bound
        return stdtrit(self.dof, 0.975) * self.error <= SETTLED

    @staticmethod
    def resampled_minima(
        x: np.ndarray, cumulative: np.ndarray, block: int, seed: int
    ) -> np.ndarray:
        """The envelope's lowest point on each moving-block resample of the samples;
        ``cumulative``: each grid point's cumulative cost over them (a leading 0)."""
        n = cumulative.shape[1] - 1
        block = min(max(block, 1), n)
        count = max(1, round(n / block))
        starts = np.random.default_rng(seed).integers(0, n - block + 1, size=(RESAMPLES, count))
        costs = (cumulative[:, starts + block] - cumulative[:, starts]).sum(axis=2)
        coef, *_ = np.linalg.lstsq(np.vander(x, DEGREE + 1), costs, rcond=None)
        return _lowest(coef, x[0], x[-1])


def _lowest(coef: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """Where each cubic (columns of ``coef``: a, b, c, d) is lowest on [lo, hi]: its
    local minimum ``−c/(b + √(b² − 3ac))`` if inside and below both ends, else the
    lower of its ends."""
    a, b, c, d = coef

    def value(x: np.ndarray) -> np.ndarray:
        return ((a * x + b) * x + c) * x + d

    disc = b * b - 3.0 * a * c
    with np.errstate(divide="ignore", invalid="ignore"):
        local = -c / (b + np.sqrt(np.maximum(disc, 0.0)))
    inside = (disc >= 0.0) & np.isfinite(local) & (local > lo) & (local < hi)
    ends = np.where(value(np.full_like(a, lo)) <= value(np.full_like(a, hi)), lo, hi)
    local = np.where(inside, local, ends)
    return np.where(inside & (value(local) < value(ends)), local, ends)


def gauss_newton_step(columns: np.ndarray, residuals: np.ndarray, start: np.ndarray) -> np.ndarray:
    """``start`` moved by one Gauss-Newton step on ``residuals`` with the Jacobian
    ``columns`` (of those parameters, taken at the fit), kept in the unit box: where the
    parameters a profile holds would go to follow it along a curved valley."""
    if not np.isfinite(residuals).all():
        return start
    step, *_ = np.linalg.lstsq(columns, -residuals, rcond=None)
    return np.clip(start + step, 0.0, 1.0)


def estimates(
    jacobian: np.ndarray,
    residuals: np.ndarray,
    z: np.ndarray,
    values: list[float],
    to_value: Callable[[int, float], float],
    bounds: list[tuple[float, float]],
    cost: Callable[[int, float], np.ndarray] | None = None,
    spacing: float = 0.0,
    floor: float = 0.0,
    names: Sequence[str] = (),
) -> list[Estimate]:
    """95 % intervals of the values fitted at the unit-box point ``z``: the sandwich's
    and the profile's together (module docstring).

    ``jacobian``: ∂r/∂z of the training residual vector (``Replay.residual_vector``);
    ``residuals``: that vector at ``z`` as channels × samples; ``to_value(j, z_j)``: the
    SI value of parameter ``j`` at a unit-box coordinate; ``cost(j, v)``: the training
    cost of each sample with parameter ``j`` at ``v``, the others at ``z`` (None: the
    sandwich alone); ``spacing``: the profile's smallest spacing on the unit box (the
    scale the Jacobian looks at); ``floor``: the least the summed cost can be (a perfect
    model's). A parameter the data do not inform (a zero column) gets its bounds.
    ``names``: the values' names, for each one's ``trades_with`` (the sandwich's
    correlation beyond TRADES).
    """
    tau = correlation_time(residuals)
    n = residuals.shape[1]
    cov = sandwich(jacobian, residuals, long_run_lags(residuals))
    block = max(tau, n // BLOCKS)
    informed = np.all(np.isfinite(jacobian), axis=0) & (np.sum(jacobian**2, axis=0) > 0)
    out = []
    for j, value in enumerate(values):
        var = cov[j, j] if informed[j] and np.isfinite(cov[j, j]) else math.inf
        half = Z95 * math.sqrt(max(var, 0.0)) if math.isfinite(var) else math.inf
        zl, zh = max(z[j] - half, 0.0), min(z[j] + half, 1.0)
        if cost is not None and math.isfinite(half):
            step = max(half / 2.0, spacing)
            pl, ph = profile_interval(
                lambda v, j=j: cost(j, v), float(z[j]), step, block, SEED + j, floor
            )
            zl, zh = min(zl, pl), max(zh, ph)
        estimate = _estimate(value, z[j], zl, zh, lambda u, j=j: to_value(j, u), bounds[j])
        partner = _partner(cov, informed, j)
        if names and partner is not None:
            k, r = partner
            estimate = dataclasses.replace(estimate, trades_with=names[k], correlation=r)
        out.append(estimate)
    return out


def _partner(cov: np.ndarray, informed: np.ndarray, j: int) -> tuple[int, float] | None:
    """The informed value most correlated with value ``j`` in ``cov`` and their
    correlation, when its magnitude exceeds TRADES."""
    best = None
    for k in range(cov.shape[0]):
        if k == j or not (informed[j] and informed[k]):
            continue
        denominator = math.sqrt(max(cov[j, j] * cov[k, k], 0.0))
        if not (denominator > 0.0 and math.isfinite(denominator)):
            continue
        r = float(cov[j, k] / denominator)
        if abs(r) > TRADES and (best is None or abs(r) > abs(best[1])):
            best = (k, r)
    return best


def _estimate(
    value: float,
    z: float,
    zl: float,
    zh: float,
    to_value: Callable[[float], float],
    bounds: tuple[float, float],
) -> Estimate:
    """The Estimate of ``value`` (unit-box point ``z``) with the interval ``[zl, zh]`` on
    the unit box."""
    a, b = to_value(zl), to_value(zh)
    lo, hi = min(a, b, value), max(a, b, value)
    # an effect parameter at 0 is "off": a bound only when 0 is not its natural floor
    flagged = (z <= AT_BOUND and bounds[0] != 0.0) or z >= 1.0 - AT_BOUND
    return Estimate(float(value), (float(lo), float(hi)), bounds, bool(flagged))


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


def held_interval(
    column: np.ndarray,
    z: float,
    value: float,
    to_value: Callable[[float], float],
    bounds: tuple[float, float],
    cost_train: float,
    samples: int,
    effective: float,
) -> Estimate:
    """The interval of one parameter with the others held, from its Jacobian column of
    the residual vector whose sum of squares is the training cost: ``(JᵀJ)⁻¹`` inflated
    by the cost ``c`` (above the noise floor) and by samples over effective samples,
    ``cov = c · (M / M_eff) · (JᵀJ)⁻¹`` (:func:`effective_samples`)."""
    info = float(column @ column) * samples  # the residual vector is e/√M
    scale = max(cost_train, 1.0) * samples / effective
    var = scale / info if math.isfinite(info) and info > 0 else math.inf
    half = Z95 * math.sqrt(var) if math.isfinite(var) else math.inf
    return _estimate(value, z, max(z - half, 0.0), min(z + half, 1.0), to_value, bounds)
