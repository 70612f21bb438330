"""Step-response metrics of a sampled run: pure functions of arrays.

Conventions follow MATLAB ``stepinfo`` (and python-control ``step_info``): rise time,
settling time and overshoot are relative to the final value ``y_final`` and the initial
value ``y_init`` of each step, not to the reference.
"""

from __future__ import annotations

import itertools
import math
from typing import TYPE_CHECKING

import numpy as np

from fuzzyservo.metrics._types import METRIC_NAMES, Metrics, StepMetrics, moves

if TYPE_CHECKING:
    from fuzzyservo.simulation.result import SimResult

# A reference change smaller than this (relative to max(1, |r|)) is float noise, not a step
# (the reference is mapped through the feedback sensor's inverse before it reaches us).
_CHANGE_RTOL = 1e-12
# Samples this close below warmup_s still count, so a step sampled at k * dt with rounding
# error (2 = 200 * 0.01 - 4e-16) is scored when warmup_s = 2.
_WARMUP_ATOL = 1e-9
# y_final: mean over this trailing fraction of the step (at least one sample).
_FINAL_FRACTION = 0.05
#: without a sensor resolution, the output must move by this share of the reference's
#: range over the scored samples to count as moving
FALLBACK_RESOLUTION_SHARE = 1e-4

_WORST_CASE = (
    "rise_time_s",
    "settling_time_s",
    "overshoot_pct",
    "sse_abs",
    "sse_pct",
    "peak_command",
)
_SUMMED = ("saturation_time_s", "iae", "ise", "itae")


