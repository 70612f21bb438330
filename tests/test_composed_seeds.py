"""Seed rigs composed from components reproduce the hand-written seed plants.

Tolerances: seed 003 (pump, characteristic valve, single-rod cylinder, spring and
friction loads) is the same set of equations, so only rounding and the bore given as a
diameter (39.99941 mm for A_p = 12.566 cm²) separate the runs: 1 µm and 10 Pa. Seed 002
composed integrates chamber pressure where plants/cylinder.py integrates the liquid
volume at reference density (seed eq. 8-9); the mass form's factor (1 + p/E) ≈ 1.002
on the piston's displacement flow moves the pulses by less than 0.1 mm and 0.3 bar
(rigs/dinca_cylinder_composed.yaml), about the compiled loop's own tolerance (0.31 bar,
closed_loop.py DEFAULT_TOL).
"""

from __future__ import annotations

import numpy as np
from support import controller_named, rig_named

from fuzzyservo.simulation import simulate


def test_seed002_composed_reproduces_the_open_centre_cylinder() -> None:
    hand, composed = rig_named("dinca_cylinder"), rig_named("dinca_cylinder_composed")
    p10 = controller_named("p_k10")
    a, b = simulate(hand, p10, "pulses"), simulate(composed, p10, "pulses")
    assert b.status == "ok"
    np.testing.assert_allclose(b.signals["y"], a.signals["y"], atol=0.1e-3)
    for mine, theirs in (("p_s", "p1"), ("p_t", "p2"), ("p_a", "p3"), ("p_b", "p4")):
        np.testing.assert_allclose(b.signals[mine], a.signals[theirs], atol=0.3e5)
    np.testing.assert_array_equal(b.saturated, a.saturated)
    assert set(hand.plant.effects) <= set(composed.plant.effects)  # every effect, and more


def test_seed003_composed_reproduces_the_hydroprax_bench() -> None:
    hand, composed = rig_named("hydroprax_pdcv"), rig_named("hydroprax_pdcv_composed")
    pi = controller_named("pi_hydroprax")
    a, b = simulate(hand, pi, "steps"), simulate(composed, pi, "steps")
    assert b.status == "ok" and b.integration_steps == a.integration_steps
    np.testing.assert_allclose(b.signals["y"], a.signals["y"], atol=1e-6)
    for k in ("p_s", "p_a", "p_b"):
        np.testing.assert_allclose(b.signals[k], a.signals[k], atol=10.0)
    for k in ("q_a", "q_b", "q_relief", "q_supply"):
        np.testing.assert_allclose(b.signals[k], a.signals[k], atol=1e-9)
