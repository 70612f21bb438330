"""What the decision would see on this record if no effect were missing (issue 28).

decision.py's error rate holds where the replay reproduces the data up to noise. A real
record never does: a rig differs from its model by more than its sensor noise, and that
model error is correlated in time and across channels. So each round's decision is
calibrated on the record at hand, with the residual ``r_c = y_c − ŷ_c`` of the round's
starting model (the whole record, every channel c of noise floor σ_c) less what the
round's candidates together explain of it (least squares on all their contributions):
what effects explain is not disturbance (with two effects missing, the one the best
candidate leaves is no model error), and on a record without a missing effect they
explain little, so this is the residual of the fitted nominal model up to that:

1. **The residual's own level and correlation** (:func:`residual_levels`): its RMS in
   noise units and its correlation time (the first lag at which its autocorrelation
   falls below 1/e).
2. **A parametric bootstrap of that null** (:func:`null_round`). A record like this one
   without a missing effect is the starting model's replay plus a disturbance with the
   residual's spectrum: a multivariate phase-randomised surrogate of ``r`` (Prichard &
   Theiler 1994, Phys. Rev. Lett. 73, 951): the Fourier transform of every channel's
   residual, one set of random phases for all channels, and back. It keeps each
   channel's spectrum (its level and autocorrelation) and the cross-spectra between
   channels, and scrambles its timing against the input, which no effect can follow.
   Each candidate is refitted on each surrogate along the direction it took on the data,
   ``ŷ + a·δ`` with ``δ`` its model minus the starting one (least squares in ``a`` on the
   training part: the fit linearised about the data's), and tested as decision.py tests
   it. No simulation is needed: the replays of the starting model and of each candidate
   are at hand. The round's threshold is the ``1 − ALPHA`` quantile of the largest z
   over the candidates in each draw (a max-T test, Westfall & Young 1993, Resampling-based
   multiple testing, Wiley), never below the one-test ``Φ⁻¹(1 − ALPHA)``; the share of
   draws whose largest z passes it is the false-positive rate on this record. It holds
   the rate as Bonferroni's ``Φ⁻¹(1 − ALPHA/K)`` does (decision.py; used without
   surrogates), without counting as K independent tests the candidates that move the
   outputs alike (a dead band, a bias and a leakage all shift the pressures at null):
   with 11 candidates Bonferroni asks z > 2.61 where their surrogates' largest z passes
   1.5-2.3 in 5 % of draws on the power records, and that gap is what a bulk modulus
   or a leakage at the middle of its typical range lacked (docs/calibration-power.md).
3. **Practical significance** (:func:`assess`). An effect is added when it passes the
   test and matters physically (significance.py: its fitted size against the sizes real
   rigs show, or, for an effect without a size, its change of a recorded signal against
   that signal's own variation; never against the residual level, which on a clean
   record is mostly noise); one that passes the test and not this is reported as
   negligible, with its size. Each judged candidate carries its detection limit on this
   record: the smallest scale ``s`` of its fitted contribution that matters and passes
   the threshold in ``REQUIRED`` of records like this one. Linearised, z grows in
   proportion to ``s`` (the log-likelihood ratio with ``s²``, its spread with ``s``), so
   that is the ``s`` at which the data's ``z`` scales to the threshold plus the
   ``REQUIRED`` quantile of the candidate's z over the surrogates (its null spread).
4. **The starting model's own prediction uncertainty** (:func:`prediction_band`). From
   the second round on, the starting model carries effects added earlier. The round's
   candidates refit their parameters along (search.py ``_freed``), but a candidate's
   gain is judged against what re-estimating them alone would do: those
   parameters are known only to their 95 % interval (each with the others held: the
   ends are models the data allow), and the outputs of the starting model at the ends
   of that interval differ from its replay by ``β`` (root sum of squares over the
   parameters of the larger end's ``‖Δŷ/σ‖``, pooled as ``share``). Where the model is
   linear in them, each adds about ``1.96/√N_eff`` of the residual level (``N_eff`` the
   record's effective samples): a few % on a record whose residual is near white, a
   fifth on the Festo record (N_eff ≈ 70), where Stribeck's three levels frozen in
   round 2 make a band of 41 % and a line resistance moving the outputs by 37 % is
   negligible.
   A candidate whose contribution is below ``β`` does less than re-estimating what the
   model already has within the data's own uncertainty, so it is negligible whatever its
   z: an effect is added only when ``share ≥ β / ‖r/σ‖``. It matters
   where the model is ill-conditioned: a piston held by Coulomb friction with the valve
   near null leaves its chamber pressures to integrate whatever tiny flow remains, so
   where it stops and at which pressures depends on the friction to a fraction of a
   newton. On the benchmark's record (300 N undeclared) the friction fitted at 295.9 N
   leaves the pressures 3 σ off in the holds, a 0.1 N change (its 95 % interval) moves
   them as much, and a leakage of 1e-16 m³/(s·Pa) (1 % of the smallest typical one) that lets
   them settle explains 70 % of that: z 18.6, far above any phase-randomised null
   (which scrambles the residual's timing against the input, and this model error is
   locked to the holds). With ``β`` it is negligible; a phase-randomised null alone
   cannot see model error that follows the input.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from scipy.special import ndtri

from fuzzyservo.calibration.decision import ALPHA, held_out_lags, long_run_variance, threshold
from fuzzyservo.calibration.replay import Replay
from fuzzyservo.calibration.significance import Practical, practical
from fuzzyservo.rig import Rig

DRAWS = 200  # surrogate records per round (numpy only: ~5 ms each with 10 candidates)
LIMIT_DRAWS = 40  # of them, for a candidate's interval and null spread of z
REQUIRED = 0.9  # detection limit: passes in this share of draws (as detection.py)
SEED = 28  # the surrogates' phases: a calibration is repeatable


class Fitted(Protocol):
    """What :func:`assess` reads of a fitted candidate (search.Candidate)."""

    name: str
    params: dict[str, float]
    model: dict[str, np.ndarray]
    status: str


@dataclass(frozen=True)
class Level:
    """One channel's residual: RMS in noise units, correlation time [s]."""

    rms_sigma: float
    correlation_s: float


