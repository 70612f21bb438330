"""Bar charts comparing controllers, one small panel per metric."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
from matplotlib.figure import Figure

from fuzzyservo.display import controller_colour

_MAX_COLUMNS = 3


def metrics_bar_figure(
    names: Sequence[str], metrics: Sequence[Mapping[str, float]], keys: Sequence[str]
) -> Figure:
    """One bar chart per metric in ``keys``, one bar per controller in ``names``.

    ``metrics[k]`` holds controller ``names[k]``'s values. A value that is NaN, infinite
    or absent (a diverged run, a response that never settled) is drawn as a missing bar
    labelled ``n/a``; a key absent from every mapping is an error (likely misspelled).
    """
    names = list(names)
    keys = list(keys)
    if len(names) != len(metrics):
        raise ValueError(
            f"names and metrics must have the same length, but got {len(names)} names "
            f"and {len(metrics)} metric mappings; give one mapping per controller"
        )
    if not names:
        raise ValueError("metrics_bar_figure needs at least one controller, got none")
    if not keys:
        raise ValueError("metrics_bar_figure needs at least one metric key, got none")
    for key in keys:
        if not any(key in m for m in metrics):
            available = sorted({k for m in metrics for k in m})
            raise ValueError(f"metric {key!r} is in none of the mappings; available: {available}")

    ncols = min(_MAX_COLUMNS, len(keys))
    nrows = math.ceil(len(keys) / ncols)
    fig = Figure(figsize=(3.2 * ncols, 0.4 + 2.9 * nrows), layout="tight")
    axes = fig.subplots(nrows, ncols, squeeze=False).ravel()
    for ax in axes[len(keys) :]:
        fig.delaxes(ax)

    x = np.arange(len(names))
    colours = [controller_colour(k) for k in range(len(names))]
    for ax, key in zip(axes, keys, strict=False):
        values = np.array([float(m.get(key, np.nan)) for m in metrics])
        finite = np.isfinite(values)
        ax.bar(x, np.where(finite, values, 0.0), color=colours, width=0.65)
        top = float(np.max(np.abs(values[finite]))) if finite.any() else 1.0
        for xk, value, ok in zip(x, values, finite, strict=True):
            if ok:
                va = "bottom" if value >= 0 else "top"
                ax.annotate(
                    f"{value:.3g}",
                    (xk, value),
                    xytext=(0, 2 if value >= 0 else -2),
                    textcoords="offset points",
                    ha="center",
                    va=va,
                    fontsize=8,
                )
            else:
                ax.text(xk, 0.03 * top, "n/a", ha="center", va="bottom", fontsize=8, color="0.4")
        ax.set_title(key, fontsize=10)
        ax.set_xticks(x, names, rotation=30 if max(len(n) for n in names) > 8 else 0, ha="right")
        ax.axhline(0.0, color="0.3", lw=0.8)
        ax.grid(True, axis="y", color="0.85", lw=0.6)
        ax.set_axisbelow(True)
        ax.margins(y=0.15)
    return fig
