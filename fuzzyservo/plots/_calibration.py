"""Calibration figures: model against measurement, residual tests, effect candidates.

Laid out as MATLAB's System Identification Toolbox shows them: ``compare`` (overlay
with the fit in the legend) and ``resid`` (correlations with a confidence band).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from fuzzyservo.display import axis_label
from fuzzyservo.plots._display import label_span

_MEASURED = "black"
_BEFORE = "tab:blue"
_AFTER = "tab:red"
_BAND = "tab:blue"
_CHOSEN = "tab:green"
_OTHER = "0.6"
_FAILED = "0.85"
_VALIDATION = "0.93"


def _channels(measured: Mapping[str, np.ndarray], what: str) -> list[str]:
    names = list(measured)
    if not names:
        raise ValueError(f"{what} needs at least one channel, got none")
    return names


def _require_channels(
    names: Sequence[str], given: Mapping[str, object], what: str, n: int | None = None
) -> None:
    missing = [c for c in names if c not in given]
    if missing:
        raise ValueError(f"{what} lacks channels {missing}; it has {sorted(given)}")
    if n is None:
        return
    for c in names:
        size = np.asarray(given[c]).size
        if size != n:
            raise ValueError(
                f"{what}[{c!r}] has {size} samples but t has {n}; pass one value per sample"
            )


def _fit_text(value: float | None) -> str:
    if value is None or math.isnan(value):
        return "n/a"
    if math.isinf(value):
        return "failed"
    return f"{value:.1f} %"


def overlay_figure(
    t: np.ndarray,
    measured: Mapping[str, np.ndarray],
    before: Mapping[str, np.ndarray],
    after: Mapping[str, np.ndarray] | None,
    units: Mapping[str, str],
    split_s: float,
    fit_before: Mapping[str, float],
    fit_after: Mapping[str, float] | None,
    title: str = "",
    window: tuple[float, float] | None = None,
) -> Figure:
    """Measured channels with the model before and after calibration, as ``compare``.

    One panel per channel of ``measured`` (shared time axis): the measurement as a thin
    black line, the model before calibration dashed, after calibration solid, each
    with its fit (``fit_percent``) in the legend, e.g. "before: 83.2 %". The held-out
    validation part ``t ≥ split_s`` is shaded and labelled. Arrays are already in the
    display units ``units`` names; NaN samples (a diverged replay) leave gaps.
    ``window`` (start, end) [s] zooms every panel to that stretch, each y-axis fitted
    to what is drawn there (a long record's detail cannot be read at full length).
    """
    t = np.asarray(t, dtype=float)
    names = _channels(measured, "overlay_figure")
    _require_channels(names, measured, "measured", t.size)
    _require_channels(names, before, "before", t.size)
    if after is not None:
        _require_channels(names, after, "after", t.size)

    fig = Figure(figsize=(9.0, 0.8 + 2.4 * len(names)), layout="tight")
    axes = fig.subplots(len(names), 1, sharex=True, squeeze=False)[:, 0]
    t_start, t_end = (float(t[0]), float(t[-1])) if t.size else (0.0, 1.0)
    for ax, name in zip(axes, names, strict=True):
        ax.plot(
            t, np.asarray(measured[name], dtype=float), color=_MEASURED, lw=0.7, label="measured"
        )
        ax.plot(
            t,
            np.asarray(before[name], dtype=float),
            color=_BEFORE,
            ls="--",
            lw=1.2,
            label=f"before: {_fit_text(fit_before.get(name))}",
        )
        if after is not None:
            fits = fit_after or {}
            ax.plot(
                t,
                np.asarray(after[name], dtype=float),
                color=_AFTER,
                lw=1.2,
                label=f"after: {_fit_text(fits.get(name))}",
            )
        shown = window or (t_start, t_end)
        _mark_validation(ax, split_s, t_start, t_end, shown)
        ax.set_ylabel(axis_label(name, units.get(name, "")))
        ax.grid(True, color="0.85", lw=0.6)
        ax.set_xlim(t_start, t_end)
        if window is not None:
            ax.set_xlim(*window)
            inside = (t >= window[0]) & (t <= window[1])
            drawn = [measured[name], before[name]] + ([after[name]] if after is not None else [])
            values = np.concatenate([np.asarray(v, dtype=float)[inside] for v in drawn])
            values = values[np.isfinite(values)]
            if values.size:
                lo, hi = float(values.min()), float(values.max())
                pad = 0.05 * (hi - lo) or 0.05 * max(abs(hi), 1e-12)
                ax.set_ylim(lo - pad, hi + pad)
        ax.legend(loc="best", fontsize=8)
    axes[-1].set_xlabel("time [s]")
    if title:
        fig.suptitle(title)
    return fig


def _mark_validation(
    ax: Axes,
    split_s: float,
    t_start: float,
    t_end: float,
    shown: tuple[float, float] | None = None,
) -> None:
    """Shade ``t ≥ split_s`` (data not used for fitting) when it lies inside the record.

    The label sits over the part of the span inside ``shown`` (the visible time window),
    so a zoomed panel keeps it in view and the layout never has to make room for it.
    """
    if not math.isfinite(split_s) or split_s >= t_end:
        return
    left = max(split_s, t_start)
    ax.axvspan(left, t_end, color=_VALIDATION, zorder=0, lw=0)
    if split_s > t_start:
        ax.axvline(split_s, color="0.5", ls=":", lw=1.0)
    lo, hi = shown or (t_start, t_end)
    label_left, label_right = max(left, lo), min(t_end, hi)
    if label_right > label_left:
        label_span(ax, label_left, label_right, "validation")


def residual_figure(
    t: np.ndarray,
    residuals: Mapping[str, np.ndarray],
    units: Mapping[str, str],
    acf: Mapping[str, tuple[np.ndarray, np.ndarray]],
    xcf: Mapping[str, tuple[np.ndarray, np.ndarray]],
    band: float,
    input_name: str,
    title: str = "",
) -> Figure:
    """Per channel: residual against time, its autocorrelation, its correlation with the input.

    One row per channel of ``residuals``, as MATLAB ``resid``: the residual (display
    units ``units``); stems of the normalised autocorrelation ``acf[c] = (lags, r)``;
    stems of the cross-correlation with input ``input_name``, ``xcf[c] = (lags, r)``
    (positive lag: the input leads, see ``calibration.residuals.cross_correlation``).
    Both correlation panels show the confidence band ``±band`` (``confidence_band``).
    """
    t = np.asarray(t, dtype=float)
    names = _channels(residuals, "residual_figure")
    _require_channels(names, residuals, "residuals", t.size)
    _require_channels(names, acf, "acf")
    _require_channels(names, xcf, "xcf")

    fig = Figure(figsize=(12.0, 0.8 + 2.3 * len(names)), layout="tight")
    axes = fig.subplots(len(names), 3, squeeze=False)
    for row, name in enumerate(names):
        ax_t, ax_a, ax_x = axes[row]
        e = np.asarray(residuals[name], dtype=float)
        ax_t.plot(t, e, color=_MEASURED, lw=0.7)
        ax_t.axhline(0.0, color="0.3", lw=0.8)
        ax_t.set_ylabel(axis_label(f"residual {name}", units.get(name, "")))
        if t.size:
            ax_t.set_xlim(float(t[0]), float(t[-1]))
        _stems(ax_a, *acf[name], band)
        _stems(ax_x, *xcf[name], band)
        for ax in (ax_t, ax_a, ax_x):
            ax.grid(True, color="0.85", lw=0.6)
        if row == 0:
            ax_t.set_title("residual", fontsize=10)
            ax_a.set_title("autocorrelation of residual", fontsize=10)
            ax_x.set_title(f"cross-correlation with {input_name} (+: input leads)", fontsize=10)
    axes[-1, 0].set_xlabel("time [s]")
    axes[-1, 1].set_xlabel("lag [samples]")
    axes[-1, 2].set_xlabel("lag [samples]")
    if title:
        fig.suptitle(title)
    return fig


def _stems(ax: Axes, lags: np.ndarray, r: np.ndarray, band: float) -> None:
    lags = np.asarray(lags, dtype=float)
    r = np.asarray(r, dtype=float)
    if lags.size:
        ax.axhspan(-band, band, color=_BAND, alpha=0.12, lw=0, zorder=0)
        ax.axhline(band, color=_BAND, ls="--", lw=0.8)
        ax.axhline(-band, color=_BAND, ls="--", lw=0.8)
        shown = np.where(np.isfinite(r), r, 0.0)
        stems = ax.stem(lags, shown, linefmt="k-", markerfmt="ko", basefmt="0.3")
        stems.markerline.set_markersize(3)
        stems.stemlines.set_linewidth(0.8)
        if not np.isfinite(r).all():
            ax.text(0.5, 0.5, "undefined (constant signal)", transform=ax.transAxes, ha="center")
        ax.set_xlim(lags[0] - 0.5, lags[-1] + 0.5)
    ax.set_ylim(-1.05, 1.05)


def candidates_figure(
    names: Sequence[str],
    scores: Sequence[float],
    baseline: float,
    noise: float,
    chosen: Sequence[str],
    title: str = "",
) -> Figure:
    """Score of every effect candidate as a horizontal bar, best (lowest) at the top.

    Lines mark the score without any added effect (``baseline``) and the noise floor
    (``noise``, a score no model can beat); ``chosen`` candidates are drawn in green
    with bold labels. The x-axis is logarithmic when the finite scores span more than
    two decades. A non-finite score (a failed fit or diverged replay) is a hatched bar
    reaching the right edge, labelled "failed".
    """
    names = list(names)
    values = np.asarray(scores, dtype=float)
    if len(names) != values.size:
        raise ValueError(
            f"names and scores must have the same length, but got {len(names)} names and "
            f"{values.size} scores; give one score per candidate"
        )
    if not names:
        raise ValueError("candidates_figure needs at least one candidate, got none")
    unknown = [c for c in chosen if c not in names]
    if unknown:
        raise ValueError(f"chosen candidates {unknown} are not among names {names}")

    finite = np.isfinite(values)
    # Stable sort, best first; failed candidates last.
    order = sorted(range(len(names)), key=lambda k: (not finite[k], values[k] if finite[k] else 0))
    shown = values[finite]
    log = bool(
        shown.size > 0 and np.all(shown > 0) and float(shown.max()) > 100.0 * float(shown.min())
    )
    marks = [v for v in (baseline, noise) if math.isfinite(v) and (v > 0 or not log)]
    reach = [*shown.tolist(), *marks]
    if log:
        left = 0.5 * min(reach)
        right = 2.0 * max(reach)
    else:
        left = min(0.0, *reach) if reach else 0.0
        top = max(0.0, *reach) if reach else 1.0
        right = top + 0.15 * (top - left) if top > left else 1.0

    fig = Figure(figsize=(7.5, 1.2 + 0.35 * len(names)), layout="tight")
    ax = fig.subplots()
    if log:
        ax.set_xscale("log")
    y = np.arange(len(names))
    start = left if log else 0.0  # a log axis has no zero
    for pos, k in zip(y, order, strict=True):
        colour = _CHOSEN if names[k] in chosen else _OTHER
        if finite[k]:
            ax.barh(pos, values[k] - start, left=start, color=colour, height=0.7)
            ax.annotate(
                f"{values[k]:.3g}",
                (values[k], pos),
                xytext=(3, 0),
                textcoords="offset points",
                va="center",
                fontsize=8,
            )
        else:
            ax.barh(
                pos,
                right - start,
                left=start,
                color=_FAILED,
                hatch="//",
                edgecolor="0.5",
                height=0.7,
            )
            ax.text(
                right,
                pos,
                "failed ",
                ha="right",
                va="center",
                fontsize=8,
                color="0.2",
                bbox={"facecolor": "white", "edgecolor": "none", "pad": 1.0},
            )
    if math.isfinite(baseline) and (baseline > 0 or not log):
        ax.axvline(baseline, color="black", ls="--", lw=1.0, label=f"no effect: {baseline:.3g}")
    if math.isfinite(noise) and (noise > 0 or not log):
        ax.axvline(noise, color="tab:purple", ls=":", lw=1.2, label=f"noise floor: {noise:.3g}")
    ax.set_yticks(y, [names[k] for k in order])
    for label, k in zip(ax.get_yticklabels(), order, strict=True):
        if names[k] in chosen:
            label.set_fontweight("bold")
    ax.invert_yaxis()
    ax.set_xlim(left, right)
    ax.set_xlabel("score (lower is better)")
    ax.grid(True, axis="x", color="0.85", lw=0.6)
    ax.set_axisbelow(True)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="best", fontsize=8)
    if title:
        ax.set_title(title)
    return fig
