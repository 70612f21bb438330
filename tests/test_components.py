"""Rigs composed from components (issue 10): declarations, the generated plant, every
effect on every composition, the rig no seed has (simulated, calibrated, tuned).

Reference values: static balance and continuity are exact consequences of the
component equations (components/library/); the calibration recovers parameters that
generated the synthetic data, within what 5 µm / 0.05 bar of noise allow.
"""

from __future__ import annotations

import dataclasses
import json
import math
import pickle
from pathlib import Path

import numpy as np
import pytest
import yaml
from support import DATA, controller_named, rig_named

from fuzzyservo.calibration.synthetic import synthetic_run
from fuzzyservo.cli import main
from fuzzyservo.components.declare import phase, registry
from fuzzyservo.components.effects import LIBRARY
from fuzzyservo.errors import ConfigError
from fuzzyservo.io.measured import write_measured
from fuzzyservo.io.rigs import load_rig
from fuzzyservo.params import pack
from fuzzyservo.plants.composed import CompositionError, compose
from fuzzyservo.simulation import bind, simulate


@pytest.fixture(scope="module")
def lift():
    return rig_named("servo_lift")


@pytest.fixture(scope="module")
def p4():
    return controller_named("p_servo_lift")


def test_a_composed_rig_pickles_as_its_composition(lift) -> None:
    """Calibration sends the rig to worker processes: the parameter class and the plant's
    closures are made at load time, so they pickle as the composition and rebuild there."""
    rig = lift.with_params(payload__mass=130.0).with_effect("coulomb_friction", force=200.0)
    again = pickle.loads(pickle.dumps(rig))
    assert again.params == rig.params
    assert again.plant is rig.plant  # compose() is cached: the same plant object
    assert again.params.payload__mass == 130.0


def test_the_lift_starts_in_balance_holding_its_weight(lift) -> None:
    """(p_a − p_b)·A = (m_piston + m_payload)·g at rest, so nothing moves at t = 0."""
    x0 = lift.plant.initial_state(lift.params, **lift.initial)
    dx = bind(lift.plant).rhs_with_inputs(x0, 0.0, 0.0, pack(lift.params), 0.0)
    states = dict(zip(lift.plant.states, x0, strict=True))
    p = lift.params
    area = 0.25 * math.pi * (p.cylinder__piston_diameter**2 - p.cylinder__rod_diameter**2)
    weight = (p.cylinder__piston_mass + p.payload__mass) * 9.80665
    assert (states["p_a"] - states["p_b"]) * area == pytest.approx(weight, rel=1e-9)
    assert states["y"] == pytest.approx(0.15)
    assert abs(dx[lift.plant.states.index("v")]) < 1e-9


def test_the_lift_follows_its_steps(lift, p4) -> None:
    r = simulate(lift, p4, "steps")
    assert r.status == "ok"
    t, y = r.t, r.signals["y"]
    for t_end, target in ((3.0, 0.2), (5.5, 0.1), (8.0, 0.13)):
        k = round(t_end / r.sample_time_s) - 1
        assert y[k] == pytest.approx(target, abs=0.5e-3), (t[k], y[k])
    # continuity of the valve: what it takes from P and does not return to T leaves
    # through A and B, at every sample
    sig = r.signals
    np.testing.assert_allclose(
        sig["q_supply"] - sig["q_tank"], sig["q_a"] + sig["q_b"], rtol=1e-9, atol=1e-15
    )
    # the spool never opens beyond its stroke limit
    assert np.max(np.abs(r.signals["x_spool"])) <= 1.0 + 1e-12


def test_every_effect_runs_on_the_lift_or_is_refused_in_one_line(lift, p4) -> None:
    scales = lift.scales()
    for name, effect in LIBRARY.items():
        refusal = lift.plant.refusal(name)
        if refusal:
            assert "\n" not in refusal and name in refusal
            with pytest.raises(ValueError):
                lift.with_effect(name, **{p.key: 1.0 for p in effect.fitted})
            continue
        values = {p.key: 0.5 * sum(p.value_bounds(scales)) for p in effect.fitted}
        r = simulate(lift.with_effect(name, **values), p4, "steps", duration_s=1.0)
        assert r.status == "ok", (name, r.message)
    assert lift.plant.refusal("supply_droop") is not None  # the pump models it already


