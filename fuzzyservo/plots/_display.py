"""What the figures share beyond :mod:`fuzzyservo.display`: span labels and saving."""

from __future__ import annotations

from pathlib import Path

from matplotlib.axes import Axes
from matplotlib.figure import Figure

from fuzzyservo.atomic import atomic_write


def label_span(ax: Axes, start: float, end: float, text: str) -> None:
    """A small grey label at the top of a shaded time span (warm-up, validation)."""
    ax.text(
        0.5 * (start + end),
        0.98,
        text,
        transform=ax.get_xaxis_transform(),
        ha="center",
        va="top",
        fontsize=8,
        color="0.45",
    )


def save(fig: Figure, path: str | Path) -> Path:
    """Write ``fig`` to ``path`` (PNG unless the suffix names another format) at 120 dpi,
    whole or not at all (:func:`fuzzyservo.atomic.atomic_write`).

    Creates the parent folder; leaves the figure open and touches no pyplot state.
    """
    path = Path(path)
    fmt = path.suffix[1:].lower() or "png"
    with atomic_write(path, "wb") as fh:
        fig.savefig(fh, dpi=120, format=fmt)
    return path
