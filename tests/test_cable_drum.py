"""The cable-drum load (components/library/cable_drum.py) on a composed motor, and the
seed-001 options of the motor and valve it rides on: the drum's winding direction, the
motor's hydro-mechanical efficiency, the servo-valve's land leakage (seed 001 eq. 3-4,
checked against the hand-written seed-001 valve, tests/reference_plants/kernels.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from reference_plants.kernels import port_flow

from fuzzyservo.params import pack
from fuzzyservo.plants.composed import CompositionError, compose
from fuzzyservo.simulation import bind

PARTS = (
    ("oil", "oil"),
    ("supply", "ideal_supply"),
    ("valve", "servo_valve"),
    ("motor", "motor"),
    ("drum", "cable_drum"),
)


def _params(plant, **over):
    values = {
        "oil__bulk_modulus": 1.5e9, "supply__supply_pressure": 100e5,
        "valve__rated_flow": 1e-4, "valve__rated_pressure_drop": 70e5,
        "valve__rated_signal": 0.01, "motor__displacement": 1e-6, "motor__volume_a": 1e-4,
        "motor__volume_b": 1e-4, "motor__inertia": 1e-3, "drum__mass": 5.0,
        "drum__drum_radius": 0.05,
    }  # fmt: skip
    values.update(over)
    return plant.params_cls(**values)


def test_the_drum_holds_its_weight_at_rest_and_adds_its_inertia() -> None:
    plant = compose(PARTS)
    p = _params(plant)
    x0 = plant.initial_state(p)
    s = dict(zip(plant.states, x0, strict=True))
    # (p_a − p_b)·D = m·g·r: the motor starts holding the weight
    assert (s["p_a"] - s["p_b"]) * 1e-6 == pytest.approx(5.0 * 9.80665 * 0.05, rel=1e-9)
    # with the valve shut and chamber A vented a little, the shaft accelerates backwards
    # at (Δp·D − m·g·r)/(J + m·r²)
    x = x0.copy()
    x[plant.states.index("p_a")] -= 1e5
    dx = bind(plant).rhs_with_inputs(x, 0.0, 0.0, pack(p), 0.0)
    expected = -1e5 * 1e-6 / (1e-3 + 5.0 * 0.05**2)
    assert dx[plant.states.index("w")] == pytest.approx(expected, rel=1e-9)
    assert np.isfinite(dx).all()


def test_the_drum_needs_a_motor() -> None:
    with pytest.raises(CompositionError, match="cable_drum load is not meaningful"):
        compose((*PARTS[:3], ("cyl", "double_rod_cylinder"), ("drum", "cable_drum")))


def test_a_drum_paying_out_forward_is_held_by_pressures_symmetric_about_null() -> None:
    """winding −1 (seed 001: +θ pays out): the weight pulls +θ, so the motor holds it with
    p_b > p_a, η_hm·(p_b − p_a)·D = m·g·r, the two symmetric about (p_s + p_t)/2."""
    plant = compose(PARTS)
    p = _params(plant, drum__winding=-1.0, motor__hydromechanical_efficiency=0.9)
    x0 = plant.initial_state(p)
    s = dict(zip(plant.states, x0, strict=True))
    assert 0.9 * (s["p_b"] - s["p_a"]) * 1e-6 == pytest.approx(5.0 * 9.80665 * 0.05, rel=1e-9)
    assert s["p_a"] + s["p_b"] == pytest.approx(100e5, rel=1e-12)
    dx = bind(plant).rhs_with_inputs(x0, 0.0, 0.0, pack(p), 0.0)
    assert dx[plant.states.index("w")] == pytest.approx(0.0, abs=1e-9)
    # the efficiency scales the hydraulic torque only: vent p_b by 1 bar
    x = x0.copy()
    x[plant.states.index("p_b")] -= 1e5
    dx = bind(plant).rhs_with_inputs(x, 0.0, 0.0, pack(p), 0.0)
    assert dx[plant.states.index("w")] == pytest.approx(0.9 * 1e5 * 1e-6 / (1e-3 + 5.0 * 0.05**2))
    with pytest.raises(ValueError, match="winding: must be"):
        _params(plant, drum__winding=0.5)


def test_land_leakage_is_the_seed001_valve() -> None:
    """K_l on each land: closed, the ports leak K_l·(p_s − 2p + p_t); open, the orifice
    flow adds to it, as plants/ahc_*.py's port_flow writes seed 001 eq. 3-4."""
    plant = compose(PARTS)
    kl, lam = 2.4e-12, 1e4
    p = _params(plant, valve__land_leakage=kl, oil__laminar_pressure=lam)
    k = 1e-4 / math.sqrt(35e5)  # rated flow over √(Δp_N/2)
    out = np.empty(len(plant.signals))
    x = plant.initial_state(p)
    states = plant.states
    for u, pa, pb in ((0.0, 30e5, 65e5), (0.004, 45e5, 52e5), (-0.007, 81e5, 12e5)):
        x[states.index("p_a")], x[states.index("p_b")] = pa, pb
        plant.kernels.plant_signals(x, u, 0.0, pack(p), out)
        sig = dict(zip(plant.signals, out, strict=True))
        opening = u / 0.01
        assert sig["q_a"] == pytest.approx(
            port_flow(opening, k, kl, 100e5, 0.0, pa, lam), rel=1e-12
        )
        assert sig["q_b"] == pytest.approx(
            port_flow(-opening, k, kl, 100e5, 0.0, pb, lam), rel=1e-12
        )
        assert sig["q_supply"] - sig["q_tank"] == pytest.approx(sig["q_a"] + sig["q_b"], rel=1e-12)