def _minimal(actuator: str, extra: tuple[tuple[str, str], ...] = ()) -> tuple:
    return (
        ("oil", "oil"),
        ("supply", "ideal_supply"),
        ("valve", "proportional_valve"),
        ("act", actuator),
        *extra,
    )


@pytest.mark.slow
def test_every_registered_component_type_is_reachable() -> None:
    """Each component type composes into a plant that the compiled loop simulates."""
    types = registry()
    by_role: dict[str, list[str]] = {}
    for name, comp in types.items():
        by_role.setdefault(comp.role, []).append(name)
    reached = set()
    for name, comp in types.items():
        # a load restricted to some actuators (cable_drum: a motor) rides on the first
        base = dict(_minimal(comp.actuators[0] if comp.actuators else "single_rod_cylinder"))
        role_slot = {"fluid": "oil", "supply": "supply", "valve": "valve", "actuator": "act"}
        if comp.role in role_slot:
            base[role_slot[comp.role]] = name
        elif comp.role == "line":
            base["lines"] = name
        else:
            base["load"] = name
        plant = compose(tuple(base.items()))
        p = plant.params_cls(**{f.name: _size(f) for f in _required(plant.params_cls)})
        x0 = np.asarray(plant.initial_state(p), dtype=float)
        out = np.empty(len(plant.signals))
        plant.kernels.plant_signals(x0, 0.0, 0.0, pack(p), out)
        assert out.shape == (len(plant.signals),)
        reached.add(name)
    assert reached == set(types)


# plausible values for the keys whose checks relate them; 1.0 (SI) for every other
_SIZES = {
    "piston_diameter": 0.04,
    "rod_diameter": 0.02,
    "supply_pressure": 1e7,
    "relief_cracking_pressure": 9.5e6,
}


def _size(f: dataclasses.Field) -> object:
    """A value of the right size for a required field (a vector: ones, e.g. the weights)."""
    if "vector_key" in f.metadata:
        return (1.0,) * f.metadata["length"]
    return _SIZES.get(f.name.split("__")[1], 1.0)


def _required(cls) -> list:
    return [
        f
        for f in dataclasses.fields(cls)
        if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
    ]


def test_compositions_refuse_in_one_line() -> None:
    with pytest.raises(CompositionError, match="exactly 1 valve"):
        compose((("oil", "oil"), ("supply", "ideal_supply"), ("act", "double_rod_cylinder")))
    with pytest.raises(CompositionError, match="gravity load is not meaningful on a motor"):
        compose(_minimal("motor", (("g", "gravity"),)))
    with pytest.raises(CompositionError, match="unknown component type"):
        compose(_minimal("linear_motor"))


def test_phase_functions_are_joined_by_argument_name() -> None:
    """The composer passes each argument by its name and binds each return: a circuit
    variable, a derivative dx[i], or the instance's own value; a name nothing provides
    is a one-line error naming the component."""
    from fuzzyservo.components.declare import Component, Param, State
    from fuzzyservo.plants.composed import _Calls

    load = Component(
        "spring",
        "load",
        "a test load",
        "test",
        params=(Param("k", "N/m", "k"),),
        states=(State("y", "m", "y", "motion", 1e-6, 1e-3),),
        code={"load": _spring_force},
    )
    calls = _Calls({("ld", "k"): (False, 20)}, {("ld", "y"): 3})
    calls.circuit.add("f_load")  # as compose sets it before the first phase
    assert calls.records("ld", load) == ["ld_P = _c0(p[20])", "ld_X = _c1(x[3])"]
    line = calls.call("ld", load, "load", _spring_force)
    assert line == "ld_f, f_load, dx[3] = _c2(ld_P, ld_X, f_load)"
    assert calls.value("ld", load, "f") == "ld_f"
    assert calls.value("ld", load, "k") == "p[20]"
    with pytest.raises(CompositionError, match="reads 'vel', which no earlier phase provides"):
        calls.call("ld", load, "load", _damper_force)
    with pytest.raises(CompositionError, match="returns 'dx_w' but declares no state 'w'"):
        calls.call("ld", load, "load", _moves_w)


