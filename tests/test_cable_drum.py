"""The cable-drum load (components/library/cable_drum.py) on a composed motor."""

from __future__ import annotations

import numpy as np
import pytest

from fuzzyservo.params import pack
from fuzzyservo.plants.composed import CompositionError, compose

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
    dx = plant.loop.rhs_with_inputs(x, 0.0, 0.0, pack(p), 0.0)
    expected = -1e5 * 1e-6 / (1e-3 + 5.0 * 0.05**2)
    assert dx[plant.states.index("w")] == pytest.approx(expected, rel=1e-9)
    assert np.isfinite(dx).all()


def test_the_drum_needs_a_motor() -> None:
    with pytest.raises(CompositionError, match="cable_drum load is not meaningful"):
        compose((*PARTS[:3], ("cyl", "double_rod_cylinder"), ("drum", "cable_drum")))