@dataclass(frozen=True)
class Null:
    """A round's null distribution on its record.

    ``threshold``: the z the best must exceed, the bootstrap ``quantile`` of the largest
    z (at least the one-test quantile; ``bonferroni`` without draws);
    ``false_positive_rate``: share of the ``draws`` whose largest z passes ``threshold``
    (``bonferroni_rate``: ``bonferroni`` would pass, for comparison);
    ``band``: :func:`prediction_band` (0 in a round whose starting model has no frozen
    parameter)."""

    draws: int
    threshold: float
    bonferroni: float
    quantile: float
    false_positive_rate: float
    bonferroni_rate: float
    levels: dict[str, Level]
    band: float = 0.0  # the starting model's prediction uncertainty, share of the residual
    # the first LIMIT_DRAWS surrogates, channel -> one draw per row (for assess)
    surrogates: dict[str, np.ndarray] = field(default_factory=dict, repr=False, compare=False)


@dataclass(frozen=True)
class Assessment:
    """Whether a fitted candidate matters: ``share`` of the residual level its
    contribution reaches, its size as a ``scale`` of the fitted contribution that the
    data support (``interval``, 95 %), its detection limit on this record as a scale
    (``limit``; inf: not reachable) and how it compares physically (``practical``,
    significance.py). ``verdict``: ``added``, ``negligible`` (passes the test, too small
    to matter), ``not established``, ``failed`` (the run diverged), ``failed fit`` (the
    fit could not get below the starting model) or ``out-ranked`` (would be added, but
    another ranks first); ``reason``: why, in words."""

    name: str
    z: float
    share: float
    limit: float
    interval: tuple[float, float]
    verdict: str
    reason: str = ""
    practical: Practical | None = None


def residual_levels(
    replay: Replay, model: Mapping[str, np.ndarray]
) -> tuple[dict[str, np.ndarray], dict[str, Level]]:
    """The residual of ``model`` in noise units per channel (whole record) and its level."""
    dt = float(replay.data.sample_period_s)
    residual, levels = {}, {}
    for channel in replay.channels:
        r = (replay.measured(channel) - model[channel]) / replay.sigma[channel]
        residual[channel] = r
        levels[channel] = Level(float(np.sqrt(np.mean(r * r))), _correlation_time(r) * dt)
    return residual, levels


def _correlation_time(r: np.ndarray) -> int:
    """First lag (samples) at which the autocorrelation of ``r`` is below 1/e."""
    centred = r - np.mean(r)
    n = centred.size
    spectrum = np.fft.rfft(centred, 2 * n)
    acf = np.fft.irfft(spectrum * np.conj(spectrum))[:n]
    if acf[0] <= 0.0:
        return 0
    below = np.flatnonzero(acf / acf[0] < math.exp(-1.0))
    return int(below[0]) if below.size else n


def surrogates(
    residual: Mapping[str, np.ndarray], draws: int, seed: int
) -> tuple[dict[str, np.ndarray], ...]:
    """``draws`` phase-randomised surrogates of the channels ``residual`` about their
    means (one set of random phases for all channels; for an even length the Nyquist
    term kept)."""
    stack = _surrogate_stack(residual, draws, seed)
    return tuple({c: rows[k] for c, rows in stack.items()} for k in range(draws))


