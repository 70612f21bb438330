"""The effect library: formulations, their place in every plant, and how rig files declare them."""

from __future__ import annotations

import dataclasses
import math
import pickle
from pathlib import Path

import numpy as np
import pytest
import yaml
from reference_plants import motor as motor_module
from reference_plants import reference_rig
from support import DATA, controller_named, ideal_sensor, rig_named

from fuzzyservo.components import effects as fx
from fuzzyservo.components.orifice import signed_sqrt_flow
from fuzzyservo.controllers.classical import OpenLoop
from fuzzyservo.errors import ConfigError
from fuzzyservo.io.rigs import load_rig
from fuzzyservo.params import index_of, pack
from fuzzyservo.rig import Scenario
from fuzzyservo.signals import Sampled, Steps
from fuzzyservo.simulation import simulate
from fuzzyservo.simulation.reference import simulate_reference

ISSUE_NAMES = (
    "coulomb_friction", "stribeck_friction", "line_resistance", "internal_leakage",
    "valve_deadband", "valve_bias", "valve_lag", "transport_delay", "bulk_modulus",
    "supply_droop",
)  # fmt: skip


def test_library_has_exactly_the_issue_names_with_units_bounds_and_sources() -> None:
    # the ten names of the calibration issue, then the effects added since (issue 10)
    assert tuple(fx.LIBRARY)[: len(ISSUE_NAMES)] == ISSUE_NAMES
    assert tuple(fx.LIBRARY)[len(ISSUE_NAMES) :] == ("external_leakage", "entrained_air")
    # a calibration screens all but entrained air (only low pressures tell it apart)
    assert [e.name for e in fx.LIBRARY.values() if not e.screened] == ["entrained_air"]
    scales = rig_named("dinca_cylinder").scales()
    for effect in fx.LIBRARY.values():
        assert effect.formulation and effect.source
        assert effect.fitted, effect.name
        for param in effect.params:
            lo, hi = param.value_bounds(scales)
            assert lo < hi and math.isfinite(lo) and math.isfinite(hi), (effect.name, param.key)


@pytest.mark.parametrize(
    "name", ["dinca_cylinder", "ehs160_motor", "hydroprax_pdcv", "ahc_cylinder", "ahc_motor"]
)
def test_every_plant_carries_the_effects_at_the_same_positions(name: str) -> None:
    plant = rig_named(name).plant
    cls = plant.params_cls
    assert issubclass(cls, fx.EffectParams)
    assert index_of(cls, "coulomb_force_si") == fx.E.coulomb_force_si == 0
    for field_name, at in fx.E._asdict().items():
        assert index_of(cls, field_name) == at
    assert set(fx.INPUT_EFFECTS) <= set(plant.effects)


def test_effect_parameters_are_made_from_the_library_declarations() -> None:
    declared = {prm.field: prm for e in fx.LIBRARY.values() for prm in e.params}
    fields = {f.name: f for f in dataclasses.fields(fx.EffectParams)}
    assert set(fields) == set(declared) == set(fx.E._fields)
    for field_name, prm in declared.items():
        meta = fields[field_name].metadata
        assert meta["unit"] == prm.unit and meta["doc"] == prm.doc
        assert meta["nonnegative"] is not prm.signed
        assert meta["key"].endswith(f".{prm.key}")
    assert fields["valve_bias_si"].metadata["key"] == "valve_bias.offset"
    with pytest.raises(ValueError, match="unit"):
        fx.EffectParam("k", "k_si", "Pa*s/m^3x", lambda s: (0.0, 1.0), doc="a misspelt unit")


def test_friction_force_formulation() -> None:
    # MODELLING.md: F = (Fc + Fst·exp(−(v/vs)²))·tanh(v/vc); here Fc = 100 + 50 N
    p = np.zeros(len(fx.E))
    p[fx.E.coulomb_force_si], p[fx.E.stribeck_coulomb_force_si] = 100.0, 50.0
    p[fx.E.stribeck_stiction_force_si] = 30.0
    p[fx.E.stribeck_velocity_si], p[fx.E.friction_smoothing_velocity_si] = 5e-3, 1e-4
    assert fx.friction_force(0.0, p) == 0.0
    assert fx.friction_force(1.0, p) == pytest.approx(150.0)  # far above vs: Coulomb only
    v = 5e-3
    expected = (150.0 + 30.0 * math.exp(-1.0)) * math.tanh(v / 1e-4)
    assert fx.friction_force(v, p) == pytest.approx(expected)
    assert fx.friction_force(-v, p) == pytest.approx(-expected)


