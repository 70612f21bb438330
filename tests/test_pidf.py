"""PIDF (PID with a filtered derivative) in its three forms, its controller file, and
controller gains declared unknown and fitted in a closed-loop replay."""

from __future__ import annotations

import numpy as np
import pytest

from fuzzyservo.calibration.replay import make_replay
from fuzzyservo.calibration.search import search_effects
from fuzzyservo.calibration.synthetic import synthetic_run
from fuzzyservo.controllers.classical import PI, PIDF
from fuzzyservo.errors import ConfigError
from fuzzyservo.io.controllers import controller_from_data
from fuzzyservo.io.paths import find_file
from fuzzyservo.io.rigs import load_rig

TS = 0.01


def _run(c: PIDF, r: np.ndarray, y: np.ndarray) -> np.ndarray:
    state = c.init(TS)
    out = []
    for rk, yk in zip(r, y, strict=True):
        u, state = c.step(state, rk, yk)
        out.append(u)
    return np.array(out)


def test_pidf_without_derivative_is_the_pi():
    rng = np.random.default_rng(0)
    r, y = rng.normal(size=200), rng.normal(size=200)
    pi = PI(kp=2.0, ki=5.0, u_min=-3, u_max=3)
    pidf = PIDF(kp=2.0, ki=5.0, kd=0.0, u_min=-3, u_max=3)
    np.testing.assert_allclose(_run(pidf, r, y), _run(pi, r, y), rtol=0, atol=1e-14)