def step_metrics(
    t: np.ndarray,
    r: np.ndarray,
    y: np.ndarray,
    u: np.ndarray | None = None,
    saturated: np.ndarray | None = None,
    *,
    warmup_s: float = 0.0,
    settling_band: float = 0.02,
    rise_band: tuple[float, float] = (0.1, 0.9),
    resolution: float | None = None,
    resolution_source: str = "",
) -> Metrics:
    """Rise, settling, overshoot, steady-state error, saturation and error integrals per step.

    Parameters
    ----------
    t:
        Sample times [s], strictly increasing and uniform; ``t[0]`` may be any value.
        The sample time ``dt`` is the median spacing.
    r, y:
        Reference and measured output, same unit (the output's SI unit). ``r`` is
        piecewise constant.
    u:
        Controller command [V], or ``None`` (then ``peak_command`` is NaN).
    saturated:
        True where the actuator sits at a limit, or ``None`` (then
        ``saturation_time_s`` is NaN).
    warmup_s:
        Samples with ``t < warmup_s`` are ignored for every metric.
    settling_band:
        Settling band as a fraction of the step size ``|y_final - y_init|``.
    rise_band:
        Fractions of ``y_final - y_init`` between which the rise time is measured.
    resolution, resolution_source:
        The smallest change of ``y`` the sensor resolves [output unit] and what sets it
        (e.g. an ADC's step); ``None`` or 0: :data:`FALLBACK_RESOLUTION_SHARE` of the
        reference's range (max - min) over the scored samples and the one before them.

    Motion
        ``motion`` is ``max(y) - min(y)`` over the finite scored samples. A run with
        ``motion < resolution`` did not move: a drift below what the sensor resolves has
        no rise, settling or overshoot, so those are NaN in every step (``Metrics.moved``
        is False); the errors, integrals and command metrics are computed as usual.

    Segments and steps
        The run is split at every sample ``k`` where ``|r[k] - r[k-1]| > 1e-12 max(1, |r|)``;
        the first segment starts at ``t[0]``. A segment starting at such a change at or
        after ``warmup_s`` is a step from ``r0 = r[k-1]`` to ``r1 = r[k]``, ending before the
        next change. The first segment (no reference before it) and a segment starting
        before ``warmup_s`` are not steps. ``y_init = y[k]``; ``y_final`` is the mean of
        ``y`` over the last 5 % of the step's samples (at least one).

    Per step (MATLAB ``stepinfo`` conventions; ``d = y_final - y_init``, ``s = sign(d)``)
        - ``rise_time_s``: first time ``s (y - y_init) >= hi |d|`` minus first time
          ``>= lo |d|``, each linearly interpolated between the samples around the crossing.
        - ``settling_time_s``: from ``t_step`` to the time after which
          ``|y - y_final| <= settling_band |d|`` holds to the end of the step; the exit
          from the band is linearly interpolated. 0 if ``y`` never leaves the band; NaN if
          the last sample is outside it (not settled).
        - ``overshoot_pct = 100 max(0, max(s y) - s y_final) / |d|``; a response still creeping
          towards its final value shows a tiny positive overshoot, as ``y_final`` is a mean.
        - ``sse_abs = |r1 - y_final|``; ``sse_pct = 100 sse_abs / |r1 - r0|``.
        - ``saturation_time_s`` = count of saturated samples x ``dt``.
        - ``iae = sum |e| dt``, ``ise = sum e^2 dt``, ``itae = sum (t - t_step) |e| dt`` with
          ``e = r - y``: rectangle rule, each sample holding for one sample time (the
          zero-order hold of the sampled loop); for ``y = 1 - exp(-t/tau)`` this gives
          ``iae = tau + dt/2 + O(dt^2/tau)``.
        - ``peak_command = max |u|``.

        ``d == 0`` or NaN, or a run that did not move, makes rise, settling and overshoot
        NaN. A non-finite sample of ``y`` in a step makes ``y_final`` and everything
        computed from ``y`` NaN (no exception); ``saturation_time_s`` and
        ``peak_command`` come from ``saturated``/``u``.

    Aggregate
        Worst case (largest value) over the steps for rise, settling, overshoot, both
        steady-state errors and ``peak_command``; NaN if any step's value is NaN (an
        undefined step is not silently dropped), NaN if there is no step.
        ``saturation_time_s``, ``iae``, ``ise`` and ``itae`` are sums over every scored
        sample (``t >= warmup_s``): the steps plus any lead-in between ``warmup_s`` and the
        first step (its ``itae`` timed from its first sample). They are computed even
        when there is no step.

    Returns
    -------
    Metrics
        ``aggregate`` keyed by :data:`METRIC_NAMES` and the per-step ``steps``.

    Raises
    ------
    ValueError
        For arrays of different lengths, an empty or non-increasing ``t``, or bands
        outside their range (an input shape error, not a bad response).
    """
    t, r, y, u, saturated = _checked(t, r, y, u, saturated, settling_band, rise_band)
    n = t.size
    dt = float(np.median(np.diff(t))) if n > 1 else 0.0
    first_scored = int(np.searchsorted(t, warmup_s - _WARMUP_ATOL * max(1.0, abs(warmup_s))))

    jump = np.abs(np.diff(r)) > _CHANGE_RTOL * np.maximum(
        1.0, np.maximum(np.abs(r[1:]), np.abs(r[:-1]))
    )
    changes = np.flatnonzero(jump) + 1
    bounds = [*changes.tolist(), n]
    motion = _range(y[first_scored:])
    if resolution is None or not resolution > 0:
        # the level before the first scored sample too: a step right at warmup_s counts
        resolution = FALLBACK_RESOLUTION_SHARE * _range(r[max(first_scored - 1, 0) :])
        resolution_source = (
            f"{100 * FALLBACK_RESOLUTION_SHARE:g} % of the reference's range "
            "(the rig's feedback sensor declares no ADC or noise)"
        )
    moved = moves(motion, resolution)
    steps = [
        _step(t, r, y, u, saturated, a, b, dt, settling_band, rise_band, moved)
        for a, b in itertools.pairwise(bounds)
        if a >= first_scored
    ]

    aggregate: dict[str, float] = {}
    for name in _WORST_CASE:
        values = [getattr(step, name) for step in steps]
        aggregate[name] = float(np.max(values)) if values else math.nan
    lead_end = int(changes[changes >= first_scored][0]) if steps else n
    lead_in = _integrals(t, r, y, saturated, first_scored, lead_end, dt)
    for name in _SUMMED:
        aggregate[name] = float(lead_in[name] + sum(getattr(step, name) for step in steps))
    aggregate["command_tv"] = command_tv(u[first_scored:], dt) if u is not None else math.nan
    return Metrics(
        aggregate={name: aggregate[name] for name in METRIC_NAMES},
        steps=steps,
        motion=motion,
        resolution=float(resolution),
        resolution_source=resolution_source,
    )


