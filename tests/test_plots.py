"""Figures: built from hand-made results, saved headless, laid out as documented."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from fuzzyservo.plots import metrics_bar_figure, response_figure, save
from fuzzyservo.simulation.result import SimResult

TS = 0.01


def _result(controller: str, *, kind: str, gain: float = 1.0, status: str = "ok") -> SimResult:
    t = np.arange(0.0, 2.0, TS)
    ref_v = np.where(t >= 0.5, 1.0, 0.0)
    shape = 1.0 - np.exp(-np.clip(t - 0.5, 0.0, None) * 8.0 * gain)
    if kind == "cylinder":
        ref = ref_v * 0.05  # m: 1 V of feedback is 5 cm
        output = 0.05 * shape
        actuator = np.clip(gain * 0.02 * (ref_v - shape), -0.03, 0.03)  # A
        limits = (-0.03, 0.03)
        p = 1e5 * np.vstack([100 - 20 * shape, 10 + 5 * shape, 60 + 10 * shape, 40 - 10 * shape])
        pressures = ("p_s", "p_t", "p_a", "p_b")  # seed 002's p1..p4
        signals = dict(zip(pressures, p, strict=True)) | {"y": output}
        units = dict.fromkeys(pressures, "Pa") | {"y": "m"}
        names = ("y", "i", "cylinder", {"y": "cm"})
        input_unit = "A"
    else:
        ref = ref_v * 100.0  # rad/s
        output = 100.0 * shape
        actuator = np.clip(gain * 5.0 * (ref_v - shape), -10.0, 10.0)  # V
        limits = (-10.0, 10.0)
        p_load = 1e5 * (50 + 30 * shape)
        signals = {"w": output, "p_a": (70e5 + p_load) / 2, "p_b": (70e5 - p_load) / 2}
        signals["q_a"] = 1e-4 * shape
        units = {"w": "rad/s", "p_a": "Pa", "p_b": "Pa", "q_a": "m^3/s"}
        names = ("w", "u_c", "motor", {})
        input_unit = "V"
    output_name, actuator_name, rig, display_units = names
    return SimResult(
        rig=rig,
        scenario="step",
        controller=controller,
        t=t,
        reference=ref_v,
        reference_output=ref,
        feedback=ref_v * shape,
        output=output,
        command=actuator,
        actuator=actuator,
        saturated=np.abs(actuator) >= max(limits) * (1 - 1e-9),
        signals=signals,
        units=units,
        output_name=output_name,
        actuator_name=actuator_name,
        actuator_limits=limits,
        sample_time_s=TS,
        warmup_s=0.2,
        status=status,
        display_units=display_units,
        actuator_unit=input_unit,
    )


def _labels(fig) -> list[str]:
    return [ax.get_ylabel() for ax in fig.axes]


def _legend(ax) -> list[str]:
    return [text.get_text() for text in ax.get_legend().get_texts()]


def _check_png(fig, path) -> None:
    written = save(fig, path)
    assert written == path
    assert path.stat().st_size > 1000
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_response_cylinder_single_shows_four_pressures_in_bar(tmp_path):
    result = _result("P K=10", kind="cylinder", gain=3.0)
    assert result.saturated.any()
    fig = response_figure([result])
    assert len(fig.axes) == 3
    assert _labels(fig) == ["position y [cm]", "valve current i [mA]", "pressure [bar]"]
    assert fig.axes[2].get_xlabel() == "time [s]"
    assert _legend(fig.axes[2]) == ["p_s", "p_t", "p_a", "p_b"]
    # SI to display: 5 cm, 30 mA limits, 100 bar
    ax_out, ax_act, ax_p = fig.axes
    assert np.nanmax(ax_out.lines[1].get_ydata()) == pytest.approx(5.0, rel=1e-3)
    limit_lines = [line for line in ax_act.lines if line.get_linestyle() == ":"]
    assert sorted(line.get_ydata()[0] for line in limit_lines) == pytest.approx([-30.0, 30.0])
    assert np.max(ax_p.lines[0].get_ydata()) == pytest.approx(100.0)
    assert "saturated (P K=10)" in _legend(ax_act)
    assert fig._suptitle.get_text() == "cylinder — step"
    _check_png(fig, tmp_path / "cylinder.png")


def test_response_cylinder_two_controllers_compares_p_a_p_b(tmp_path):
    results = [
        _result("P K=10", kind="cylinder", gain=3.0),
        _result("fuzzy", kind="cylinder", status="diverged"),
    ]
    fig = response_figure(results)
    assert len(fig.axes) == 3
    ax_out, _, ax_p = fig.axes
    assert _legend(ax_out) == ["reference", "P K=10", "fuzzy (diverged)"]
    assert _legend(ax_p) == [
        "p_a P K=10", "p_b P K=10", "p_a fuzzy (diverged)", "p_b fuzzy (diverged)"
    ]  # fmt: skip
    styles = [line.get_linestyle() for line in ax_p.lines]
    assert styles == ["-", "-", "--", "--"]
    _check_png(fig, tmp_path / "sub" / "cylinder_two.png")


def test_response_motor_shows_port_pressures_and_actuator_in_volts(tmp_path):
    results = [_result("PI", kind="motor"), _result("fuzzy", kind="motor", gain=2.0)]
    fig = response_figure(results)
    assert len(fig.axes) == 3
    assert _labels(fig) == [
        "speed w [rad/s]",
        "valve input u_c [V]",
        "pressure [bar]",
    ]
    assert _legend(fig.axes[2]) == ["p_a PI", "p_b PI", "p_a fuzzy", "p_b fuzzy"]
    _check_png(fig, tmp_path / "motor.png")


def test_response_rejects_empty_and_mixed_rigs():
    with pytest.raises(ValueError, match="at least one"):
        response_figure([])
    with pytest.raises(ValueError, match="one figure per"):
        response_figure([_result("a", kind="cylinder"), _result("b", kind="motor")])


def test_metrics_bar_figure_marks_nan_as_na(tmp_path):
    names = ["P K=10", "fuzzy"]
    metrics = [
        {"rise_time_s": 0.12, "overshoot_pct": 3.0, "iae": 0.4, "settling_time_s": 0.5},
        {"rise_time_s": 0.08, "overshoot_pct": float("nan"), "iae": 0.3},
    ]
    keys = ["rise_time_s", "overshoot_pct", "iae", "settling_time_s"]
    fig = metrics_bar_figure(names, metrics, keys)
    assert len(fig.axes) == len(keys)
    assert [ax.get_title() for ax in fig.axes] == keys
    for ax in fig.axes:
        assert [t.get_text() for t in ax.get_xticklabels()] == names
    overshoot = fig.axes[1]
    assert [t.get_text() for t in overshoot.texts] == ["3", "n/a"]
    assert [bar.get_height() for bar in overshoot.patches] == [3.0, 0.0]
    assert [t.get_text() for t in fig.axes[3].texts] == ["0.5", "n/a"]  # absent key
    _check_png(fig, tmp_path / "metrics.png")


def test_metrics_bar_figure_rejects_bad_input():
    with pytest.raises(ValueError, match="same length"):
        metrics_bar_figure(["a", "b"], [{"x": 1.0}], ["x"])
    with pytest.raises(ValueError, match="none of the mappings"):
        metrics_bar_figure(["a"], [{"rise_time_s": 1.0}], ["rise_time"])


def test_import_fuzzyservo_does_not_import_matplotlib():
    code = (
        "import sys, fuzzyservo, fuzzyservo.simulation; "
        "assert 'matplotlib' not in sys.modules, 'matplotlib was imported'"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