def test_a_component_runs_alone() -> None:
    """A phase function is ordinary compiled code: called with its records, the
    cylinder's actuator phase gives the piston area, the chamber volumes and the
    end-stop force."""
    import math

    from fuzzyservo.components.declare import registry
    from fuzzyservo.components.effects import EffectParams
    from fuzzyservo.components.library.cylinders import chambers, single_rod_areas

    cylinder = registry()["single_rod_cylinder"]
    values = dict(
        piston_diameter=0.03, rod_diameter=0.014, stroke=0.16, zero_position=0.0,
        piston_mass=1.0, dead_volume_a=1e-6, dead_volume_b=1e-6, end_stop_stiffness=1e8,
        end_stop_damping=0.0,
    )  # fmt: skip
    P = cylinder.values(**values)
    p = pack(EffectParams())
    area_a, area_b = single_rod_areas(P)
    assert area_a == pytest.approx(0.25 * math.pi * 0.03**2)

    def actuator(y: float) -> dict[str, float]:
        state = cylinder.state(y, 0.0, 2e6, 1e6, 0.0)
        return dict(zip(chambers.returns, chambers(P, state, p, area_a, area_b), strict=True))

    out = actuator(0.05)
    assert out["va"] == pytest.approx(1e-6 + area_a * 0.05)
    assert out["f_hyd"] == pytest.approx(2e6 * area_a - 1e6 * area_b)
    assert out["f_stop"] == 0.0
    assert actuator(-0.001)["f_stop"] == pytest.approx(1e5)


def test_rig_file_errors_name_the_component_key(tmp_path: Path) -> None:
    data = yaml.safe_load((DATA / "rigs" / "servo_lift.yaml").read_text())
    data["plant"]["components"]["valve"]["parameters"]["rated_flw"] = {"value": 1, "unit": "1"}
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match=r"components\.valve\.parameters.*rated_flw"):
        load_rig(bad)
    data = yaml.safe_load((DATA / "rigs" / "servo_lift.yaml").read_text())
    data["plant"]["components"]["cylinder"]["parameters"]["rod_diameter"]["value"] = 50
    bad.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match=r"cylinder\.parameters\.rod_diameter: must be smaller"):
        load_rig(bad)


@pytest.mark.slow
def test_calibrate_the_lift_on_its_own_synthetic_data(tmp_path: Path, lift, p4) -> None:
    """Data from the lift with 130 kg instead of 100 and 200 N of Coulomb friction; the rig
    file marks the mass unknown. ``fuzzyservo calibrate`` fits both."""
    truth = lift.with_params(payload__mass=130.0)
    noise = {"y": 5e-6, "p_a": 0.05e5, "p_b": 0.05e5}
    data = synthetic_run(truth, p4, "steps", {"coulomb_friction": {"force": 200.0}}, noise, seed=3)
    csv = write_measured(
        tmp_path / "lift.csv", data, {"ref": "mm", "i": "mA", "y": "mm", "p_a": "bar", "p_b": "bar"}
    )
    spec = yaml.safe_load((DATA / "rigs" / "servo_lift.yaml").read_text())
    spec["plant"]["components"]["payload"]["parameters"]["mass"]["fit"] = [50, 200]
    rig_file = tmp_path / "servo_lift_unknown_mass.yaml"
    rig_file.write_text(yaml.safe_dump(spec, sort_keys=False))
    summary_file = tmp_path / "summary.json"
    code = main(
        ["calibrate", str(rig_file), str(csv), "--controller", "p_servo_lift",
         "--out", str(tmp_path / "out"), "--json", str(summary_file)]
    )  # fmt: skip
    assert code == 0
    summary = json.loads(summary_file.read_text())
    assert summary["fitted_parameters"]["payload__mass"] == pytest.approx(130.0, rel=0.01)
    assert [e["name"] for e in summary["effects_added"]][:1] == ["coulomb_friction"]
    assert summary["effects_added"][0]["params"]["force"] == pytest.approx(200.0, rel=0.05)
    calibrated = load_rig(summary["calibrated_rig"])
    assert calibrated.params.payload__mass == pytest.approx(130.0, rel=0.01)


