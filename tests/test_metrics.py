"""Step metrics against analytic responses (first- and second-order) and hand counts.

Reference values and their sources:
- first-order lag y = 1 - exp(-t/tau): 10 % at tau ln(10/9), 90 % at tau ln 10, so the
  10-90 % rise time is tau ln 9 = 2.1972 tau; |y - 1| = 0.02 at tau ln 50 = 3.9120 tau
  (MATLAB ``stepinfo(tf(1, [1 1]))``: RiseTime 2.1970, SettlingTime 3.9121);
  integral of exp(-t/tau) = tau, of exp(-2t/tau) = tau/2, of t exp(-t/tau) = tau^2.
- second-order y = 1 - exp(-zeta wn t) sin(wd t + acos zeta) / sqrt(1 - zeta^2):
  overshoot 100 exp(-zeta pi / sqrt(1 - zeta^2)) (Ogata, Modern Control Engineering,
  eq. 5-21): 16.303 % for zeta = 0.5, 37.234 % for zeta = 0.3.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest
from scipy.optimize import brentq

from fuzzyservo.metrics import METRIC_DOCS, METRIC_NAMES, Metrics, result_metrics, step_metrics

TAU = 0.1


def lag(t: np.ndarray, t_step: float, tau: float = TAU) -> np.ndarray:
    """Unit first-order step response starting at ``t_step`` (0 before)."""
    s = np.clip(t - t_step, 0.0, None)
    return 1.0 - np.exp(-s / tau)


def second_order(t: np.ndarray, t_step: float, zeta: float, wn: float = 10.0) -> np.ndarray:
    """Unit step response of wn^2 / (s^2 + 2 zeta wn s + wn^2) starting at ``t_step``."""
    s = np.clip(t - t_step, 0.0, None)
    wd = wn * math.sqrt(1 - zeta**2)
    return 1.0 - np.exp(-zeta * wn * s) * np.sin(wd * s + math.acos(zeta)) / math.sqrt(1 - zeta**2)


def overshoot_ref(zeta: float) -> float:
    """Ogata eq. 5-21: Mp = exp(-zeta pi / sqrt(1 - zeta^2)), in %."""
    return 100.0 * math.exp(-zeta * math.pi / math.sqrt(1 - zeta**2))


def unit_step_run(dt: float, t0: float = 0.0, t_end: float = 20 * TAU):
    """One sample at r = 0, then r = 1 from t0 on; y the first-order lag."""
    t = t0 + dt * np.arange(-1, round(t_end / dt) + 1)
    r = np.where(np.arange(t.size) >= 1, 1.0, 0.0)
    return t, r, lag(t, t[1])


@pytest.mark.parametrize("dt", [TAU / 1000, TAU / 5])
def test_first_order_lag(dt):
    t, r, y = unit_step_run(dt)
    m = step_metrics(t, r, y)
    assert len(m.steps) == 1
    step = m.steps[0]
    assert step.t_step_s == pytest.approx(t[1])
    assert (step.r0, step.r1, step.y_init) == (0.0, 1.0, 0.0)
    # interpolation of a convex curve: error well below one sample
    assert m.aggregate["rise_time_s"] == pytest.approx(TAU * math.log(9), abs=dt)
    assert m.aggregate["settling_time_s"] == pytest.approx(TAU * math.log(50), abs=dt)
    # y_final is the mean of the last 5 %, a hair below the still-creeping peak
    assert m.aggregate["overshoot_pct"] == pytest.approx(0.0, abs=1e-4)
    assert m.aggregate["sse_abs"] == pytest.approx(0.0, abs=1e-6)
    assert m.aggregate["sse_pct"] == pytest.approx(0.0, abs=1e-4)
    # rectangle rule: tau + dt/2 + O(dt^2/tau)
    assert m.aggregate["iae"] == pytest.approx(TAU, abs=0.6 * dt)
    assert m.aggregate["ise"] == pytest.approx(TAU / 2, abs=0.6 * dt)
    assert m.aggregate["itae"] == pytest.approx(TAU**2, rel=0.01)
    assert m.aggregate["iae"] == m.steps[0].iae


def test_fine_sampling_integrals_converge():
    t, r, y = unit_step_run(TAU / 10000)
    m = step_metrics(t, r, y)
    assert m.aggregate["iae"] == pytest.approx(TAU, rel=1e-3)
    assert m.aggregate["ise"] == pytest.approx(TAU / 2, rel=1e-3)
    assert m.aggregate["itae"] == pytest.approx(TAU**2, rel=1e-3)
    # interpolated, so much tighter than a sample at this resolution
    assert m.aggregate["rise_time_s"] == pytest.approx(TAU * math.log(9), rel=1e-6)
    assert m.aggregate["settling_time_s"] == pytest.approx(TAU * math.log(50), rel=1e-5)


@pytest.mark.parametrize("zeta", [0.5, 0.3])
def test_second_order_overshoot(zeta):
    dt = 1e-4
    t = dt * np.arange(-1, 50_001)
    r = np.where(t >= 0, 1.0, 0.0)
    y = second_order(t, 0.0, zeta)
    m = step_metrics(t, r, y)
    assert m.aggregate["overshoot_pct"] == pytest.approx(overshoot_ref(zeta), rel=1e-3)
    # rise time against the analytic response solved for 10 % and 90 % (first crossings,
    # before the peak at pi / wd)
    t_peak = math.pi / (10.0 * math.sqrt(1 - zeta**2))
    t10 = brentq(lambda s: second_order(np.array([s]), 0.0, zeta)[0] - 0.1, 0.0, t_peak)
    t90 = brentq(lambda s: second_order(np.array([s]), 0.0, zeta)[0] - 0.9, 0.0, t_peak)
    assert m.aggregate["rise_time_s"] == pytest.approx(t90 - t10, abs=dt)


def test_steady_state_error():
    # definition: y_final = 0.9 for a unit step -> |1 - 0.9| = 0.1, 10 % of the step
    t, r, y = unit_step_run(TAU / 100)
    m = step_metrics(t, r, 0.9 * y)
    assert m.aggregate["sse_abs"] == pytest.approx(0.1, abs=1e-6)
    assert m.aggregate["sse_pct"] == pytest.approx(10.0, abs=1e-4)
    # stepinfo is relative to y_final: the scaled lag still rises in tau ln 9
    assert m.aggregate["rise_time_s"] == pytest.approx(TAU * math.log(9), abs=TAU / 100)
    assert m.aggregate["overshoot_pct"] == pytest.approx(0.0, abs=1e-4)


def multi_step_run(dt: float = 1e-4):
    """r: 0, up to 1 at t = 1 (zeta 0.5), down to 0.5 at t = 4 (zeta 0.3), end at 7."""
    t = dt * np.arange(round(7.0 / dt))
    r = np.select([t >= 4.0 - 1e-12, t >= 1.0 - 1e-12], [0.5, 1.0], 0.0)
    y = second_order(t, t[np.argmax(t >= 1.0 - 1e-12)], 0.5)
    k2 = int(np.argmax(t >= 4.0 - 1e-12))
    y2_init = y[k2]
    y[k2:] = y2_init + (0.5 - y2_init) * second_order(t[k2:], t[k2], 0.3)
    return t, r, y


def test_multi_step_up_and_down():
    dt = 1e-4
    t, r, y = multi_step_run(dt)
    m = step_metrics(t, r, y)
    assert len(m.steps) == 2
    up, down = m.steps
    assert (up.r0, up.r1, down.r0, down.r1) == (0.0, 1.0, 1.0, 0.5)
    assert up.t_step_s == pytest.approx(1.0, abs=dt)
    assert down.t_step_s == pytest.approx(4.0, abs=dt)
    assert up.overshoot_pct == pytest.approx(overshoot_ref(0.5), rel=1e-3)
    # the down step overshoots below 0.5: measured downward, positive
    assert down.overshoot_pct == pytest.approx(overshoot_ref(0.3), rel=1e-3)
    assert up.rise_time_s > 0 and down.rise_time_s > 0
    assert down.y_final == pytest.approx(0.5, abs=1e-4)
    agg = m.aggregate
    for name in ("rise_time_s", "settling_time_s", "overshoot_pct", "sse_abs", "sse_pct"):
        assert agg[name] == max(getattr(up, name), getattr(down, name))
    assert agg["overshoot_pct"] == down.overshoot_pct
    for name in ("iae", "ise", "itae"):
        assert agg[name] == pytest.approx(getattr(up, name) + getattr(down, name), rel=1e-12)
    # hand count: the lead-in (r = y = 0) adds nothing, so iae is the plain sum over samples
    assert agg["iae"] == pytest.approx(np.sum(np.abs(r - y)) * dt, rel=1e-12)


def test_warmup_excludes_first_step_and_its_samples():
    dt = 1e-4
    t, r, y = multi_step_run(dt)
    m = step_metrics(t, r, y, warmup_s=1.5)
    assert len(m.steps) == 1
    assert m.steps[0].r1 == 0.5
    scored = t >= 1.5
    # lead-in from 1.5 s to the step at 4 s counts in the integrals, not as a step
    assert m.aggregate["iae"] == pytest.approx(np.sum(np.abs(r - y)[scored]) * dt, rel=1e-12)
    assert m.aggregate["iae"] > m.steps[0].iae
    assert m.aggregate["overshoot_pct"] == m.steps[0].overshoot_pct


def test_step_exactly_at_warmup_is_scored():
    dt = 0.01
    t = dt * np.arange(800)  # 200 * 0.01 carries rounding error
    r = np.where(np.arange(800) >= 200, 1.0, 0.0)
    y = lag(t, t[200])
    m = step_metrics(t, r, y, warmup_s=2.0)
    assert len(m.steps) == 1
    assert m.steps[0].t_step_s == pytest.approx(2.0)


def test_saturation_time_counts_scored_samples():
    dt = 1e-3
    t, r, y = unit_step_run(dt)
    saturated = np.zeros(t.size, dtype=bool)
    saturated[1:8] = True  # 7 samples from the step on
    m = step_metrics(t, r, y, saturated=saturated)
    assert m.aggregate["saturation_time_s"] == pytest.approx(7 * dt)
    assert m.steps[0].saturation_time_s == pytest.approx(7 * dt)
    # samples before the warm-up do not count
    m = step_metrics(t, r, y, saturated=saturated, warmup_s=t[5] - dt / 2)
    assert m.steps == []
    assert m.aggregate["saturation_time_s"] == pytest.approx(3 * dt)


def test_peak_command_and_missing_inputs():
    t, r, y = multi_step_run(1e-3)
    u = np.where(t < 4.0, 2.0, -3.5)
    m = step_metrics(t, r, y, u)
    assert m.steps[0].peak_command == 2.0
    assert m.steps[1].peak_command == 3.5
    assert m.aggregate["peak_command"] == 3.5
    m = step_metrics(t, r, y)
    assert math.isnan(m.aggregate["peak_command"])
    assert math.isnan(m.aggregate["saturation_time_s"])


def test_nan_output_gives_nan_not_exception():
    t, r, y = multi_step_run(1e-3)
    y[t > 5.0] = np.nan  # a run that diverged during the second step
    m = step_metrics(t, r, y, np.zeros_like(t), np.zeros(t.size, dtype=bool))
    up, down = m.steps
    assert math.isfinite(up.overshoot_pct) and math.isfinite(up.iae)
    for name in ("y_final", "rise_time_s", "settling_time_s", "overshoot_pct", "sse_abs", "iae"):
        assert math.isnan(getattr(down, name))
    for name in (
        "rise_time_s",
        "settling_time_s",
        "overshoot_pct",
        "sse_abs",
        "sse_pct",
        "iae",
        "itae",
    ):
        assert math.isnan(m.aggregate[name])
    assert m.aggregate["saturation_time_s"] == 0.0
    json.dumps(m.to_dict(), allow_nan=False)


def test_degenerate_steps_give_nan():
    t, r, _ = unit_step_run(1e-3)
    m = step_metrics(t, r, np.zeros_like(t))  # y never moves: y_final == y_init
    step = m.steps[0]
    assert math.isnan(step.rise_time_s) and math.isnan(step.settling_time_s)
    assert math.isnan(step.overshoot_pct)
    assert step.sse_abs == 1.0 and step.sse_pct == 100.0
    # last sample outside the 2 % band: not settled within the step
    y = lag(t, t[1])
    y[-1] += 0.5
    assert math.isnan(step_metrics(t, r, y).aggregate["settling_time_s"])


def test_nonzero_start_time():
    dt = TAU / 100
    m0 = step_metrics(*unit_step_run(dt))
    m1 = step_metrics(*unit_step_run(dt, t0=100.0), warmup_s=50.0)
    assert m1.steps[0].t_step_s == pytest.approx(100.0)
    for name in METRIC_NAMES:
        a, b = m0.aggregate[name], m1.aggregate[name]
        assert (math.isnan(a) and math.isnan(b)) or b == pytest.approx(a, rel=1e-6, abs=1e-9)


def test_no_step_after_warmup():
    dt = 1e-3
    t = dt * np.arange(1000)
    r = np.ones_like(t)
    y = np.full_like(t, 0.8)
    m = step_metrics(t, r, y, warmup_s=0.5)
    assert m.steps == []
    for name in ("rise_time_s", "settling_time_s", "overshoot_pct", "sse_abs", "sse_pct"):
        assert math.isnan(m.aggregate[name])
    # 500 scored samples of |e| = 0.2
    assert m.aggregate["iae"] == pytest.approx(500 * 0.2 * dt)
    assert m.aggregate["ise"] == pytest.approx(500 * 0.04 * dt)


def test_reference_noise_is_not_a_step():
    t, r, y = unit_step_run(1e-3)
    r = r * (1 + 1e-15 * np.sin(np.arange(t.size)))
    assert len(step_metrics(t, r, y).steps) == 1


def test_to_dict_is_json_friendly():
    t, r, y = multi_step_run(1e-3)
    m = step_metrics(t, r, y)
    d = m.to_dict()
    assert list(d["metrics"]) == list(METRIC_NAMES)
    assert d["metrics"]["peak_command"] is None
    assert d["metrics"]["command_tv"] is None
    assert len(d["steps"]) == 2 and d["steps"][1]["r1"] == 0.5
    json.dumps(d, allow_nan=False)


def test_names_docs_and_frozen():
    assert METRIC_NAMES == (
        "rise_time_s",
        "settling_time_s",
        "overshoot_pct",
        "sse_abs",
        "sse_pct",
        "saturation_time_s",
        "iae",
        "ise",
        "itae",
        "peak_command",
        "command_tv",
    )
    assert set(METRIC_DOCS) == set(METRIC_NAMES)
    assert all("[" in doc and "\n" not in doc for doc in METRIC_DOCS.values())
    m = step_metrics(*unit_step_run(1e-3))
    assert isinstance(m, Metrics)
    with pytest.raises(AttributeError):
        m.steps[0].iae = 0.0


def test_result_metrics_reads_a_sim_result():
    from fuzzyservo.simulation.result import SimResult

    t, r, y = multi_step_run(1e-3)
    u = np.full_like(t, 1.5)
    sat = t < 0.1
    result = SimResult(
        rig="test",
        scenario="steps",
        controller="p",
        t=t,
        reference=r * 10,  # feedback volts: must not be used
        reference_output=r,
        feedback=y * 10,
        output=y,
        command=u,
        actuator=u,
        saturated=sat,
        signals={},
        units={"y": "m"},
        output_name="y",
        actuator_name="i",
        actuator_limits=(-1.0, 1.0),
        sample_time_s=1e-3,
        warmup_s=0.5,
    )
    assert result_metrics(result) == step_metrics(t, r, y, u, sat, warmup_s=0.5)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"y": np.zeros(3)}, "shape of t"),
        ({"t": np.array([0.0, 0.0, 1.0, 2.0])}, "strictly increasing"),
        ({"settling_band": 0.0}, "settling_band"),
        ({"rise_band": (0.9, 0.1)}, "rise_band"),
    ],
)
def test_bad_input_raises(kwargs, match):
    args = {"t": np.arange(4.0), "r": np.zeros(4), "y": np.zeros(4)} | kwargs
    with pytest.raises(ValueError, match=match):
        step_metrics(**args)


def test_import_pulls_no_plotting_yaml_or_optuna():
    code = (
        "import sys, fuzzyservo.metrics; "
        "print([m for m in ('matplotlib', 'yaml', 'optuna') if m in sys.modules])"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