def _range(values: np.ndarray) -> float:
    """``max - min`` of the finite ``values``; NaN when none is finite."""
    finite = values[np.isfinite(values)]
    return float(np.ptp(finite)) if finite.size else math.nan


def command_tv(u: np.ndarray, dt: float) -> float:
    """Chatter: the command's total variation per second, ``Σ|u[k] − u[k−1]| / (n·dt)``."""
    u = np.asarray(u, dtype=float)
    if u.size < 2 or not dt > 0:
        return math.nan
    return float(np.sum(np.abs(np.diff(u))) / (u.size * dt))


def result_metrics(result: SimResult) -> Metrics:
    """:func:`step_metrics` of a simulated run: output against the reference in its
    unit, motion judged against the feedback sensor's resolution."""
    return step_metrics(
        result.t,
        result.reference_output,
        result.output,
        result.command,
        result.saturated,
        warmup_s=result.warmup_s,
        resolution=result.resolution or None,
        resolution_source=result.resolution_source,
    )


#: metrics defined by a reference step; a reference that moves continuously (a tracked
#: wave) makes every sample a "step", and these numbers mean nothing there
STEP_ONLY = ("rise_time_s", "settling_time_s", "overshoot_pct", "sse_abs", "sse_pct", "itae")
#: a reference changing in more than this share of the scored samples is tracked, not stepped
TRACKING_SHARE = 0.05


def applicable_metrics(result: SimResult) -> tuple[str, ...]:
    """The :data:`METRIC_NAMES` that mean something for ``result``'s reference: all of them
    for steps and pulses, those not in :data:`STEP_ONLY` for a continuously moving one."""
    scored = result.t >= result.t[0] + result.warmup_s
    changes = np.count_nonzero(np.diff(result.reference_output[scored]))
    if changes > TRACKING_SHARE * max(int(scored.sum()), 1):
        return tuple(m for m in METRIC_NAMES if m not in STEP_ONLY)
    return METRIC_NAMES


def _checked(t, r, y, u, saturated, settling_band, rise_band):
    """Arrays as 1-D float (bool for ``saturated``) arrays; ``ValueError`` on bad input."""
    t = np.asarray(t, dtype=float)
    r = np.asarray(r, dtype=float)
    y = np.asarray(y, dtype=float)
    if t.ndim != 1 or t.size == 0:
        raise ValueError(
            f"t must be a non-empty 1-D array of sample times [s], got shape {t.shape}"
        )
    arrays = {"r": r, "y": y}
    if u is not None:
        u = np.asarray(u, dtype=float)
        arrays["u"] = u
    if saturated is not None:
        saturated = np.asarray(saturated, dtype=bool)
        arrays["saturated"] = saturated
    for name, values in arrays.items():
        if values.shape != t.shape:
            raise ValueError(
                f"{name} must have the shape of t {t.shape}, got {values.shape}; "
                "pass one value per sample"
            )
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise ValueError(
            "t must be finite and strictly increasing; sort the samples or drop duplicates"
        )
    if not 0 < settling_band < 1:
        raise ValueError(
            f"settling_band must lie in (0, 1), got {settling_band!r}; e.g. 0.02 for 2 %"
        )
    lo, hi = rise_band
    if not 0 <= lo < hi <= 1:
        raise ValueError(
            f"rise_band must satisfy 0 <= low < high <= 1, got {rise_band!r}; e.g. (0.1, 0.9)"
        )
    return t, r, y, u, saturated