def test_lugre_friction_formulation() -> None:
    # Canudas de Wit et al. 1995: off (no pre-sliding distance) it is the static law; in
    # steady sliding the bristles hold still at g(v)/σ0 and the force is the Stribeck
    # curve g(v); at rest they are a spring σ0 = (Fc + Fst)/d
    p = np.zeros(len(fx.E))
    p[fx.E.stribeck_coulomb_force_si], p[fx.E.stribeck_stiction_force_si] = 150.0, 75.0
    p[fx.E.stribeck_velocity_si], p[fx.E.friction_smoothing_velocity_si] = 5e-3, 1e-4
    assert fx.actuator_friction(0.01, 0.0, 1.0, p) == fx.friction_force(0.01, p)
    assert fx.bristle_rate(0.01, 0.0, p) == 0.0
    p[fx.E.stribeck_presliding_si] = 22.5e-6  # σ0 = 225 N / 22.5 µm = 1e7 N/m
    v = 3e-3
    g = 150.0 + 75.0 * math.exp(-((v / 5e-3) ** 2))
    assert fx.bristle_rate(v, g / 1e7, p) == pytest.approx(0.0, abs=1e-12)
    assert fx.actuator_friction(v, g / 1e7, 1.0, p) == pytest.approx(g)
    assert fx.actuator_friction(-v, -g / 1e7, 1.0, p) == pytest.approx(-g)
    assert fx.actuator_friction(0.0, 1e-6, 1.0, p) == pytest.approx(10.0)
    assert fx.bristle_rate(0.0, 1e-6, p) == 0.0


def test_lugre_friction_sticks_where_the_static_law_creeps() -> None:
    # an exact reading, as the other reference-path tests; the steps end in a 2 s hold
    rig, ctrl = ideal_sensor(rig_named("dinca_cylinder")), controller_named("p_k10")
    curve = {"coulomb_force": 150.0, "stiction_force": 75.0, "stribeck_velocity": 5e-3}
    lugre = rig.with_effect("stribeck_friction", **curve, presliding_distance=22.5e-6)
    static = rig.with_effect("stribeck_friction", **curve)
    held = {}
    for name, r in (("lugre", lugre), ("static", static)):
        res = simulate(r, ctrl, "steps", duration_s=4.0)
        y = res.signals["y"]
        held[name] = abs(y[-1] - y[np.searchsorted(res.t, res.t[-1] - 1.0)])
    assert held["lugre"] < 1e-9  # stuck: the bristles hold the P loop's force
    assert held["static"] > 1e-8  # the tanh law creeps at about its smoothing velocity
    ref = simulate_reference(lugre, ctrl, "steps", duration_s=4.0, rtol=1e-8)
    fast = simulate(lugre, ctrl, "steps", duration_s=4.0)
    assert np.max(np.abs(fast.signals["y"] - ref.signals["y"])) < 5e-6  # 4.0 µm measured


def test_the_bristle_state_is_carried_only_where_friction_sticks() -> None:
    # a run without a pre-sliding distance is spared the state; with one, the plant's
    # other form carries it last, every other state where it was, one parameter class
    rig = rig_named("dinca_cylinder")
    static = rig.with_effect("coulomb_friction", force=300.0)
    lugre = rig.with_effect("coulomb_friction", force=300.0, presliding_distance=2e-5)
    compact = static.plant.for_params(static.params)
    carried = lugre.plant.for_params(lugre.params)
    assert compact is rig.plant and "z" not in compact.states
    assert carried.states == (*compact.states, "z")
    assert carried.params_cls is compact.params_cls
    assert carried.for_params(static.params) is compact  # and back
    assert pickle.loads(pickle.dumps(carried)) is carried  # compose() is cached per form