def test_tune_the_lift(tmp_path: Path) -> None:
    """The study file tunes a PI on the composed rig; the report names both controllers."""
    spec = yaml.safe_load((DATA / "studies" / "servo_lift_pi.yaml").read_text())
    spec["rig"] = str(DATA / "rigs" / "servo_lift.yaml")
    spec["controller"] = str(DATA / "studies" / "controllers" / "pi_servo_lift.yaml")
    spec["baseline"] = str(DATA / "studies" / "controllers" / "p_servo_lift.yaml")
    study = tmp_path / "study.yaml"
    study.write_text(yaml.safe_dump(spec))
    summary = tmp_path / "summary.json"
    out = tmp_path / "out"
    code = main(["tune", str(study), "--trials", "6", "--out", str(out), "--json", str(summary)])
    assert code == 0
    data = json.loads(summary.read_text())
    assert data["trials"] == 6
    assert data["best"]["status"] == "ok" and data["best"]["feasible"]
    assert set(data["best"]["params"]) == {"kp", "ki"}
    assert (out / "report.md").is_file()


def test_a_load_force_measured_on_the_rig_drives_a_scenario(tmp_path: Path, lift, p4) -> None:
    """``load: {type: measured, file, signal}`` replays a recorded force (zero-order hold)."""
    t = np.arange(0.0, 2.0, 0.01)
    force = np.where((t >= 0.5) & (t < 1.5), 0.5, 0.0)  # kN
    (tmp_path / "push.csv").write_text(
        "t_s,f_kN\n" + "".join(f"{a:.3f},{b}\n" for a, b in zip(t, force, strict=True))
    )
    spec = yaml.safe_load((DATA / "rigs" / "servo_lift.yaml").read_text())
    spec["scenarios"]["recorded"] = {
        "duration": {"value": 2, "unit": "s"},
        "reference": {"type": "constant", "unit": "mm", "value": 150},
        "load": {"type": "measured", "file": "push.csv", "signal": "f"},
    }
    rig_file = tmp_path / "lift.yaml"
    rig_file.write_text(yaml.safe_dump(spec, sort_keys=False))
    rig = load_rig(rig_file)
    recorded = simulate(rig, p4, "recorded")
    stepped = simulate(rig, p4, "disturbed")  # the same 500 N push, written as steps
    np.testing.assert_allclose(recorded.signals["f_load"], stepped.signals["f_load"])
    np.testing.assert_allclose(recorded.signals["y"], stepped.signals["y"], atol=1e-9)
    spec["scenarios"]["recorded"]["load"]["signal"] = "p"
    rig_file.write_text(yaml.safe_dump(spec, sort_keys=False))
    with pytest.raises(ConfigError, match=r"push\.csv"):
        load_rig(rig_file)


def test_extra_sensors_read_any_signal_scaled_and_offset(tmp_path: Path, p4) -> None:
    """A load cell (force) and a pressure transducer (4-20 mA over 0-250 bar) on the lift."""
    spec = yaml.safe_load((DATA / "rigs" / "servo_lift.yaml").read_text())
    spec["sensors"] = {
        "load_cell": {"signal": "f_loads", "gain": {"value": 1, "unit": "V/kN"}},
        "p_a_sensor": {
            "signal": "p_a", "unit": "mA",
            "offset": {"value": 4, "unit": "mA"}, "gain": {"value": 0.064, "unit": "mA/bar"},
        },
    }  # fmt: skip
    rig_file = tmp_path / "lift.yaml"
    rig_file.write_text(yaml.safe_dump(spec, sort_keys=False))
    r = simulate(load_rig(rig_file), p4, "disturbed")
    np.testing.assert_allclose(r.signals["load_cell"], r.signals["f_loads"] / 1e3)
    # a reading is in its sensor's unit (here mA), as a logger records it
    np.testing.assert_allclose(r.signals["p_a_sensor"], 4.0 + 0.064 * r.signals["p_a"] / 1e5)
    assert r.units["p_a_sensor"] == "mA"


@phase("f", "f_load", "dx_y")
def _spring_force(P, X, f_load):
    f = P.k * X.y
    return f, f_load + f, 0.0


@phase("f_load")
def _damper_force(P, vel, f_load):
    return f_load + P.k * vel


@phase("dx_w")
def _moves_w(P):
    return 0.0