def _integrals(t, r, y, saturated, a: int, b: int, dt: float) -> dict[str, float]:
    """Rectangle-rule error integrals and saturation time of samples ``a:b``, time from ``t[a]``."""
    e = np.abs(r[a:b] - y[a:b])
    t0 = t[a] if b > a else 0.0
    sat = math.nan if saturated is None else np.count_nonzero(saturated[a:b]) * dt
    return {
        "saturation_time_s": float(sat),
        "iae": float(np.sum(e) * dt),
        "ise": float(np.sum(e * e) * dt),
        "itae": float(np.sum((t[a:b] - t0) * e) * dt),
    }


def _step(
    t, r, y, u, saturated, a: int, b: int, dt: float, band: float, rise_band, moved: bool
) -> StepMetrics:
    """Metrics of the step at sample ``a`` (reference ``r[a-1] -> r[a]``) up to sample ``b``;
    no rise, settling or overshoot when the run did not move."""
    ts, ys = t[a:b], y[a:b]
    r0, r1 = float(r[a - 1]), float(r[a])
    y_init = float(y[a])
    if np.all(np.isfinite(ys)):
        y_final = float(np.mean(ys[-max(1, int(_FINAL_FRACTION * ys.size)) :]))
    else:
        y_final = math.nan
    d = y_final - y_init
    rise = settling = overshoot = math.nan
    if moved and math.isfinite(d) and d != 0:
        s = math.copysign(1.0, d)
        lo, hi = rise_band
        rise = _first_crossing(ts, s * (ys - y_init), hi * abs(d)) - _first_crossing(
            ts, s * (ys - y_init), lo * abs(d)
        )
        settling = _settling_time(ts, ys, y_final, band * abs(d))
        overshoot = 100.0 * max(0.0, float(np.max(s * ys)) - s * y_final) / abs(d)
    sse_abs = abs(r1 - y_final)
    return StepMetrics(
        t_step_s=float(t[a]),
        r0=r0,
        r1=r1,
        y_init=y_init,
        y_final=y_final,
        rise_time_s=rise,
        settling_time_s=settling,
        overshoot_pct=overshoot,
        sse_abs=sse_abs,
        sse_pct=100.0 * sse_abs / abs(r1 - r0),
        peak_command=math.nan if u is None else float(np.max(np.abs(u[a:b]))),
        **_integrals(t, r, y, saturated, a, b, dt),
    )


def _first_crossing(ts: np.ndarray, x: np.ndarray, level: float) -> float:
    """First time ``x`` reaches ``level`` from below, linearly interpolated; NaN if never."""
    above = np.flatnonzero(x >= level)
    if above.size == 0:
        return math.nan
    j = int(above[0])
    if j == 0:
        return float(ts[0])
    frac = (level - x[j - 1]) / (x[j] - x[j - 1])
    return float(ts[j - 1] + frac * (ts[j] - ts[j - 1]))


def _settling_time(ts: np.ndarray, ys: np.ndarray, y_final: float, tol: float) -> float:
    """Time from ``ts[0]`` after which ``|y - y_final| <= tol`` to the end; NaN if not settled.

    The last exit from the band is interpolated linearly between the last sample outside
    and the first sample inside, on the band edge that sample leaves by.
    """
    outside = np.flatnonzero(np.abs(ys - y_final) > tol)
    if outside.size == 0:
        return 0.0
    j = int(outside[-1])
    if j == ys.size - 1:
        return math.nan
    edge = y_final + math.copysign(tol, ys[j] - y_final)
    frac = (ys[j] - edge) / (ys[j] - ys[j + 1])
    return float(ts[j] + frac * (ts[j + 1] - ts[j]) - ts[0])
