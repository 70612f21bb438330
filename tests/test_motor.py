"""Seed-000 servo motor: steady state against the algebraic equations, load step, convergence;
the seed's equations as written (tests/reference_plants/motor.py) stay finite everywhere."""

from __future__ import annotations

import math

import numpy as np
import pytest
from reference_plants import motor, reference_rig
from scipy.optimize import fsolve

from fuzzyservo.params import pack
from fuzzyservo.simulation import simulate
from fuzzyservo.simulation.reference import simulate_reference


def _steady_speed(u_volts: float, load_n_m: float) -> tuple[float, float]:
    """Seed 000 eq. 9, 14, 17 at rest of the derivatives, Table 2 values:
    Q = K_a·K_x·u·sqrt((P_s − P_x)/P_s), V_m·P_x = B_e·w + T_f·tanh(w/w_c) + T_L,
    Q = V_m·w + L_e·P_x."""
    kq, ps, vm, le, be, tf, wc = -1 * -1.36e-4, 70e5, 0.716e-6, 2.8e-11, 2.95e-3, 0.225, 0.5

    def eqs(z):
        w, px_bar = z
        px = px_bar * 1e5
        q = kq * u_volts * math.sqrt((ps - px) / ps)
        return [
            q - vm * w - le * px,
            (vm * px - be * w - tf * math.tanh(w / wc) - load_n_m) / vm / 1e5,
        ]

    w, px_bar = fsolve(eqs, [140.0 * u_volts, 9.0 + load_n_m / 0.716e-6 / 1e5], xtol=1e-12)
    return w, px_bar * 1e5


def test_open_loop_steady_speed(ehs160, open_loop):
    w_expected, p_expected = _steady_speed(1.0, 0.0)
    # 6 s: the flywheel (issue 11) makes the approach slow (time constant ~0.23 s), and the
    # 3 s scenario would end 1.8e-5 short of the steady state
    r = simulate(ehs160, open_loop, "unit_step", duration_s=6.0)
    assert r.status == "ok"
    assert r.output[-1] == pytest.approx(w_expected, rel=1e-5)
    p_load = r.signals["p_a"] - r.signals["p_b"]
    assert p_load[-1] == pytest.approx(p_expected, rel=1e-4)
    # the flow the valve delivers is what the motor swallows plus what leaks
    q = r.signals["q_a"][-1]
    assert q == pytest.approx(0.716e-6 * r.output[-1] + 2.8e-11 * p_load[-1], rel=1e-6)


def test_brake_slows_the_motor_to_the_loaded_equilibrium(ehs160, open_loop):
    """Seed 000 Fig. 11: a load torque lowers the open-loop speed (1 N·m brake from 2 s to 4 s)."""
    r = simulate(ehs160, open_loop, "brake")
    free, _ = _steady_speed(1.0, 0.0)
    braked, _ = _steady_speed(1.0, 1.0)
    t = r.t
    # rel 1e-3 (was 1e-4): with the flywheel (issue 11, time constant ~0.23 s) the 2 s
    # between the brake's events leave the speed 1.6e-4 short of each equilibrium
    assert r.output[np.searchsorted(t, 1.99)] == pytest.approx(free, rel=1e-3)
    assert r.output[np.searchsorted(t, 3.99)] == pytest.approx(braked, rel=1e-3)
    assert r.output[-1] == pytest.approx(free, rel=1e-3)
    assert braked < 0.8 * free


def test_position_sensor_reads_through_the_gear(ehs160, open_loop):
    """Seed 000 Table 2: K_s = 3.44 V/rad on the output shaft after the 7.5 gear."""
    r = simulate(ehs160, open_loop, "unit_step")
    np.testing.assert_allclose(r.signals["position"], 3.44 * r.signals["theta"] / 7.5)


def test_rhs_is_finite_at_and_beyond_supply_pressure():
    p = pack(reference_rig("ehs160_motor").params)
    dx = np.empty(4)
    for pl in (-200e5, -70e5, 0.0, 69.99e5, 70e5, 200e5):
        for u in (-10.0, 0.0, 10.0):
            motor.rhs(np.array([u, 50.0, 0.0, pl]), u, 0.0, p, dx)
            assert np.isfinite(dx).all()


@pytest.mark.parametrize("scenario", ["steps", "brake"])
def test_fast_loop_converges_to_tight_reference(ehs160, p_kb0105, scenario):
    fast = simulate(ehs160, p_kb0105, scenario, duration_s=2.5)
    tight = simulate_reference(ehs160, p_kb0105, scenario, duration_s=2.5, rtol=1e-9)
    assert np.max(np.abs(fast.output - tight.output)) < 0.05  # rad/s, of ~150 rad/s
    for k in ("p_a", "p_b"):
        assert np.max(np.abs(fast.signals[k] - tight.signals[k])) < 0.5e5
