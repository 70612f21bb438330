"""Several axes on one supply: a circuit of two valve-cylinder axes (rigs/twin_lift.yaml).

Each valve, line, actuator and load names its axis; the fluid, the supply and an
accumulator serve every axis, and the supply sees the sum of the valves' flows. The
composer names an axis's states and signals ``<axis>_<name>``; the loop drives every
valve with its one command and closes on the signal ``feedback`` names.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from support import DATA, controller_named, rig_named

from fuzzyservo.cli import main
from fuzzyservo.io.rigs import load_rig
from fuzzyservo.plants.composed import CompositionError, compose
from fuzzyservo.simulation import simulate

_AXIS_ROLES = ("valve", "cylinder", "payload", "weight", "guides")


def _lift(tmp_path: Path, name: str, change) -> Path:
    data = yaml.safe_load((DATA / "rigs" / "servo_lift.yaml").read_text(encoding="utf-8"))
    change(data)
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


def test_one_named_axis_runs_as_the_circuit_without_axes(tmp_path: Path) -> None:
    """The servo lift with its valve, cylinder and loads on an axis ``main`` is the same
    plant: the same equations, the same numbers to the last bit."""

    def on_axis(data):
        for key in _AXIS_ROLES:
            data["plant"]["components"][key]["axis"] = "main"
        data["feedback"]["signal"] = data["output"]["signal"] = "main_y"

    named = load_rig(_lift(tmp_path, "lift_main", on_axis))
    assert "main_y" in named.plant.states and "main_p_a" in named.plant.signals
    p4 = controller_named("p_servo_lift")
    plain = simulate(rig_named("servo_lift"), p4, "disturbed")
    axis = simulate(named, p4, "disturbed")
    assert axis.status == plain.status == "ok"
    for signal in ("y", "v", "p_a", "p_b", "x_spool", "q_a", "f_loads"):
        np.testing.assert_array_equal(axis.signals[f"main_{signal}"], plain.signals[signal])
    np.testing.assert_array_equal(axis.signals["p_s"], plain.signals["p_s"])


@pytest.mark.slow
def test_two_equal_axes_on_a_doubled_pump_move_as_one_lift(tmp_path: Path) -> None:
    """Two copies of the lift's axis on a pump of twice the flow and volume: by symmetry
    each axis sees half the pump, so each moves as the one-axis lift does and the supply
    pressure is the lift's. Were the supply to see one valve's flow, not the sum, p_s
    would rise by bars while both lift."""

    def twin(data):
        comps = data["plant"]["components"]
        supply = comps["supply"]["parameters"]
        for key in ("pump_flow", "supply_volume"):
            supply[key]["value"] *= 2
        for side in ("left", "right"):
            for key in _AXIS_ROLES:
                comps[f"{key}_{side}"] = {**comps[key], "axis": side}
        for key in _AXIS_ROLES:
            del comps[key]
        data["feedback"]["signal"] = data["output"]["signal"] = "left_y"

    twin_rig = load_rig(_lift(tmp_path, "twin", twin))
    p4 = controller_named("p_servo_lift")
    one = simulate(rig_named("servo_lift"), p4, "steps")
    two = simulate(twin_rig, p4, "steps")
    assert two.status == one.status == "ok"
    # the loop's own local-error tolerance (0.5 µm, 500 Pa): the state vectors differ in size
    np.testing.assert_allclose(two.signals["left_y"], one.signals["y"], rtol=0, atol=2e-6)
    # the twins part only by rounding (the integrator's linear solve mixes the states)
    np.testing.assert_allclose(two.signals["left_y"], two.signals["right_y"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(two.signals["p_s"], one.signals["p_s"], rtol=0, atol=2e3)
    draw = two.signals["left_q_supply"] + two.signals["right_q_supply"]
    np.testing.assert_allclose(draw, 2 * one.signals["q_supply"], rtol=0, atol=2e-7)


def test_the_twin_lift_loses_synchronisation_under_its_uneven_load() -> None:
    """rigs/twin_lift.yaml: 120 kg on the left axis, 80 kg on the right, one command.
    The loop holds the left axis on the reference. Lifting, the lighter right axis, which
    needs less of the supply pressure to hold its load, runs ahead; lowering, the heavier
    left one sinks faster: the right stays higher after every move. Both valves draw on
    the one pump, whose pressure sags far below its setting while both lower."""
    rig = rig_named("twin_lift")
    run = simulate(rig, controller_named("p_servo_lift"), "steps")
    assert run.status == "ok"
    t = run.t
    lead = run.signals["right_y"] - run.signals["left_y"]

    def at(time_s: float) -> float:
        return float(lead[np.searchsorted(t, time_s)])

    assert at(0.5) == 0.0  # at rest, both at mid-stroke
    # the figures docs/rigs.md gives: after the lift, the lowering and the last lift [mm]
    assert [round(at(s) * 1e3, 1) for s in (2.9, 5.4, 7.9)] == [1.1, 3.2, 3.9]
    lowering = (t > 3.0) & (t < 3.5)
    assert round(run.signals["p_s"][lowering].min() / 1e5) == 63  # 140 bar at rest
    # the left axis follows the reference (P 4 V/V holds it to a few µm)
    assert abs(run.signals["left_y"][np.searchsorted(t, 2.9)] - 0.200) < 1e-4


def test_compare_and_tune_run_on_the_twin_lift(tmp_path: Path, capsys) -> None:
    assert main(["compare", "twin_lift", "p_servo_lift", "--scenario", "steps",
                 "--out", str(tmp_path / "compare")]) == 0  # fmt: skip
    assert "p_servo_lift" in capsys.readouterr().out
    assert main(["tune", "twin_lift_pi", "--trials", "3", "--out", str(tmp_path / "tune")]) == 0
    out = capsys.readouterr().out
    assert "trials: 3 asked: 3 complete" in out
    assert (tmp_path / "tune" / "report.md").is_file()


def test_axes_refuse_in_one_line() -> None:
    shared = (("oil", "oil"), ("supply", "ideal_supply"))
    left = (("vl", "servo_valve", "left"), ("cl", "double_rod_cylinder", "left"))
    with pytest.raises(CompositionError, match="supply: a supply serves every axis"):
        compose((("oil", "oil"), ("supply", "ideal_supply", "left"), *left))
    with pytest.raises(CompositionError, match=r"exactly 1 valve component\(s\) on axis 'right'"):
        compose((*shared, *left, ("cr", "double_rod_cylinder", "right")))
    with pytest.raises(CompositionError, match="cr: give every valve, line, actuator and load"):
        compose((*shared, *left, ("vr", "servo_valve", "right"), ("cr", "double_rod_cylinder")))
    with pytest.raises(CompositionError, match="valves take different inputs"):
        compose((*shared, *left, ("vr", "proportional_valve", "right"),
                 ("cr", "double_rod_cylinder", "right")))  # fmt: skip
    with pytest.raises(CompositionError, match="move in different units"):
        compose((*shared, *left, ("vr", "servo_valve", "right"), ("mr", "motor", "right")))