def test_deadband_around_the_null() -> None:
    null, w = 2.83e-3, 0.5e-3
    assert fx.deadband(null + 0.3e-3, null, w) == null
    assert fx.deadband(null + 1.5e-3, null, w) == pytest.approx(null + 1.0e-3)
    assert fx.deadband(null - 1.5e-3, null, w) == pytest.approx(null - 1.0e-3)
    assert fx.deadband(7.0, null, 0.0) == 7.0


def test_port_pressure_balances_the_flows() -> None:
    c_in, c_out, lam = 2e-7, 1e-7, 1e4
    p_in, p_out, p_c, r = 70e5, 0.0, 30e5, 2e10
    x = fx.port_pressure(c_in, p_in, c_out, p_out, p_c, r, lam)
    q_valve = signed_sqrt_flow(c_in, p_in - x, lam) - signed_sqrt_flow(c_out, x - p_out, lam)
    assert q_valve == pytest.approx((x - p_c) / r, rel=1e-9, abs=1e-15)
    # a negligible line leaves the chamber pressure at the port
    assert fx.port_pressure(c_in, p_in, c_out, p_out, p_c, 1.0, lam) == pytest.approx(p_c, rel=1e-6)


def test_motor_line_flow_solves_its_implicit_equation() -> None:
    rig = reference_rig("ehs160_motor")  # the seed's equations as written
    p = pack(dataclasses.replace(rig.params, line_resistance_pa_s_m3=5e10))
    spool, p_load = -2.0, 10e5
    q = motor_module.line_flow(spool, p_load, p)
    assert q == pytest.approx(motor_module.valve_flow(spool, p_load + 2 * 5e10 * q, p), rel=1e-9)
    assert abs(q) < abs(motor_module.valve_flow(spool, p_load, p))


def test_valve_bias_is_a_shifted_null() -> None:
    """i_eff = i + b with Δi = i_eff − I_bias is the seed-002 valve with I_bias − b."""
    rig, ctrl = rig_named("dinca_cylinder"), controller_named("p_k10")
    b = 0.4e-3
    with_bias = simulate(rig.with_effect("valve_bias", offset=b), ctrl, "steps")
    null = rig.params.valve__bias_current
    shifted = simulate(rig.with_params(valve__bias_current=null - b), ctrl, "steps")
    assert np.allclose(with_bias.signals["y"], shifted.signals["y"], atol=1e-9)


def test_transport_delay_of_one_sample_shifts_the_command() -> None:
    rig = rig_named("dinca_cylinder")
    dt = rig.sample_time_s
    t = np.arange(200) * dt
    u = np.where(t >= 0.5, 6.45, 6.2)
    ctrl = OpenLoop(gain=0.01, name="open")  # 0.01 V/V: ±30 mA stays unsaturated
    base = Scenario("s", 2.0, Sampled(t, u))
    late = Scenario("s", 2.0, Sampled(t, np.concatenate([[u[0]], u[:-1]])))
    delayed = simulate(rig.with_effect("transport_delay", delay=dt), ctrl, base)
    shifted = simulate(rig, ctrl, late)
    assert np.allclose(delayed.signals["y"], shifted.signals["y"], atol=2e-7)


def test_valve_lag_matches_the_reference_path() -> None:
    # an exact reading: this pins the lag, not the ADC (issue 11, see tests/test_cylinder.py)
    rig = ideal_sensor(rig_named("dinca_cylinder")).with_effect("valve_lag", time_constant=5e-3)
    ctrl = controller_named("p_k10")
    fast = simulate(rig, ctrl, "steps", duration_s=3.0)
    ref = simulate_reference(rig, ctrl, "steps", duration_s=3.0, rtol=1e-8)
    assert np.max(np.abs(fast.signals["y"] - ref.signals["y"])) < 2e-6  # 2 µm
    # a tiny lag is no lag
    tiny = simulate(rig.with_effect("valve_lag", time_constant=1e-7), ctrl, "steps", duration_s=3.0)
    plain = simulate(rig.with_params(valve_lag_s=0.0), ctrl, "steps", duration_s=3.0)
    assert np.max(np.abs(tiny.signals["y"] - plain.signals["y"])) < 1e-6


