"""The seeds' reported behaviour, reproduced (or the difference pinned and explained).

Figures of this model next to the seeds' are in docs/seeds.md and docs/reproduction.md.
"""

from __future__ import annotations

import pytest

from fuzzyservo.metrics import result_metrics
from fuzzyservo.simulation import simulate


def test_seed002_p_k10_bias_error_and_saturation(dinca, p_k10):
    """Seed 002 §5 and §8: with P K=10 "a relatively large stationary error" caused by the
    valve bias current, and the converter "works practically only at saturation" during
    the transitions.

    Model: to hold the piston the valve needs i ≈ I_bias − 0.23 mA = 2.60 mA, which a P
    controller only produces from an error e = i/(K·K_UI) = 0.026 V, i.e. 1.34 mm
    (0.026 V / 0.1936 V/cm) on every level, 2.6 % of the 5.17 cm pulse.
    """
    r = simulate(dinca, p_k10, "pulses")
    m = result_metrics(r)
    assert r.status == "ok"
    assert len(m.steps) == 4
    for step in m.steps:
        assert step.sse_abs == pytest.approx(1.34e-3, abs=0.02e-3)
        assert step.sse_pct > 2.0
        # saturated for most of each transition (to the 2 % settling band)
        assert step.saturation_time_s > 0.5 * step.settling_time_s
        # 1 V (less the 0.026 V offset) × K ≈ 10 V → 100 mA asked, 30 mA given
        assert step.peak_command > 9.7
    # the output sits below the reference on both levels: the bias is not compensated
    assert (r.reference_output - r.output)[r.t > 6.5][:10].mean() > 1e-3


def test_seed000_open_loop_step(ehs160, open_loop):
    """Seed 000 §6, Fig. 10: open-loop unit step ts = 0.9 s, tr = 0.5 s, SSE = 2.8 (volts of
    the tachogenerator).

    The steady state matches: 1 V on the valve gives 142 rad/s = 3.70 V of tachogenerator,
    SSE 2.70 V (seed 2.8 / 2.89): valve gain, leakage and friction of Table 2 agree with the
    rig. Table 2's J is the motor's alone; the rig adds the flywheel of §2, identified from
    this figure's tr = 0.5 s (ehs160_motor.yaml, inertia). Issue 11 moved this test: with
    Table 2's J alone the model rose in 0.055 s. The settling time was not fitted.
    """
    r = simulate(ehs160, open_loop, "unit_step")
    m = result_metrics(r).aggregate
    kt = 0.026  # V/(rad/s), Table 2
    assert m["sse_abs"] * kt == pytest.approx(2.8, rel=0.05)
    assert m["rise_time_s"] == pytest.approx(0.5, rel=0.05)
    assert m["settling_time_s"] == pytest.approx(0.9, rel=0.1)


def test_seed000_p_controller_step(ehs160, p_kb0105):
    """Seed 000 §6, Fig. 12: with P Kb = 0.105, ts = 0.6 s, tr = 0.4 s, SSE = 0.3.

    Read as a gain on the tachogenerator error in volts (the only reading the block
    diagram supports), Kb = 0.105 gives a loop gain of 0.105 × 3.70 = 0.39, and the
    Coulomb friction eats much of the 0.1 V it commands: the model settles at 0.11 V
    (SSE 0.89 V). The seed's SSE of 0.3 needs a loop gain near 2.3, twenty times more;
    the P controller does shorten the response (tr 0.27 s against 0.5 s open loop; the
    seed 0.4 s), as the seed reports.
    """
    r = simulate(ehs160, p_kb0105, "unit_step")
    m = result_metrics(r).aggregate
    open_tr = 0.5
    assert m["sse_abs"] * 0.026 == pytest.approx(0.89, rel=0.05)
    assert m["rise_time_s"] < open_tr


def test_seed002_flc1_cancels_the_bias_error_without_saturating(dinca, p_k10, flc1):
    """Seed 002 §6, Fig. 8: the translated output terms cancel the stationary error, and the
    command current "does not reach the saturation in any situation"."""
    run = simulate(dinca, flc1, "pulses")
    p = result_metrics(simulate(dinca, p_k10, "pulses"))
    m = result_metrics(run)
    assert run.status == "ok"
    for step in m.steps:  # both pulse levels, twice
        assert step.sse_abs <= 0.1e-3
    assert min(s.sse_abs for s in p.steps) > 1.2e-3
    assert m.aggregate["saturation_time_s"] == 0.0
    assert abs(run.actuator).max() < 0.9 * dinca.actuator.upper


def test_seed002_flc2_is_faster_than_flc1(dinca, p_k10, flc1, flc2):
    """Seed 002 §7, Fig. 10: reshaped input terms cut the response time "about 20 %" with the
    stationary error still cancelled and saturation far below P K=10."""
    m1 = result_metrics(simulate(dinca, flc1, "pulses")).aggregate
    m2 = result_metrics(simulate(dinca, flc2, "pulses"))
    p = result_metrics(simulate(dinca, p_k10, "pulses")).aggregate
    assert m2.aggregate["rise_time_s"] <= 0.8 * m1["rise_time_s"]
    assert m2.aggregate["settling_time_s"] <= 0.8 * m1["settling_time_s"]
    for step in m2.steps:
        assert step.sse_abs <= 0.1e-3
    # "reaches only for a short period the saturation": with the ±20 mA converter chosen
    # from these observations (issue 11) FLC2 saturates about a quarter of P's time (it
    # never did at ±30 mA, where this bound was 0.1 × P); FLC1 never does
    assert 0.0 < m2.aggregate["saturation_time_s"] <= 0.5 * p["saturation_time_s"]
