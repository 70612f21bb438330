"""The external_leakage effect (components/effects.py): K_e·p from each chamber to the
drain, on composed cylinders and motors; refused in one line where no kernel reads it
(the seeds' hand-written equations, tests/reference_plants)."""

from __future__ import annotations

import math

import pytest
from reference_plants import reference_rig
from support import rig_named

from fuzzyservo.controllers.classical import P
from fuzzyservo.simulation import simulate


def test_external_leakage_lets_the_lift_sink_under_its_weight() -> None:
    """Valve shut (P with zero gain: the critically lapped spool at null): without the
    effect the weight stays put; with K_e = 1e-13 m³/(s·Pa) both chambers drain and the
    piston sinks, by at most the volume lost, K_e·(p_a + p_b)·t, over the area."""
    rig = rig_named("servo_lift")
    hold = P(gain=0.0, u_min=-10.0, u_max=10.0, name="valve shut")
    still = simulate(rig, hold, "disturbed", duration_s=0.4)
    leaky = simulate(
        rig.with_effect("external_leakage", coefficient=1e-13), hold, "disturbed", duration_s=0.4
    )
    assert abs(still.signals["y"][-1] - 0.15) < 1e-7
    sink = 0.15 - leaky.signals["y"][-1]
    p = rig.params
    area = math.pi / 4 * (p.cylinder__piston_diameter**2 - p.cylinder__rod_diameter**2)
    lost = 1e-13 * (still.signals["p_a"][0] + still.signals["p_b"][0]) * 0.4
    assert 1e-6 < sink < lost / area


def test_external_leakage_is_refused_where_no_kernel_reads_it() -> None:
    """Every actuator component reads it, so every shipped rig models it (the seed-002
    rig too, whose hand-written kernel did not); the seed's equations as written still
    refuse it in one line."""
    leaky = rig_named("dinca_cylinder").with_effect("external_leakage", coefficient=1e-12)
    assert "external_leakage" in leaky.effects
    with pytest.raises(ValueError, match=r"external_leakage.*not modelled"):
        reference_rig("dinca_cylinder").with_effect("external_leakage", coefficient=1e-12)