def test_lower_bulk_modulus_slows_the_pressure_build_up() -> None:
    # an exact reading: sensor noise would leave the two runs apart at the end (issue 11)
    rig, ctrl = ideal_sensor(rig_named("dinca_cylinder")), controller_named("p_k10")
    soft = simulate(rig.with_effect("bulk_modulus", effective=0.3e9), ctrl, "steps")
    stiff = simulate(rig, ctrl, "steps")
    # the softer liquid lags the stiff one by bars in the fast transients, then agrees
    gap = np.abs(soft.signals["p_a"] - stiff.signals["p_a"])
    assert gap.max() > 5e5
    assert gap[-1] < 0.05e5


# ---------------------------------------------------------------- rig files


def _rig_with(tmp_path: Path, base: str, extra: str) -> Path:
    """The shipped rig file with ``extra`` appended; the test's own ``effects`` block
    replaces the file's (seed 002 declares its spool lag)."""
    path = tmp_path / f"{base}.yaml"
    data = yaml.safe_load((DATA / "rigs" / f"{base}.yaml").read_text())
    data.pop("effects", None)
    path.write_text(yaml.safe_dump(data, sort_keys=False) + "\n" + extra)
    return path


def test_rig_file_declares_effects_and_unknowns(tmp_path: Path) -> None:
    path = _rig_with(
        tmp_path,
        "dinca_cylinder",
        "effects:\n"
        "  coulomb_friction:\n    force: {value: 0.15, unit: kN, source: test}\n"
        "  valve_lag:\n    time_constant: {value: 3, unit: ms, fit: [0, 20]}\n",
    )
    rig = load_rig(path)
    assert rig.effects == ("coulomb_friction", "valve_lag")
    assert rig.params.coulomb_force_si == pytest.approx(150.0)
    assert rig.params.friction_smoothing_velocity_si == pytest.approx(
        rig.scales().smoothing_velocity
    )
    assert rig.unknowns == {"valve_lag_s": pytest.approx((0.0, 0.02))}
    assert rig_named("hydroprax_pdcv").effects == ()  # off by default
    assert rig_named("dinca_cylinder").effects == ("valve_lag",)  # its spool (issue 11)


@pytest.mark.parametrize(
    ("base", "extra", "key", "words"),
    [
        ("dinca_cylinder", "effects:\n  coulomb_frction: {force: 10}\n", "effects.coulomb_frction", "unknown effect"),
        ("ahc_cylinder", "effects:\n  supply_droop: {pump_flow: 1.0e-3}\n", "effects.supply_droop", "not meaningful"),
        ("dinca_cylinder", "effects:\n  valve_lag: {}\n", "effects.valve_lag", "time_constant"),
        ("dinca_cylinder", "effects:\n  valve_lag:\n    time_constant: {value: 30, unit: ms, fit: [0, 20]}\n", "effects.valve_lag.time_constant.fit", "outside"),
        ("dinca_cylinder", "effects:\n  valve_lag:\n    time_constant: {value: 3, unit: kg}\n", "effects.valve_lag.time_constant.unit", "unit"),
        ("dinca_cylinder", "measured:\n  sample_period: {value: -1, unit: s}\n", "measured.sample_period", "must be at least"),
    ],
)  # fmt: skip
def test_bad_effect_declarations_fail_with_one_line(
    tmp_path: Path, base: str, extra: str, key: str, words: str
) -> None:
    with pytest.raises(ConfigError) as info:
        load_rig(_rig_with(tmp_path, base, extra))
    message = str(info.value)
    assert key in message and words in message and "\n" not in message


def test_with_effect_refuses_what_the_plant_does_not_model() -> None:
    with pytest.raises(ValueError, match=r"not meaningful.*pump_supply"):
        rig_named("hydroprax_pdcv").with_effect("supply_droop", pump_flow=1e-4)
    rig = rig_named("hydroprax_pdcv").with_effect("valve_lag", time_constant=5e-3)
    assert simulate(rig, controller_named("pi_hydroprax")).ok


def test_steps_reference_through_open_loop() -> None:
    # the Sampled signal holds each value until the next sample
    s = Sampled(np.array([0.0, 1.0, 2.0]), np.array([1.0, 2.0, 3.0]))
    assert list(s.sample(np.array([-1.0, 0.0, 0.5, 1.0, 2.5]))) == [1.0, 1.0, 1.0, 2.0, 3.0]
    assert isinstance(Steps((1.0,), (2.0,)), Steps)
