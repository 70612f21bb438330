"""Calibration figures: built from hand-made records, saved headless, laid out as documented."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from fuzzyservo.calibration.residuals import (
    autocorrelation,
    confidence_band,
    cross_correlation,
)
from fuzzyservo.plots import candidates_figure, overlay_figure, residual_figure, save

DT = 0.01
T = np.arange(0.0, 4.0, DT)
UNITS = {"y": "mm", "p3": "bar"}


def _records() -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], dict[str, np.ndarray]]:
    rng = np.random.default_rng(7)
    measured = {
        "y": 50.0 * np.sin(T) + 0.1 * rng.standard_normal(T.size),
        "p3": 60.0 + 10.0 * np.cos(T) + 0.2 * rng.standard_normal(T.size),
    }
    before = {"y": 45.0 * np.sin(T - 0.05), "p3": 58.0 + 8.0 * np.cos(T)}
    after = {"y": 50.0 * np.sin(T), "p3": 60.0 + 10.0 * np.cos(T)}
    return measured, before, after


def _check_saved(fig, path) -> None:
    written = save(fig, path)
    assert written.exists()
    assert written.stat().st_size > 1000
    fig.clear()


def test_overlay_figure_with_after_shows_fits_and_validation(tmp_path):
    measured, before, after = _records()
    after["y"][200:] = np.nan  # the calibrated model diverged in validation
    fig = overlay_figure(
        T,
        measured,
        before,
        after,
        UNITS,
        split_s=3.0,
        fit_before={"y": 83.2, "p3": 71.04},
        fit_after={"y": -np.inf, "p3": 97.5},
        title="dinca — step",
    )
    axes = fig.get_axes()
    assert len(axes) == 2
    labels = [t.get_text() for t in axes[0].get_legend().get_texts()]
    assert labels == ["measured", "before: 83.2 %", "after: failed"]
    labels = [t.get_text() for t in axes[1].get_legend().get_texts()]
    assert labels == ["measured", "before: 71.0 %", "after: 97.5 %"]
    assert axes[1].get_ylabel() == "p3 [bar]"
    assert axes[0].get_ylabel() == "position y [mm]"
    assert any(t.get_text() == "validation" for t in axes[0].texts)
    _check_saved(fig, tmp_path / "overlay.png")


def test_overlay_figure_without_after(tmp_path):
    measured, before, _ = _records()
    fig = overlay_figure(T, measured, before, None, UNITS, 2.0, {"y": 90.0}, None)
    labels = [t.get_text() for t in fig.get_axes()[1].get_legend().get_texts()]
    assert labels == ["measured", "before: n/a"]
    _check_saved(fig, tmp_path / "sub" / "overlay_before.png")


def test_overlay_zoomed_into_a_long_record_keeps_its_label_in_view(tmp_path):
    """A window into the held-out part: the "validation" label sits inside the window and
    the layout is applied without matplotlib's "Tight layout not applied" warning (the
    label used to be placed mid-span, far right of a zoomed axis)."""
    t = np.linspace(0.0, 160.0, 16001)
    measured = {"y": np.sin(t)}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fig = overlay_figure(
            t, measured, measured, measured, {"y": "mm"}, 112.0, {"y": 90.0}, {"y": 95.0},
            title="a long record (held-out part, first 10 s)", window=(112.0, 122.0),
        )  # fmt: skip
        (label,) = [x for x in fig.get_axes()[0].texts if x.get_text() == "validation"]
        assert 112.0 <= label.get_position()[0] <= 122.0
        _check_saved(fig, tmp_path / "zoom.png")


def test_overlay_figure_rejects_missing_channel_and_wrong_length():
    measured, before, _ = _records()
    with pytest.raises(ValueError, match="before lacks channels"):
        overlay_figure(T, measured, {"y": before["y"]}, None, UNITS, 2.0, {}, None)
    with pytest.raises(ValueError, match="samples but t has"):
        overlay_figure(T[:-1], measured, before, None, UNITS, 2.0, {}, None)


def test_residual_figure_has_three_panels_per_channel(tmp_path):
    measured, before, _ = _records()
    u = np.sin(T)
    residuals = {c: measured[c] - before[c] for c in measured}
    residuals["p3"][5] = np.nan  # a gap in the time panel
    acf = {c: autocorrelation(np.nan_to_num(r)) for c, r in residuals.items()}
    xcf = {c: cross_correlation(np.nan_to_num(r), u) for c, r in residuals.items()}
    acf["p3"] = (acf["p3"][0], np.full(acf["p3"][0].size, np.nan))  # undefined correlations
    fig = residual_figure(
        T, residuals, UNITS, acf, xcf, confidence_band(T.size), "i", title="residuals"
    )
    axes = fig.get_axes()
    assert len(axes) == 6
    assert axes[2].get_title().startswith("cross-correlation with i")
    assert axes[4].get_xlabel() == "lag [samples]"
    _check_saved(fig, tmp_path / "residuals.svg")


def test_residual_figure_rejects_missing_correlations():
    measured, before, _ = _records()
    residuals = {c: measured[c] - before[c] for c in measured}
    acf = {"y": autocorrelation(residuals["y"])}
    with pytest.raises(ValueError, match="acf lacks channels"):
        residual_figure(T, residuals, UNITS, acf, {}, 0.1, "i")


def test_candidates_figure_sorts_best_first_and_marks_failed(tmp_path):
    names = ["coulomb", "delay", "leakage", "stribeck"]
    scores = [0.02, 0.5, np.nan, 3.0]  # spans > 2 decades: log axis
    fig = candidates_figure(names, scores, baseline=4.0, noise=0.01, chosen=["coulomb"])
    ax = fig.get_axes()[0]
    assert ax.get_xscale() == "log"
    ticks = [t.get_text() for t in ax.get_yticklabels()]
    assert ticks == ["coulomb", "delay", "stribeck", "leakage"]
    assert ax.get_yticklabels()[0].get_fontweight() == "bold"
    assert any(t.get_text().strip() == "failed" for t in ax.texts)
    assert ax.get_ylim()[0] > ax.get_ylim()[1]  # inverted: best at the top
    _check_saved(fig, tmp_path / "candidates.png")


def test_candidates_figure_linear_when_scores_are_close(tmp_path):
    fig = candidates_figure(["a", "b"], [0.4, 0.3], 0.5, 0.1, [], title="effects")
    ax = fig.get_axes()[0]
    assert ax.get_xscale() == "linear"
    assert [t.get_text() for t in ax.get_yticklabels()] == ["b", "a"]
    _check_saved(fig, tmp_path / "candidates_linear.png")


def test_candidates_figure_rejects_bad_input():
    with pytest.raises(ValueError, match="same length"):
        candidates_figure(["a"], [1.0, 2.0], 1.0, 0.1, [])
    with pytest.raises(ValueError, match="not among names"):
        candidates_figure(["a"], [1.0], 1.0, 0.1, ["b"])
    with pytest.raises(ValueError, match="at least one"):
        candidates_figure([], [], 1.0, 0.1, [])