def _surrogate_stack(
    residual: Mapping[str, np.ndarray], draws: int, seed: int
) -> dict[str, np.ndarray]:
    """:func:`surrogates` as one array per channel, a draw per row."""
    rng = np.random.default_rng(seed)
    # about its mean: a constant residual is no disturbance (a null shift would take
    # it in every draw), and the spectrum's zero-frequency term cannot be randomised
    spectra = {c: np.fft.rfft(r - np.mean(r)) for c, r in residual.items()}
    n = next(iter(residual.values())).size
    m = n // 2 + 1
    phases = np.exp(2j * np.pi * rng.random((draws, m)))
    phases[:, 0] = 1.0
    if n % 2 == 0:
        phases[:, -1] = 1.0
    return {c: np.fft.irfft(s * phases, n, axis=1) for c, s in spectra.items()}


class _Direction:
    """A candidate's fitted contribution ``δ`` in noise units and the test of ``ŷ + a·δ``
    against ``ŷ`` on a record ``ŷ + d`` (d: a disturbance in noise units)."""

    def __init__(
        self, replay: Replay, base: Mapping[str, np.ndarray], model: Mapping[str, np.ndarray]
    ):
        self.split = replay.split
        self.lags = held_out_lags(replay)
        self.delta = {c: (model[c] - base[c]) / replay.sigma[c] for c in replay.channels}
        self.norm_train = sum(float(d[: self.split] @ d[: self.split]) for d in self.delta.values())

    def power(self) -> float:
        return sum(float(d @ d) for d in self.delta.values())

    def z(self, d: Mapping[str, np.ndarray], scale: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """z and fitted ``a`` (least squares of ``a·δ`` on the training part) on records
        carrying ``scale·δ`` and the disturbances ``d`` (channel -> one draw per row),
        as decision.evidence computes them, for every draw at once."""
        s = self.split
        a = np.zeros(next(iter(d.values())).shape[0])
        if self.norm_train > 0.0:
            for c, v in self.delta.items():
                a += (d[c][:, :s] + scale * v[:s]) @ v[:s]
            a /= self.norm_train
        log_lr = np.zeros_like(a)
        variance = np.zeros_like(a)
        for c, v in self.delta.items():
            e_a = d[c][:, s:] + scale * v[s:]
            explained = a[:, None] * v[s:]  # e_a − e_b
            e_b = e_a - explained
            log_lr += 0.5 * (np.einsum("ij,ij->i", e_a, e_a) - np.einsum("ij,ij->i", e_b, e_b))
            w = e_b * explained
            variance += long_run_variance(w, min(self.lags, max(w.shape[1] // 4, 1)))
        spread = np.sqrt(variance)
        z = np.divide(log_lr, spread, out=np.zeros_like(a), where=spread > 0.0)
        return z, a


def _finite(replay: Replay, model: Mapping[str, np.ndarray]) -> bool:
    return all(np.isfinite(model[c]).all() for c in replay.channels)


def _unexplained(
    residual: Mapping[str, np.ndarray], directions: Sequence[_Direction]
) -> dict[str, np.ndarray]:
    """What of ``residual`` no combination of the candidates' contributions explains:
    its least-squares remainder on all of them together (whole record, noise units)."""
    channels = list(residual)
    r = np.concatenate([residual[c] for c in channels])
    basis = np.column_stack([np.concatenate([d.delta[c] for c in channels]) for d in directions])
    coef, *_ = np.linalg.lstsq(basis, r, rcond=None)
    rest = r - basis @ coef
    sizes = np.cumsum([0] + [residual[c].size for c in channels])
    return {c: rest[sizes[k] : sizes[k + 1]] for k, c in enumerate(channels)}


def prediction_band(
    replay: Replay,
    base: Mapping[str, np.ndarray],
    frozen: Sequence[Sequence[Mapping[str, np.ndarray]]],
) -> float:
    """How far the starting model's outputs move within the 95 % intervals of its frozen
    parameters, as a share of its residual level (pooled over channels, whole record):
    ``frozen`` holds for each parameter the channels at its interval's ends; the larger
    end counts, the parameters add in quadrature (first-order propagation of independent
    errors). 0 without frozen parameters."""
    residual, _ = residual_levels(replay, base)
    level = sum(float(r @ r) for r in residual.values())
    power = 0.0
    for ends in frozen:
        moves = [
            sum(float(np.sum(((m[c] - base[c]) / replay.sigma[c]) ** 2)) for c in replay.channels)
            for m in ends
            if _finite(replay, m)
        ]
        power += max(moves, default=0.0)
    return math.sqrt(power / level) if level > 0.0 else 0.0


def null_round(
    replay: Replay,
    base: Mapping[str, np.ndarray],
    models: Sequence[Mapping[str, np.ndarray]],
    *,
    draws: int = DRAWS,
    seed: int = SEED,
    candidates: int | None = None,
    frozen: Sequence[Sequence[Mapping[str, np.ndarray]]] = (),
) -> Null:
    """The null of a round that starts from ``base`` (channels on the data grid) and
    fitted the candidates whose channels are ``models`` (finite ones are tested; the
    residual is what they leave together). ``candidates``: how many the Bonferroni
    threshold (without draws) splits the rate over (default: the models); ``frozen``:
    the starting model's channels at the interval ends of each parameter the candidates
    did not refit (:func:`prediction_band`)."""
    bonferroni = threshold(candidates or len(models))
    band = prediction_band(replay, base, frozen)
    usable = [m for m in models if _finite(replay, m)]
    residual, levels = residual_levels(replay, base)
    if draws <= 0 or not usable or not all(np.isfinite(r).all() for r in residual.values()):
        return Null(0, bonferroni, bonferroni, math.nan, math.nan, math.nan, levels, band)
    directions = [_Direction(replay, base, m) for m in usable]
    residual = _unexplained(residual, directions)
    dt = float(replay.data.sample_period_s)
    levels = {
        c: Level(float(np.sqrt(np.mean(r * r))), _correlation_time(r) * dt)
        for c, r in residual.items()
    }
    stack = _surrogate_stack(residual, draws, seed)
    largest = np.max([d.z(stack)[0] for d in directions], axis=0)
    quantile = float(np.quantile(largest, 1.0 - ALPHA))
    z_min = max(threshold(1), quantile)
    return Null(
        draws=draws,
        threshold=z_min,
        bonferroni=bonferroni,
        quantile=quantile,
        false_positive_rate=float(np.mean(largest > z_min)),
        bonferroni_rate=float(np.mean(largest > bonferroni)),
        levels=levels,
        band=band,
        surrogates={c: rows[:LIMIT_DRAWS] for c, rows in stack.items()},
    )


def assess(
    replay: Replay,
    rig: Rig,
    base: Mapping[str, np.ndarray],
    candidate: Fitted,
    z: float,
    null: Null,
) -> Assessment:
    """Share, size interval, detection limit and verdict of ``candidate`` (fitted on top
    of ``rig``, whose channels are ``base``; held-out ``z``) against the round's ``null``.

    Added when it passes the test (``z`` above the threshold), matters physically
    (significance.py) and, from the second round on, moves the outputs more than the
    effects added before do within their intervals (the band)."""
    name, model = candidate.name, candidate.model
    if candidate.status.startswith("failed fit"):
        return Assessment(name, z, math.nan, math.inf, (math.nan, math.nan), "failed fit",
                          candidate.status.removeprefix("failed fit: "))  # fmt: skip
    if not _finite(replay, model) or not math.isfinite(z):
        return Assessment(name, z, math.nan, math.inf, (math.nan, math.nan), "failed",
                          f"its replay {candidate.status or 'diverged'}")  # fmt: skip
    direction = _Direction(replay, base, model)
    residual, _ = residual_levels(replay, base)
    level = sum(float(r @ r) for r in residual.values())
    share = math.sqrt(direction.power() / level) if level > 0.0 else 0.0
    physical = practical(replay, rig, name, candidate.params, base, model)
    # the smallest scale of the fitted contribution that matters: physically, and more
    # than the band (both grow in proportion to the scale, linearised)
    limits = [physical.floor / physical.fraction if physical.fraction > 0.0 else math.inf]
    if null.band > 0.0:
        limits.append(null.band / share if share > 0.0 else math.inf)
    limit = max(limits)
    interval = (math.nan, math.nan)
    if null.surrogates:
        zs, fits = direction.z(null.surrogates)
        spread = float(np.std(fits))
        interval = (1.0 - 1.96 * spread, 1.0 + 1.96 * spread)
        # z grows in proportion to the size (the log-likelihood ratio with its square,
        # its spread with the size): found in REQUIRED of the records where its expected
        # z is the threshold plus that quantile of the null's spread of z
        needed = null.threshold + float(ndtri(REQUIRED)) * float(np.std(zs))
        limit = max(limit, needed / z if z > 0.0 else math.inf)
    if z <= null.threshold:
        verdict = "not established"
        reason = f"z {z:.2f} is not above the threshold {null.threshold:.2f}"
    elif not physical.matters:
        verdict = "negligible"
        reason = physical.words
    elif share < null.band:
        verdict = "negligible"
        reason = (
            f"it moves the outputs less ({100 * share:.3g} % of the residual level) than the "
            f"effects already added do within their 95 % intervals ({100 * null.band:.3g} %)"
        )
    else:
        verdict = "added"
        reason = physical.words
    return Assessment(name, z, share, limit, interval, verdict, reason, physical)
