"""Physical validity (issue 11, items 4 and 5): consistent starts, no pressure below the
oil's vapour pressure reported as ``ok``, a brake that only opposes motion, and the
seed-000 timing with the flywheel the seed's text describes."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import yaml
from support import controller_named, rig_named, shipped

from fuzzyservo.cli import main
from fuzzyservo.metrics import result_metrics
from fuzzyservo.simulation.closed_loop import simulate
from fuzzyservo.simulation.validity import VAPOUR_PRESSURE_PA, pressure_violation


@pytest.fixture(scope="module")
def dinca():
    return rig_named("dinca_cylinder")


def test_start_away_from_zero_keeps_the_held_pressures(dinca):
    """Seed 002 gives the chamber masses at y = 0 (m30, m40): a scenario starting at 5 cm
    holds the same pressures there, instead of spreading the y = 0 mass over a chamber
    3.5 times larger (p3 = −12 847 bar, |v| = 198 m/s before issue 11; the composition
    is given the chamber pressures)."""
    base = dinca.scenario("pulses")
    at_zero = simulate(dinca, controller_named("p_k10"), base, duration_s=0.2)
    moved = dataclasses.replace(base, initial={**base.initial, "position": 0.05})
    r = simulate(dinca, controller_named("p_k10"), moved, duration_s=0.2)
    assert r.status == "ok"
    assert r.signals["y"][0] == pytest.approx(0.05)
    for p in ("p_a", "p_b"):
        assert r.signals[p][0] == pytest.approx(at_zero.signals[p][0], rel=1e-9)
        assert 30e5 < r.signals[p][0] < 40e5  # seed 002 §4: p30 = p40 = 36 bar
    assert np.nanmax(np.abs(r.signals["v"])) < 1.0  # m/s: no violent start


def test_a_pressure_below_vapour_pressure_is_not_ok():
    """A run whose chamber goes below vacuum completes, but reports ``cavitation``."""
    rig = rig_named("dinca_cylinder")
    base = rig.scenario("pulses")
    bad = dataclasses.replace(base, initial={"pressure_a": -2e5})
    r = simulate(rig, controller_named("p_k10"), bad, duration_s=0.2)
    assert r.status == "cavitation"
    assert r.ok  # it ran to the end: the samples are there, flagged
    assert "p_a" in r.message and "vapour pressure" in r.message


def test_pressure_violation_names_the_lowest_pressure():
    t = np.arange(4) * 0.1
    fine = {"p_a": np.array([1e5, 0.0, -0.9e5, 2e5]), "p_b": np.full(4, 3e5)}
    assert pressure_violation(t, fine, ("p_a", "p_b")) == ""
    low = {"p_a": fine["p_a"], "p_b": np.array([3e5, VAPOUR_PRESSURE_PA - 1e4, -5e5, 0.0])}
    message = pressure_violation(t, low, ("p_a", "p_b"))
    assert message.startswith("p_b") and "t = 0.100 s" in message and "-5 bar" in message


def test_composed_plants_check_every_node_pressure():
    plant = rig_named("dinca_cylinder").plant
    assert {"p_a", "p_b"} <= set(plant.pressures)
    assert all(plant.signal_units[p] == "Pa" for p in plant.pressures)


@pytest.mark.parametrize("controller", ["p_kb0105", "open_loop"])
def test_brake_never_reverses_the_motor(controller):
    """Seed 000 §2: the shoe brake is a load that opposes motion. Under P Kb = 0.105 the
    command is about 0.1 V, too little to beat 1 N·m: the brake stops the motor and holds
    it (before issue 11 it drove the motor backwards to −14.5 rad/s)."""
    r = simulate(rig_named("ehs160_motor"), controller_named(controller), "brake")
    assert r.status == "ok"
    w = r.signals["w"]
    assert np.nanmin(w) > -1e-3  # rad/s
    braked = w[np.searchsorted(r.t, 3.9)]
    assert braked < w[np.searchsorted(r.t, 1.9)]


def test_seed000_rise_time_with_the_flywheel():
    """Seed 000 Fig. 10: open-loop tr = 0.5 s. Table 2's J (0.4e-3, "motor inertia") rises
    in 0.055 s; the rig adds the flywheel of §2 (ehs160_motor.yaml says how it is
    identified)."""
    r = simulate(rig_named("ehs160_motor"), controller_named("open_loop"), "unit_step")
    assert result_metrics(r).aggregate["rise_time_s"] == pytest.approx(0.5, rel=0.05)


def test_cli_and_json_report_the_cavitation_status(tmp_path, capsys):
    """The warning reaches the user: `simulate` names it on stderr and in its JSON."""
    data = yaml.safe_load(shipped("dinca_cylinder").read_text(encoding="utf-8"))
    data["scenarios"] = {
        "below_vacuum": {
            **data["scenarios"]["pulses"],
            "duration": {"value": 0.2, "unit": "s"},
            "warmup": {"value": 0, "unit": "s"},
            "initial": {"pressure_a": {"value": -2, "unit": "bar"}},
        }
    }
    rig_file = tmp_path / "below_vacuum.yaml"
    rig_file.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    out = tmp_path / "run.json"
    code = main(
        ["simulate", str(rig_file), "p_k10", "--scenario", "below_vacuum", "--json", str(out)]
    )
    assert code == 0  # the run completed; its status says it is unphysical
    assert "status cavitation" in capsys.readouterr().err
    assert json.loads(out.read_text(encoding="utf-8"))["runs"][0]["status"] == "cavitation"


def test_every_plant_declares_its_chamber_pressures():
    """Each seed plant names its gauge pressures; the seed-000 motor's ports hold
    p_a + p_b = P_s, p_a − p_b = P_x (symmetric valve, §3 ii)."""
    for name in ("dinca_cylinder", "ahc_cylinder", "ahc_motor", "hydroprax_pdcv", "ehs160_motor"):
        plant = rig_named(name).plant
        assert plant.pressures and all(plant.signal_units[p] == "Pa" for p in plant.pressures)
    r = simulate(rig_named("ehs160_motor"), controller_named("open_loop"), "unit_step")
    s = r.signals
    np.testing.assert_allclose(s["p_a"] + s["p_b"], 70e5, atol=1.0)
