"""Seed-003 Hydroprax bench: equilibrium, conservation, robustness, supply sag, the three valve
models, the seed's PI result, convergence, and the valve-network training path, on the seed's
equations as written (tests/reference_plants/hydroprax.py: its three valve models);
tests/test_reference_plants.py holds the shipped composition to it."""

from __future__ import annotations

import json

import numpy as np
import pytest
from reference_plants import PLANTS, RIGS, hydroprax, reference_rig
from support import DATA, controller_named

from fuzzyservo.cli import main
from fuzzyservo.components.nn_fit import predict
from fuzzyservo.errors import ConfigError, DataError
from fuzzyservo.io.rigs import load_rig
from fuzzyservo.io.valve_data import read_valve_csv, read_valve_network, write_valve_csv
from fuzzyservo.metrics import result_metrics
from fuzzyservo.params import pack
from fuzzyservo.simulation import simulate
from fuzzyservo.simulation.reference import simulate_reference

SIG = {name: i for i, name in enumerate(hydroprax.SIGNALS)}


@pytest.fixture(scope="module")
def rig():
    return reference_rig("hydroprax_pdcv")


@pytest.fixture(scope="module")
def pi():
    return controller_named("pi_hydroprax")


@pytest.fixture(scope="module")
def runs(rig, pi):
    """The `steps` scenario with each valve model (1 polynomial, 2 network, 3 orifice)."""
    return {vm: simulate(rig.with_params(valve_model=float(vm)), pi, "steps") for vm in (1, 2, 3)}


def test_areas_and_table1(rig):
    # seed 003 Table 1: A_p = 12.566e-4 m² (40 mm bore); 25 mm rod from the cylinder type
    p = rig.params
    assert p.area_a_m2 == pytest.approx(12.566e-4)
    assert p.area_b_m2 == pytest.approx(12.566e-4 - np.pi * 0.025**2 / 4)
    assert (p.pump_flow_m3_s, p.supply_pressure_pa, p.supply_volume_m3) == (
        pytest.approx(0.1666e-3),
        pytest.approx(30e5),
        pytest.approx(57.0045e-6),
    )


@pytest.mark.parametrize("y", [0.0, 0.05, 0.2])
def test_spring_load_equilibrium_at_rest(rig, y):
    """At rest with U_C = 0 the valve is shut and p_a·A_a − p_b·A_b = K_L·y (eq. 5-6):
    nothing moves, and the supply sits where the relief passes the whole pump flow."""
    params = rig.params
    x = hydroprax.initial_state(params, y_m=y)
    dx = np.empty(5)
    hydroprax.rhs(x, 0.0, 0.0, pack(params), dx)
    assert dx[1] == pytest.approx(0.0, abs=1e-12)
    assert dx[3] == 0.0 and dx[4] == 0.0
    assert abs(dx[2]) < 1e-3  # Pa/s: the relief balances the pump to rounding
    assert x[3] * params.area_a_m2 - x[4] * params.area_b_m2 == pytest.approx(
        params.load_stiffness_n_m * y, abs=1e-9
    )


@pytest.mark.slow
def test_closed_loop_settles_on_the_spring_balance(runs, rig):
    """After the last step the pressures carry the spring (Coulomb 0.8 N and the viscous term
    at the creeping speed are the only other forces: tolerance 1 N of the 109 N spring force)."""
    r = runs[1]
    y = r.output[-1]
    force = (
        r.signals["p_a"][-1] * rig.params.area_a_m2 - r.signals["p_b"][-1] * rig.params.area_b_m2
    )
    assert force == pytest.approx(rig.params.load_stiffness_n_m * y, abs=1.0)


def test_supply_conservation_at_steady_state(runs):
    """eq. 1 at rest: Q_pump = Q_relief + Q_L (the valve draws what the relief does not pass)."""
    for r in runs.values():
        q_pump, q_r, q_l = (r.signals[k][-1] for k in ("q_pump", "q_relief", "q_supply"))
        assert q_pump == pytest.approx(q_r + q_l, rel=1e-6)


def test_supply_equation_and_valve_balance_everywhere(rig):
    """dp_s/dt = β/V_t·(Q_pump − Q_relief − Q_L) and Q_L = Q_A + Q_B + Q_T at random states."""
    rng = np.random.default_rng(3)
    for vm in (1, 2, 3):
        params = rig.with_params(valve_model=float(vm)).params
        p = pack(params)
        dx, out = np.empty(5), np.empty(len(hydroprax.SIGNALS))
        for _ in range(100):
            x = np.array([rng.uniform(0, 0.3), rng.uniform(-0.2, 0.2), *rng.uniform(0, 31e5, 3)])
            u = rng.uniform(-6, 6)
            hydroprax.rhs(x, u, 0.0, p, dx)
            hydroprax.signals(x, u, 0.0, p, out)
            net = out[SIG["q_pump"]] - out[SIG["q_relief"]] - out[SIG["q_supply"]]
            beta_vt = params.bulk_modulus_pa / params.supply_volume_m3
            assert dx[2] == pytest.approx(beta_vt * net, rel=1e-12, abs=1e-6)
            q_sum = out[SIG["q_a"]] + out[SIG["q_b"]] + out[SIG["q_tank"]]
            assert out[SIG["q_supply"]] == pytest.approx(q_sum, rel=1e-12, abs=1e-18)


