"""Figures only: functions take results and return a ``matplotlib.figure.Figure``.

The only place matplotlib is imported. Figures are built on ``Figure`` directly (no
pyplot, no global backend or state), so they render headless; :func:`save` writes one.
"""

from fuzzyservo.plots._bars import metrics_bar_figure
from fuzzyservo.plots._bode import bode_figure
from fuzzyservo.plots._calibration import candidates_figure, overlay_figure, residual_figure
from fuzzyservo.plots._display import save
from fuzzyservo.plots._fuzzy import (
    control_curve_figure,
    fuzzy_overview_figure,
    membership_figure,
)
from fuzzyservo.plots._response import response_figure
from fuzzyservo.plots._robustness import distribution_figure
from fuzzyservo.plots._tuning import history_figure, importance_figure, pareto_figure

__all__ = [
    "bode_figure",
    "candidates_figure",
    "control_curve_figure",
    "distribution_figure",
    "fuzzy_overview_figure",
    "history_figure",
    "importance_figure",
    "membership_figure",
    "metrics_bar_figure",
    "overlay_figure",
    "pareto_figure",
    "residual_figure",
    "response_figure",
    "save",
]
