"""Seed-002 cylinder: the seed's equations as written (tests/reference_plants/cylinder.py:
parameters, conservation, slots) and the shipped composition (equilibrium, robustness,
convergence)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from reference_plants import cylinder, reference_rig
from scipy.optimize import fsolve
from support import ideal_sensor

from fuzzyservo.controllers.classical import OpenLoop, P
from fuzzyservo.params import pack
from fuzzyservo.simulation import simulate
from fuzzyservo.simulation.reference import simulate_reference


@pytest.fixture(scope="module")
def seed():
    """The seed-002 rig on the seed's equations as written (the mass form)."""
    return reference_rig("dinca_cylinder")


def _areas(params) -> tuple[float, float]:
    """S3, S4 [m²] of the composition's cylinder (piston, annulus)."""
    d, rod = params.cylinder__piston_diameter, params.cylinder__rod_diameter
    return math.pi / 4 * d * d, math.pi / 4 * (d * d - rod * rod)


def test_areas_match_seed(seed, dinca):
    # seed 002 §4: S3 = 7.068 cm², S4 = 5.529 cm²
    assert seed.params.area_3_m2 == pytest.approx(7.068e-4, rel=2e-4)
    assert seed.params.area_4_m2 == pytest.approx(5.529e-4, rel=2e-4)
    assert _areas(dinca.params) == pytest.approx((seed.params.area_3_m2, seed.params.area_4_m2))


def test_initial_masses_give_seed_pressures(seed, dinca):
    # seed 002 §4: m30 = 12.040 g in S3·l30, m40 = 68.280 g in S4·l40, ρ0 = 0.85 g/cm³,
    # E = 18000 bar: p = E·(m/(ρ0·V) − 1) = 35.1 bar and 35.6 bar (about pa/2)
    x0 = seed.plant.initial_state(seed.params, **seed.initial)
    p1, p2, p3, p4 = cylinder.pressures(x0, pack(seed.params))
    assert p1 == pytest.approx(70e5) and p2 == pytest.approx(0.0, abs=1e-6)
    s3_cm2, s4_cm2 = seed.params.area_3_m2 * 1e4, seed.params.area_4_m2 * 1e4
    assert p3 / 1e5 == pytest.approx(18000 * (12.040 / (0.85 * s3_cm2 * 2) - 1), rel=1e-9)
    assert p4 / 1e5 == pytest.approx(18000 * (68.280 / (0.85 * s4_cm2 * 14.5) - 1), rel=1e-9)
    assert 34 < p3 / 1e5 < 37 and 34 < p4 / 1e5 < 37
    # the composition starts from the same chamber pressures (rig file: pressure_a, _b)
    x1 = dinca.plant.initial_state(dinca.params, **dinca.initial)
    start = dict(zip(dinca.plant.states, x1, strict=True))
    assert (start["p_a"], start["p_b"]) == pytest.approx((p3, p4), rel=1e-6)


def _seed_equilibrium(params):
    """Rest equilibrium from seed 002 eq. 13-18 and eq. 20 with plain square roots.

    Unknowns p1..p4 [bar] and Δi = i − I_bias [mA], in the seed's own units:
    Qa = Q1 + Q3, Q2 + Q4 = Qr, Q1 = Q2, Q3 = Q4 and p3·S3 = p4·S4.
    """
    a, b = 0.2221 / 60, 0.0600 / 60  # l/s per sqrt(bar) (per mA)
    ra, rr = 47.2298e-3, 69.0677e-3  # l/s per sqrt(bar)
    s3, s4 = _areas(params)

    def eqs(z):
        p1, p2, p3, p4, di = z
        q1 = (a + b * di) * math.sqrt(p1 - p3)
        q2 = (a - b * di) * math.sqrt(p3 - p2)
        q3 = (a - b * di) * math.sqrt(p1 - p4)
        q4 = (a + b * di) * math.sqrt(p4 - p2)
        qa = ra * math.sqrt(70 - p1)
        qr = rr * math.sqrt(p2)
        return [qa - q1 - q3, q2 + q4 - qr, q1 - q2, q3 - q4, p3 * s3 - p4 * s4]

    return fsolve(eqs, [69.0, 0.5, 30.0, 39.0, -0.2], xtol=1e-12)


def test_p_k10_settles_on_the_seed_equilibrium(dinca, p_k10):
    """The loop settles where the valve balances the piston: i = I_bias + Δi_eq, and the
    P controller needs an error e = i/(K·K_UI) to hold that current (seed 002 §5)."""
    p1, p2, p3, p4, di = _seed_equilibrium(dinca.params)
    # the model's equilibrium: an exact reading (noise and the 0.3 mV ADC step would hide
    # the 2e-5 V error this pins; issue 11 gave the shipped rig both)
    r = simulate(ideal_sensor(dinca), p_k10, "pulses", duration_s=7.0)
    k = -1  # end of the first 5 s pulse
    assert r.status == "ok"
    assert r.actuator[k] * 1e3 == pytest.approx(2.83 + di, abs=2e-3)
    for name, expected in zip(("p_s", "p_t", "p_a", "p_b"), (p1, p2, p3, p4), strict=True):
        assert r.signals[name][k] / 1e5 == pytest.approx(expected, abs=0.02)
    e_volts = (2.83 + di) * 1e-3 / (10 * 0.010)  # K = 10, K_UI = 10 mA/V
    assert r.reference[k] - r.feedback[k] == pytest.approx(e_volts, abs=2e-5)
    # and at rest the flows balance: what comes in leaves (mass conservation)
    assert r.signals["q_in"][k] == pytest.approx(r.signals["q_ret"][k], rel=1e-6)