def test_filtered_derivative_of_a_ramp_settles_at_its_slope():
    """Tf·dD/dt + D = de/dt on e = a·t: D → a with the filter's time constant (backward
    difference: D_k − a = (Tf/(Tf+T))^k · (D_0 − a))."""
    slope, tf = 2.0, 0.05
    c = PIDF(kp=0.0, ki=0.0, kd=1.0, filter_time_s=tf)
    t = np.arange(200) * TS
    u = _run(c, np.zeros_like(t), -slope * t)
    k = np.arange(t.size)
    expected = slope * (1.0 - (tf / (tf + TS)) ** k)  # D_0 = 0: no kick at the first sample
    np.testing.assert_allclose(u, expected, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize(
    ("form", "jump"),
    [("parallel", 1.0 + 1.0 / (0.02 + TS)), ("PI-D", 1.0), ("I-PD", 0.0)],
)
def test_forms_differ_only_in_what_sees_a_reference_step(form, jump):
    """At a unit reference step (y held at 0) the command jumps by Kp·b + Kd·c/(Tf + T):
    parallel both, PI-D the proportional part only, I-PD neither (Åström & Hägglund §3.4)."""
    c = PIDF(kp=1.0, ki=3.0, kd=1.0, filter_time_s=0.02, form=form)
    r = np.r_[np.zeros(5), np.ones(5)]
    u = _run(c, r, np.zeros(10))
    assert u[4] == 0.0
    assert u[5] == pytest.approx(jump, rel=1e-12)
    if form != "parallel":  # then only the integral moves: Ki·e·T a sample
        assert u[6] - u[5] == pytest.approx(3.0 * TS, rel=1e-9)


def test_pidf_clamps_its_integral_at_a_limit():
    c = PIDF(kp=1.0, ki=10.0, kd=0.1, filter_time_s=0.01, form="PI-D", u_min=-1, u_max=1)
    state = c.init(TS)
    for _ in range(500):
        u, state = c.step(state, 5.0, 0.0)
    assert u == 1.0
    assert state[1][0] == 0.0  # saturated from the first sample: nothing integrated
    u, state = c.step(state, 0.5, 0.0)
    assert u == pytest.approx(0.5)  # leaves the limit at once: no wound-up integral


def test_controller_file_reads_pidf_with_unknown_gains():
    c = controller_from_data(
        {
            "kind": "PIDF",
            "form": "I-PD",
            "kp": {"value": 2.0, "fit": [0.5, 8]},
            "ki": {"fit": [0.0, 4]},
            "kd": 0.01,
            "filter_time": 0.004,
        },
        "pid.yaml",
    )
    assert isinstance(c, PIDF)
    assert (c.kp, c.ki, c.kd, c.filter_time_s, c.form) == (2.0, 2.0, 0.01, 0.004, "I-PD")
    assert c.gain_bounds() == {"kp": (0.5, 8.0), "ki": (0.0, 4.0)}


@pytest.mark.parametrize(
    ("data", "key", "says"),
    [
        ({"kind": "PIDF", "kp": 1, "form": "ideal"}, "form", "choose one of"),
        ({"kind": "PIDF", "kp": {"fit": [3, 1]}}, "kp.fit", "lower < upper"),
        ({"kind": "PIDF", "kp": {"value": 9, "fit": [1, 3]}}, "kp.fit", "outside its fit bounds"),
        ({"kind": "PIDF", "kp": 1, "filter_time": -0.1}, "filter_time", ">= 0"),
        ({"kind": "PIDF", "ki": 0}, "kp", "all zero"),
        ({"kind": "PI", "kp": 1, "ki": 1, "kd": 1}, "kd", "kind PIDF"),
    ],
)
def test_bad_pidf_files_name_the_key(data, key, says):
    with pytest.raises(ConfigError) as err:
        controller_from_data(data, "pid.yaml")
    text = str(err.value)
    assert "pid.yaml" in text and key in text and says in text


def test_closed_loop_replay_recovers_unknown_pid_gains():
    """Generated data: the servo_lift rig under a PI-D (kp 3 V/V, ki 2 1/s, kd 0.01 s,
    Tf 5 ms) on its `steps` scenario, position read with 20 µm of noise. Replayed in
    closed loop through the same PI-D with all three gains unknown, started at half
    their values, calibration recovers each within 5 %."""
    rig = load_rig(find_file("servo_lift", "rigs", "rig"))
    true = PIDF(kp=3.0, ki=2.0, kd=0.01, filter_time_s=0.005, form="PI-D", u_min=-10, u_max=10)
    data = synthetic_run(rig, true, "steps", {}, {"y": 20e-6}, seed=1)
    unknown = PIDF(
        kp=1.5,
        ki=1.0,
        kd=0.005,
        filter_time_s=0.005,
        form="PI-D",
        u_min=-10,
        u_max=10,
        unknowns=(("kp", 0.5, 8.0), ("ki", 0.1, 8.0), ("kd", 0.0, 0.04)),
    )
    outcome = search_effects(make_replay(rig, data, unknown), rig, max_effects=0)
    fitted = outcome.controller
    assert fitted.kp == pytest.approx(3.0, rel=0.05)
    assert fitted.ki == pytest.approx(2.0, rel=0.05)
    assert fitted.kd == pytest.approx(0.01, rel=0.05)
    assert outcome.cost_nominal < 1.2  # the noise floor: nothing left to explain


def test_gains_fitted_on_a_logged_command():
    """A log of r, y and the command u of a PI-D: fit_from_log, which steps the same
    controller on the log, recovers the gains and explains u on the held-out part."""
    from fuzzyservo.calibration.gains import fit_from_log

    rng = np.random.default_rng(2)
    r = np.repeat(rng.uniform(-1, 1, 20), 25)
    y = np.convolve(r, np.full(10, 0.1), mode="same") + 0.01 * rng.normal(size=r.size)
    true = PIDF(kp=2.0, ki=4.0, kd=0.05, filter_time_s=0.02, form="PI-D")
    u = _run(true, r, y)
    start = PIDF(
        kp=1.0,
        ki=1.0,
        kd=0.0,
        filter_time_s=0.02,
        form="PI-D",
        unknowns=(("kp", 0.1, 10.0), ("ki", 0.0, 10.0), ("kd", 0.0, 0.2)),
    )
    fitted, gains, fit = fit_from_log(start, r, y, u, TS, split=350)
    assert (fitted.kp, fitted.ki, fitted.kd) == pytest.approx((2.0, 4.0, 0.05), rel=1e-4)
    assert fitted.unknowns == () and set(gains) == {"kp", "ki", "kd"}
    assert fit > 99.9
