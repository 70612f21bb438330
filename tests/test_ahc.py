"""Seed-001 AHC stand: equilibria and flow conservation of the seed's equations as written
(tests/reference_plants), supply-pressure steps and heave compensation of the shipped rigs."""

from __future__ import annotations

import math

import numpy as np
import pytest
from reference_plants import ahc_cylinder, ahc_motor, reference_rig
from scipy.optimize import fsolve
from support import controller_named, rig_named

from fuzzyservo.metrics import compensation_pct, heave_metrics, result_metrics
from fuzzyservo.params import pack
from fuzzyservo.simulation import simulate
from fuzzyservo.simulation.reference import simulate_reference

PRESSURES = ("steps_5mpa", "steps_10mpa", "steps_15mpa")


@pytest.fixture(scope="module")
def cyl():
    return rig_named("ahc_cylinder")


@pytest.fixture(scope="module")
def mot():
    return rig_named("ahc_motor")


@pytest.fixture(scope="module")
def seed_cyl():
    return reference_rig("ahc_cylinder")


@pytest.fixture(scope="module")
def seed_mot():
    return reference_rig("ahc_motor")


@pytest.fixture(scope="module")
def p_cyl():
    return controller_named("p_ahc_cylinder")


@pytest.fixture(scope="module")
def p_mot():
    return controller_named("p_ahc_motor")


@pytest.fixture(scope="module")
def flc_mot():
    return controller_named("flc_ahc_motor")


def test_seed_diameters_are_read_swapped(cyl):
    """Seed 001 §3 prints piston 60 mm / rod 100 mm; the rig reads them swapped."""
    piston, rod = cyl.params.cylinder__piston_diameter, cyl.params.cylinder__rod_diameter
    assert (piston, rod) == (pytest.approx(0.100), pytest.approx(0.060))
    assert 1 - (rod / piston) ** 2 == pytest.approx(0.64)


def _cylinder_rest(params, load_n: float, y: float = 0.2) -> np.ndarray:
    """Solve dx/dt = 0 at v = 0 for the spool opening and the two chamber pressures."""
    p = pack(params)
    dx = np.empty(5)

    def eqs(z):
        s, pa_mpa, pb_mpa = z
        ahc_cylinder.rhs(np.array([s, y, 0.0, pa_mpa * 1e6, pb_mpa * 1e6]), 10 * s, load_n, p, dx)
        return [dx[2], dx[3] * 1e3, dx[4] * 1e3]

    s, pa, pb = fsolve(eqs, [0.0, 5.0, 7.0], xtol=1e-13)
    return np.array([s, y, 0.0, pa * 1e6, pb * 1e6])


def test_cylinder_at_rest_holds_with_leakage_balanced(seed_cyl):
    """Seed 001 eq. 1-9 at rest: A·p_a − a·A·p_b = F; valve flows equal the leakages."""
    params = seed_cyl.params
    x = _cylinder_rest(params, 415.0)
    p = pack(params)
    dx = np.empty(5)
    ahc_cylinder.rhs(x, 10 * x[0], 415.0, p, dx)
    assert np.abs(dx[1:]).max() < 1e-9 * 1e6  # v, accelerations and pressure rates vanish
    a, ab = params.area_a_m2, params.area_b_m2
    assert a * x[3] - ab * x[4] == pytest.approx(415.0, rel=1e-6)
    out = np.empty(len(ahc_cylinder.SIGNALS))
    ahc_cylinder.signals(x, 10 * x[0], 415.0, p, out)
    sig = dict(zip(ahc_cylinder.SIGNALS, out, strict=True))
    # eq. 1-2 at rest: Q_a = Q_v, Q_b = Q_vb − Q_v
    assert sig["q_a"] == pytest.approx(sig["q_v"], rel=1e-6)
    assert sig["q_b"] == pytest.approx(sig["q_vb"] - sig["q_v"], rel=1e-6)
    # conservation: what the supply gives and the tank does not get leaks past the rod
    assert sig["q_supply"] - sig["q_return"] == pytest.approx(sig["q_vb"], rel=1e-6)
    # holding needs 0.3 % of the opening: the leakages are small against the valve
    assert abs(x[0]) < 1e-2


def test_motor_holding_the_load_balances_torque(seed_mot):
    """Motor at rest under the 5 kg load: m·g·r = (p_b − p_a)·D_m·η_hm (eq. 15)."""
    params = seed_mot.params
    p = pack(params)
    dx = np.empty(5)

    def eqs(z):
        s, pa_mpa, pb_mpa = z
        ahc_motor.rhs(np.array([s, 0.0, 0.0, pa_mpa * 1e6, pb_mpa * 1e6]), 10 * s, 0.0, p, dx)
        return [dx[1], dx[3] * 1e3, dx[4] * 1e3]

    pa0, pb0 = ahc_motor.holding_pressures(params)
    s, pa, pb = fsolve(eqs, [0.0, pa0 / 1e6, pb0 / 1e6], xtol=1e-13)
    x = np.array([s, 0.0, 0.0, pa * 1e6, pb * 1e6])
    ahc_motor.rhs(x, 10 * s, 0.0, p, dx)
    assert np.abs(dx).max() < 1e-6
    mgr = 5.0 * 9.81 * 0.1
    assert mgr == pytest.approx((x[4] - x[3]) * params.displacement_m3_rad * 0.92, rel=1e-9)
    assert (x[4] - x[3]) == pytest.approx(pb0 - pa0, rel=1e-9)
    out = np.empty(len(ahc_motor.SIGNALS))
    ahc_motor.signals(x, 10 * s, 0.0, p, out)
    sig = dict(zip(ahc_motor.SIGNALS, out, strict=True))
    # no external leakage: supply and return flows balance; port A feeds the motor leak
    assert sig["q_supply"] == pytest.approx(sig["q_return"], rel=1e-9)
    assert sig["q_a"] == pytest.approx(sig["q_lea"], rel=1e-6)
    assert sig["q_b"] == pytest.approx(-sig["q_lea"], rel=1e-6)