def test_mass_form_conserves_liquid(seed):
    """Σ d(xi)/dt = Qa − Qr exactly at any state (seed 002 eq. 3, 4, 8, 9)."""
    p = pack(seed.params)
    rng = np.random.default_rng(1)
    dx = np.empty(6)
    out = np.empty(len(cylinder.SIGNALS))
    for _ in range(200):
        x = cylinder.initial_state(
            seed.params,
            y_m=rng.uniform(-0.015, 0.14),
            p3_pa=rng.uniform(-5e5, 80e5),
            p4_pa=rng.uniform(0, 80e5),
        )
        x[1] = rng.uniform(-1, 1)
        i = rng.uniform(-0.03, 0.03)
        cylinder.rhs(x, i, 0.0, p, dx)
        cylinder.signals(x, i, 0.0, p, out)
        qa, qr = out[6], out[7]
        assert dx[2:].sum() == pytest.approx(qa - qr, abs=1e-15 + 1e-12 * abs(qa))


def test_rhs_is_finite_everywhere(seed):
    """No NaN for pressures of any sign, zero pressure drops, currents at and beyond the limits."""
    p = pack(seed.params)
    dx = np.empty(6)
    for y in (-0.03, -0.018, 0.0, 0.144, 0.2):
        for pres in (-50e5, 0.0, 35e5, 70e5, 200e5):
            for i in (-0.1, -0.03, 0.00283 - 0.0037, 0.00283, 0.00283 + 0.0037, 0.03, 0.1):
                x = cylinder.initial_state(
                    seed.params, y_m=0.0, p1_pa=pres, p2_pa=pres, p3_pa=pres, p4_pa=pres
                )
                x[0] = y
                cylinder.rhs(x, i, 0.0, p, dx)
                assert np.isfinite(dx).all()


def test_closing_current_shuts_slots(seed):
    """Beyond Δi = +I_cl slots 2 and 3 carry no flow; beyond −I_cl slots 1 and 4 (eq. 13-16)."""
    p = pack(seed.params)
    x = cylinder.initial_state(seed.params, p3_pa=30e5, p4_pa=40e5)
    _, _, q1, q2, q3, q4 = cylinder.flows(x, 0.00283 + 0.0038, p)
    assert q2 == 0.0 and q3 == 0.0 and q1 > 0 and q4 > 0
    _, _, q1, q2, q3, q4 = cylinder.flows(x, 0.00283 - 0.0038, p)
    assert q1 == 0.0 and q4 == 0.0 and q2 > 0 and q3 > 0


def test_end_stop_holds_the_piston(dinca):
    """A full-scale command drives the piston into the end stop: status end_stop, volumes positive."""
    r = simulate(dinca, OpenLoop(gain=1.0, name="full"), "steps", duration_s=3.0)
    _, hi = dinca.params.stroke_limits_m
    assert r.status == "end_stop"
    assert "end stop" in r.message
    assert np.isfinite(r.output).all()
    assert r.output.max() < hi + 1e-3  # 100 kN/mm stop: well under a millimetre of penetration
    assert np.all(np.isfinite([r.signals[k] for k in ("p_s", "p_t", "p_a", "p_b")]))


def test_diverging_controller_is_a_result_not_a_crash(dinca):
    r = simulate(
        dinca, P(gain=float("nan"), u_min=-3, u_max=3, name="nan"), "pulses", duration_s=1.0
    )
    assert r.status == "diverged"
    assert "diverged" in r.message
    assert np.isnan(r.output[-1])


@pytest.mark.parametrize("scenario", ["pulses", "steps"])
def test_fast_loop_converges_to_tight_reference(dinca, p_k10, scenario):
    """Compiled Rosenbrock loop against solve_ivp LSODA at rtol 1e-9 (the bench's accuracy
    discipline: position within 0.02 mm and pressures within 0.5 bar). An exact reading:
    this pins the integrator, and an ADC code flipped by a µm-level difference would
    move the paths apart by a 16 µm code (issue 11; tests/test_loop_fidelity.py compares
    the paths with noise and ADC on)."""
    dinca = ideal_sensor(dinca)
    fast = simulate(dinca, p_k10, scenario, duration_s=3.0)
    tight = simulate_reference(dinca, p_k10, scenario, duration_s=3.0, rtol=1e-9)
    assert np.max(np.abs(fast.output - tight.output)) < 0.02e-3
    for k in ("p_s", "p_t", "p_a", "p_b"):
        assert np.max(np.abs(fast.signals[k] - tight.signals[k])) < 0.5e5
    # tightening the tolerance moves the answer towards the reference
    finer = simulate(dinca, p_k10, scenario, duration_s=3.0, tol=0.01)
    assert np.max(np.abs(finer.output - tight.output)) < 0.005e-3
