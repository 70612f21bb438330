"""The ``entrained_air`` effect (issue 29, item 5): every chamber integrated with the
mixture's bulk modulus E_mix(p) and held at the oil's vapour pressure; off by default.

The suction scenario: seed 003's bench (hydroprax_pdcv) started at 50 mm with the piston
extending at 1 m/s while the PI loop asks for 0 mm, so the valve drains chamber A while
the piston enlarges it. With the seed's constant B chamber A falls to −39 bar absolute.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from support import controller_named, rig_named

from fuzzyservo.components.air import ATMOSPHERE_PA, EntrainedAir
from fuzzyservo.components.effects import LIBRARY, E, chamber_modulus
from fuzzyservo.simulation.closed_loop import simulate
from fuzzyservo.simulation.validity import entrained_air, pressure_violation

OIL = 1.8e8  # Pa, seed 003's B


@pytest.fixture(scope="module")
def bench():
    rig = rig_named("hydroprax_pdcv")
    base = rig.scenario("steps")
    suction = dataclasses.replace(base, initial={**base.initial, "position": 0.05, "velocity": 1.0})
    return rig, controller_named("pi_hydroprax"), suction


def _params(alpha: float, index: float = 1.0, vapour: float = 1e3) -> np.ndarray:
    p = np.zeros(len(E))
    p[E.air_fraction], p[E.air_polytropic_index] = alpha, index
    p[E.air_vapour_pressure_pa] = vapour
    return p


def test_modulus_is_the_oils_when_off_and_the_mixtures_when_on():
    off = _params(0.0)
    for gauge in (-1.2e5, -0.5e5, 0.0, 3e6):
        for flow in (-1e-4, 0.0, 1e-4):
            assert chamber_modulus(gauge, flow, OIL, off) == OIL  # exactly: bit for bit
    air = EntrainedAir(air_fraction=0.005)
    on = _params(0.005)
    for p_abs in (2e4, 1e5, 2e6, 3e7):
        got = chamber_modulus(p_abs - ATMOSPHERE_PA, 1e-4, OIL, on)
        assert got == pytest.approx(air.bulk_modulus(p_abs, OIL), rel=1e-12)
    # Merritt's limits: the oil's at high pressure, n·p/r near vacuum (docs/modelling.md)
    assert chamber_modulus(3e7, 0.0, OIL, on) == pytest.approx(OIL, rel=0.01)
    assert chamber_modulus(-0.9e5, 1e-4, OIL, on) < 0.01 * OIL


def test_modulus_falls_to_zero_at_the_vapour_pressure_only_while_the_chamber_empties():
    on = _params(1e-4, vapour=1e3)
    at_floor = 1e3 - ATMOSPHERE_PA
    assert chamber_modulus(at_floor, -1e-5, OIL, on) == 0.0
    assert chamber_modulus(at_floor, +1e-5, OIL, on) > 0.0  # refills at once
    half_band = 1.5e3 - ATMOSPHERE_PA
    full = chamber_modulus(half_band, +1e-5, OIL, on)
    assert chamber_modulus(half_band, -1e-5, OIL, on) == pytest.approx(0.5 * full)


def test_every_chamber_component_declares_the_effect():
    from fuzzyservo.components.declare import registry

    def reads_modulus(function) -> bool:  # directly or through the chambers' shared law
        return bool({"chamber_modulus", "two_chambers"} & set(function.py_func.__code__.co_names))

    readers = {
        t
        for t, c in registry().items()
        for functions in c.code.values()
        for f in (functions if isinstance(functions, tuple) else (functions,))
        if reads_modulus(f)
    }
    assert readers == {t for t, c in registry().items() if "entrained_air" in c.effects}
    assert {"single_rod_cylinder", "double_rod_cylinder", "motor", "lines"} <= readers
    assert [p.fitted for p in LIBRARY["entrained_air"].params] == [True, False, False]


def test_off_by_default_gives_identical_results(bench):
    rig, ctl, _ = bench
    assert rig.params.air_fraction == 0.0 and "entrained_air" not in rig.effects
    declared_off = rig.with_effect("entrained_air", air_fraction=0.0)
    a = simulate(rig, ctl, "steps", duration_s=1.0)
    b = simulate(declared_off, ctl, "steps", duration_s=1.0)
    for name in ("y", "p_a", "p_b", "p_s"):
        np.testing.assert_array_equal(a.signals[name], b.signals[name])


def test_suction_stays_above_the_vapour_pressure(bench):
    rig, ctl, suction = bench
    bare = simulate(rig, ctl, suction, duration_s=0.3)
    assert bare.status == "cavitation"
    assert bare.signals["p_a"].min() + ATMOSPHERE_PA < -1e6  # a liquid under tension

    # 0.5 % air (the usual amount) cushions the suction well above the floor
    cushioned = simulate(rig.with_effect("entrained_air", air_fraction=0.005), ctl, suction,
                         duration_s=0.3)  # fmt: skip
    assert cushioned.status == "ok", cushioned.message
    assert 2e3 < cushioned.signals["p_a"].min() + ATMOSPHERE_PA < 0.5e5

    # little air: the chamber reaches the vapour pressure and is held there, reported
    aired = rig.with_effect("entrained_air", air_fraction=1e-4)
    held = simulate(aired, ctl, suction, duration_s=0.3)
    lowest = min(held.signals[n].min() for n in ("p_a", "p_b", "p_s")) + ATMOSPHERE_PA
    assert lowest >= 0.99 * aired.params.air_vapour_pressure_pa
    assert held.status == "cavitation" and "holds the chamber" in held.message
    assert held.signals["p_a"][-1] > 10e5  # refilled: the loop goes on
    assert np.all(np.isfinite(held.signals["y"]))


def test_pressure_violation_with_air_reports_the_floor():
    t = np.arange(3) * 0.1
    air = EntrainedAir(air_fraction=0.005, vapour_pressure_pa=1e3)
    high = {"p_a": np.array([1e5, 5e3 - ATMOSPHERE_PA, 1e5])}
    assert pressure_violation(t, high, ("p_a",), air) == ""
    floor = {"p_a": np.array([1e5, 1.1e3 - ATMOSPHERE_PA, 1e5])}
    assert "vapour pressure" in pressure_violation(t, floor, ("p_a",), air)
    assert pressure_violation(t, floor, ("p_a",)) == ""  # above 0 Pa absolute
    rig = rig_named("hydroprax_pdcv")
    assert entrained_air(rig.params) is None
    assert entrained_air(rig.with_effect("entrained_air", air_fraction=0.003).params) == (
        EntrainedAir(air_fraction=0.003, polytropic_index=1.0, vapour_pressure_pa=1e3)
    )


def test_reproduce_declares_the_air_of_the_orifice_variant_as_an_assumption():
    from fuzzyservo.io.reproduction import load_reproduction_spec

    spec = load_reproduction_spec()
    air = next(a for a in spec.assumptions if a.target == "effects.entrained_air.air_fraction")
    assert air.rig == "hydroprax_orifice" and air.value == pytest.approx(0.005)
    assert "0.1-1 %" in air.reason and min(air.values) < air.value < max(air.values)
    # the seed rigs themselves stay without it: their numbers are the seeds'
    for name in ("hydroprax_pdcv", "dinca_cylinder", "ehs160_motor", "ahc_motor"):
        assert "entrained_air" not in rig_named(name).effects


def test_an_impossible_air_fraction_is_refused_by_name():
    rig = rig_named("hydroprax_pdcv")
    with pytest.raises(ValueError, match=r"entrained_air\.air_fraction: must be <= 0\.5"):
        rig.with_effect("entrained_air", air_fraction=1.5)