def test_rhs_is_finite_everywhere(rig):
    """No NaN for pressures of any sign, at and beyond the stroke, commands beyond ±6 V."""
    dx = np.empty(5)
    for vm in (1, 2, 3):
        p = pack(rig.with_params(valve_model=float(vm)).params)
        for y in (-0.01, 0.0, 0.15, 0.3, 0.31):
            for v in (-1.0, 0.0, 1.0):
                for pres in (-50e5, 0.0, 15e5, 30e5, 200e5):
                    for u in (-20.0, -6.0, 0.0, 1e-9, 6.0, 20.0):
                        x = np.array([y, v, pres, pres * 0.5, pres])
                        hydroprax.rhs(x, u, 0.0, p, dx)
                        assert np.isfinite(dx).all()


def test_fast_stroke_sags_the_supply_then_it_recovers(runs, rig):
    """The 50 mm step saturates the valve (Kp·e = 22 V ≫ 6 V), which asks for more than
    Q_pump = 10 l/min: p_s sags well below 30 bar (eq. 1), and climbs back to the relief
    setting once the piston stops."""
    r = runs[1]
    t = r.t
    move = (t > 0.5) & (t < 1.5)
    nominal = rig.params.resting_supply_pressure_pa()
    assert r.signals["q_supply"][move].max() > rig.params.pump_flow_m3_s
    assert r.signals["p_s"][move].min() < 0.8 * nominal
    settled = (t > 2.5) & (t < 3.0)
    assert np.all(np.abs(r.signals["p_s"][settled] - nominal) < 0.05e5)


@pytest.mark.parametrize("vm", [1, 2, 3])
def test_each_valve_model_tracks_the_steps(runs, vm):
    r = runs[vm]
    # the ideal orifice (3) pulls p_a to -1.1 bar gauge on the 3 s step, below the oil's
    # vapour pressure; the model has no cavitation, so that run says so (issue 11)
    assert r.status == ("cavitation" if vm == 3 else "ok"), r.message
    # the network's error at null (~0.2 l/min, held by Kp = 450 V/m) leaves up to 0.4 mm:
    # 0.8 % of the 80 mm step; the physical valves (1, 3) shut exactly at U_C = 0
    assert result_metrics(r).aggregate["sse_pct"] < (1.0 if vm == 2 else 0.3)


def test_network_tracks_the_polynomial_valve(runs, rig):
    """The network was trained on valve model 1 with an RMS error of about 0.5 l/min (3 % of the
    15 l/min full scale, a 4-5-2 network cannot follow the square-root kinks at zero Δp and
    zero command exactly). The loop corrects most of it: during the saturated strokes the
    positions agree within 5 mm (measured 3.7 mm), and at rest within 0.5 mm (measured
    0.40 mm: the network's flow at null, held by Kp = 450 V/m)."""
    a, b = runs[1], runs[2]
    assert np.max(np.abs(a.output - b.output)) < 5e-3  # during the saturated strokes
    rest = np.zeros_like(a.t, dtype=bool)
    for t_step in (3.0, 5.5, 8.0, 10.5):
        rest |= (a.t > t_step - 0.5) & (a.t < t_step)
    assert np.max(np.abs(a.output[rest] - b.output[rest])) < 0.5e-3
    net = read_valve_network(DATA / "rigs" / "hydroprax_nn_valve.json")
    assert max(net.validation_rms_m3_s) < 1.0e-3 / 60  # below 1 l/min


def test_seed_pi_result(runs):
    """seed 003 §3, Fig. 11: Kp = 450, Ki = 0.011 on the 0-0.1 m reference, SSE < 0.3 %."""
    m = result_metrics(runs[1]).aggregate
    assert m["sse_pct"] < 0.3
    assert m["overshoot_pct"] < 5.0
    assert m["settling_time_s"] < 2.0


def test_compiled_loop_converges_to_tight_reference(rig, pi):
    """Compiled Rosenbrock loop against solve_ivp LSODA at rtol 1e-9 over the first step
    (the saturated stroke with the supply sag): position within 0.02 mm, pressures 0.5 bar."""
    fast = simulate(rig, pi, "steps", duration_s=1.5)
    tight = simulate_reference(rig, pi, "steps", duration_s=1.5, rtol=1e-9)
    assert fast.status == tight.status == "ok"
    assert np.max(np.abs(fast.output - tight.output)) < 0.02e-3
    for k in ("p_s", "p_a", "p_b"):
        assert np.max(np.abs(fast.signals[k] - tight.signals[k])) < 0.5e5
    finer = simulate(rig, pi, "steps", duration_s=1.5, tol=0.01)
    assert (
        np.max(np.abs(finer.output - tight.output))
        < np.max(np.abs(fast.output - tight.output)) + 1e-9
    )