def test_rhs_is_finite_everywhere(seed_cyl, seed_mot):
    pc, pm = pack(seed_cyl.params), pack(seed_mot.params)
    dx = np.empty(5)
    for s in (-1.2, -1.0, -1e-9, 0.0, 1e-9, 1.0, 1.2):
        for pa in (-1e6, 0.0, 5e6, 10e6, 30e6):
            for pb in (-1e6, 0.0, 10e6, 30e6):
                for y in (-0.01, 0.0, 0.2, 0.4, 0.41):
                    ahc_cylinder.rhs(np.array([s, y, 0.3, pa, pb]), 10 * s, 415.0, pc, dx)
                    assert np.isfinite(dx).all()
                ahc_motor.rhs(np.array([s, 50.0, 1.0, pa, pb]), 10 * s, 0.1, pm, dx)
                assert np.isfinite(dx).all()


@pytest.mark.parametrize(("rig_name", "controller_name"), [("cyl", "p_cyl"), ("mot", "p_mot")])
def test_higher_supply_gives_a_faster_step(request, rig_name, controller_name):
    """Seed 001 Fig. 5 (cylinder) and Fig. 7 (motor): 5, 10, 15 MPa; the response speeds up.

    Model figures (P K=40 / K=2, 10-90 % rise time, worst step): cylinder 0.446, 0.316,
    0.258 s for the 100 mm step; motor 0.160, 0.108, 0.085 s for the 10 rad step.
    """
    rig = request.getfixturevalue(rig_name)
    controller = request.getfixturevalue(controller_name)
    rise = []
    for scenario in PRESSURES:
        r = simulate(rig, controller, scenario)
        assert r.status == "ok", r.message
        m = result_metrics(r).aggregate
        assert m["overshoot_pct"] < 1.0
        rise.append(m["rise_time_s"])
    assert rise[0] > rise[1] > rise[2]
    # valve flow ∝ sqrt(supply − load pressure): about sqrt(3) from 5 to 15 MPa, more
    # where the load pressure takes a larger share of the 5 MPa
    assert 1.3 < rise[0] / rise[2] < 1.2 * math.sqrt(3)


def test_cylinder_tracks_the_wave_profile(cyl, p_cyl):
    """The heave profile taken as platform motion in ahc_motor is what the cylinder does."""
    r = simulate(cyl, p_cyl, "heave")
    assert r.status == "ok", r.message
    keep = r.t >= r.warmup_s
    err = r.output[keep] - r.reference_output[keep]
    assert np.sqrt(np.mean(err**2)) < 0.025 * np.std(r.reference_output[keep])


def test_heave_reference_is_the_wave_over_the_drum_radius(mot, p_mot):
    r = simulate(mot, p_mot, "heave", duration_s=2.0)
    np.testing.assert_allclose(r.reference_output * 0.1, r.signals["z_wave"], atol=1e-12)


def test_heave_compensation_p_and_fuzzy(mot, p_mot, flc_mot):
    """Seed 001 §1: only active compensation removes more than 80 % of heave.

    Model: P K=2 leaves 3.0 % (compensation 97.0 %), the fuzzy PI 0.07 % (99.93 %).
    """
    results = {}
    for c in (p_mot, flc_mot):
        r = simulate(mot, c, "heave")
        assert r.status == "ok", r.message
        results[c.name] = heave_metrics(r)["compensation_pct"]
    assert results["p_ahc_motor"] == pytest.approx(97.0, abs=0.5)
    assert results["flc_ahc_motor"] > 99.5
    assert min(results.values()) > 80.0


def test_compensation_pct_definition():
    t = np.linspace(0, 10, 1001)
    wave = 0.1 * np.sin(t)
    assert compensation_pct(wave, 0.5 + 0 * wave) == pytest.approx(100.0)
    assert compensation_pct(wave, wave) == pytest.approx(0.0)
    assert compensation_pct(wave, 0.2 * wave) == pytest.approx(80.0)
    assert math.isnan(compensation_pct(0 * wave, wave))
    with pytest.raises(ValueError, match="same shape"):
        compensation_pct(wave, wave[:-1])


def test_heave_metrics_only_for_a_moving_wave(mot, p_mot):
    assert heave_metrics(simulate(mot, p_mot, "steps_10mpa", duration_s=0.5)) == {}


@pytest.mark.slow
@pytest.mark.parametrize(
    ("rig_name", "controller_name", "scenario", "signal", "tol"),
    [
        ("cyl", "p_cyl", "steps_10mpa", "y", 2e-5),
        ("mot", "p_mot", "steps_10mpa", "theta", 2e-4),
        ("mot", "flc_mot", "heave", "theta", 2e-4),
    ],
)
def test_fast_loop_converges_to_tight_reference(
    request, rig_name, controller_name, scenario, signal, tol
):
    rig = request.getfixturevalue(rig_name)
    controller = request.getfixturevalue(controller_name)
    fast = simulate(rig, controller, scenario, duration_s=0.8)
    tight = simulate_reference(rig, controller, scenario, duration_s=0.8, rtol=1e-9)
    assert fast.status == tight.status == "ok"
    assert np.max(np.abs(fast.signals[signal] - tight.signals[signal])) < tol
    for k in ("p_a", "p_b"):
        assert np.max(np.abs(fast.signals[k] - tight.signals[k])) < 0.5e5
