"""Monte Carlo of controllers on sampled plants: metric distributions, one panel per metric."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
from matplotlib.figure import Figure

from fuzzyservo.display import controller_colour

_MAX_COLUMNS = 2


def distribution_figure(
    values: Mapping[str, Mapping[str, Sequence[float]]], units: Mapping[str, str] | None = None
) -> Figure:
    """Box plots (whiskers to the extremes, every sample as a dot) of each metric:
    ``values[metric][controller]`` the samples' values (non-finite ones are left out and
    counted in the controller's label)."""
    metrics = list(values)
    if not metrics:
        raise ValueError("distribution_figure needs at least one metric, got none")
    units = units or {}
    ncols = min(_MAX_COLUMNS, len(metrics))
    nrows = math.ceil(len(metrics) / ncols)
    fig = Figure(figsize=(5.0 * ncols, 0.6 + 3.0 * nrows), layout="tight")
    axes = fig.subplots(nrows, ncols, squeeze=False).ravel()
    for ax in axes[len(metrics) :]:
        fig.delaxes(ax)
    for ax, metric in zip(axes, metrics, strict=False):
        names = list(values[metric])
        data, labels = [], []
        for name in names:
            v = np.asarray(values[metric][name], dtype=float)
            good = v[np.isfinite(v)]
            data.append(good if good.size else np.array([np.nan]))
            missing = v.size - good.size
            labels.append(f"{name}\n({missing} n/a)" if missing else name)
        ax.boxplot(data, whis=(0, 100), widths=0.5, showfliers=False)
        rng = np.random.default_rng(0)
        for k, d in enumerate(data):
            jitter = rng.uniform(-0.12, 0.12, d.size)
            ax.plot(k + 1 + jitter, d, ".", ms=3, alpha=0.5, color=controller_colour(k))
        ax.set_xticks(range(1, len(names) + 1), labels, fontsize=8)
        unit = units.get(metric, "")
        ax.set_title(f"{metric} [{unit}]" if unit else metric, fontsize=10)
        ax.grid(True, axis="y", alpha=0.3)
    return fig