def test_generated_data_round_trips_through_csv(rig, tmp_path):
    data = hydroprax.generate_valve_data(rig.params, 50, seed=1)
    again = read_valve_csv(write_valve_csv(tmp_path / "v.csv", data))
    np.testing.assert_allclose(again, data, rtol=1e-9)
    np.testing.assert_array_equal(data, hydroprax.generate_valve_data(rig.params, 50, seed=1))


def test_fit_valve_cli(rig, tmp_path, capsys):
    data = hydroprax.generate_valve_data(rig.params, 120, seed=2)
    csv_file = write_valve_csv(tmp_path / "valve.csv", data)
    out = tmp_path / "net.json"
    assert (
        main(["fit-valve", str(csv_file), "--out", str(out), "--seed", "1", "--restarts", "1"]) == 0
    )
    printed = capsys.readouterr().out
    assert "validation" in printed and str(out) in printed
    net = read_valve_network(out)
    payload = json.loads(out.read_text())
    assert payload["layers"] == [4, 5, 2] and payload["training"]["samples_validation"] == 30
    # the stored RMS is the network's error on the data (training and validation together)
    err = predict(np.array(net.weights), data[:, :4]) - data[:, 4:]
    full = np.sqrt(np.mean(err**2, axis=0))
    rms = np.array([net.train_rms_m3_s, net.validation_rms_m3_s])
    assert np.all(full <= rms.max(axis=0) * 1.0001)
    # the network file plugs into the rig
    params = rig.with_params(valve_model=2.0, nn_weights=net.weights).params
    assert np.isfinite(pack(params)).all()


@pytest.mark.parametrize(
    ("text", "fragment"),
    [
        ("", "empty"),
        ("p_s_bar,u_c_V,p_a_bar,p_b_bar,q_a_l_min\n1,2,3,4,5\n", "header has 5 columns"),
        ("p_s_psi,u_c_V,p_a_bar,p_b_bar,q_a_l_min,q_b_l_min\n1,2,3,4,5,6\n", "'p_s_psi'"),
        ("p_s_bar,u_c_V,p_a_bar,p_b_bar,q_a_l_min,q_b_l_min\n", "no data rows"),
        (
            "p_s_bar,u_c_V,p_a_bar,p_b_bar,q_a_l_min,q_b_l_min\n1,2,x,4,5,6\n",
            "line 2, column p_a_bar",
        ),
        ("p_s_bar,u_c_V,p_a_bar,p_b_bar,q_a_l_min,q_b_l_min\n1,2,3,4,5\n", "line 2 has 5 values"),
        ("p_s_bar,u_c_V,p_a_bar,p_b_bar,q_a_l_min,q_b_l_min\n1,2,nan,4,5,6\n", "finite"),
    ],
)
def test_bad_valve_data_files(tmp_path, capsys, text, fragment):
    bad = tmp_path / "bad.csv"
    bad.write_text(text)
    with pytest.raises(DataError, match=r"bad\.csv"):
        read_valve_csv(bad)
    assert main(["fit-valve", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and fragment in err


def test_missing_valve_data_and_too_few_rows(tmp_path, capsys, rig):
    assert main(["fit-valve", str(tmp_path / "none.csv")]) == 2
    assert "file not found" in capsys.readouterr().err
    few = write_valve_csv(tmp_path / "few.csv", hydroprax.generate_valve_data(rig.params, 10, 0))
    assert main(["fit-valve", str(few)]) == 2
    assert "too few" in capsys.readouterr().err


def test_bad_network_file_in_rig(tmp_path):
    network = "../../../rigs/hydroprax_nn_valve.json"
    text = (RIGS / "hydroprax_pdcv.yaml").read_text().replace(network, "hydroprax_nn_valve.json")
    (tmp_path / "hydroprax_nn_valve.json").write_text('{"format": "something else"}')
    (tmp_path / "rig.yaml").write_text(text)
    with pytest.raises(ConfigError, match=r"plant\.parameters\.nn_weights\.file: .*format"):
        load_rig(tmp_path / "rig.yaml", plants=PLANTS)
    (tmp_path / "rig.yaml").write_text(
        text.replace('value: 1\n      unit: "1"', 'value: 4\n      unit: "1"')
    )
    (tmp_path / "hydroprax_nn_valve.json").write_text(
        (DATA / "rigs" / "hydroprax_nn_valve.json").read_text()
    )
    with pytest.raises(ConfigError, match="valve_model"):
        load_rig(tmp_path / "rig.yaml", plants=PLANTS)
