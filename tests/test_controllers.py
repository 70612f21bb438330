"""Baseline controllers: the laws, anti-windup, and one test every controller passes."""

from __future__ import annotations

import numpy as np
import pytest

from fuzzyservo.controllers.classical import PI, PIDF, OpenLoop, P
from fuzzyservo.controllers.fuzzy import (
    FuzzyController,
    FuzzySystem,
    SevenTermDesign,
    identity_rules,
)
from fuzzyservo.controllers.fuzzy.design import macvicar_whelan, table_rules
from fuzzyservo.metrics import result_metrics
from fuzzyservo.simulation import simulate


def _fuzzy(form: str) -> FuzzyController:
    e = SevenTermDesign("e", -2, 2, reshape=1.5, points=51).variable()
    u = SevenTermDesign("u", -3, 3, translate=0.26, points=51).variable()
    if form == "p":
        return FuzzyController(
            FuzzySystem("f", (e,), u, identity_rules()), form=form, name="fuzzy_p"
        )
    de = SevenTermDesign("de", -10, 10, points=51).variable()
    system = FuzzySystem("f", (e, de), u, table_rules(macvicar_whelan()))
    return FuzzyController(
        system, form=form, output_gain=1.0 if form == "pd" else 3.0, name=f"fuzzy_{form}"
    )


ALL_CONTROLLERS = [
    P(gain=10.0, u_min=-10, u_max=10, name="p"),
    PI(kp=5.0, ki=20.0, u_min=-3, u_max=3, name="pi"),
    OpenLoop(gain=0.01, u_min=-1, u_max=1, name="ol"),
    PIDF(kp=5.0, ki=20.0, kd=0.05, filter_time_s=0.02, u_min=-3, u_max=3, name="pidf"),
    PIDF(kp=5.0, ki=20.0, kd=0.05, filter_time_s=0.02, form="I-PD", name="i_pd"),
    _fuzzy("p"),
    _fuzzy("pd"),
    _fuzzy("pi"),
]


@pytest.mark.parametrize("controller", ALL_CONTROLLERS, ids=lambda c: c.name)
def test_python_face_replays_the_compiled_loop(dinca, controller):
    """The same controller, stepped from Python on the recorded reference and the reading
    it saw (``measured``: noise and ADC, issue 11), gives exactly the commands the
    compiled loop applied (state passed explicitly)."""
    r = simulate(dinca, controller, "steps", duration_s=3.0)
    c = (
        controller
        if controller.has_limits
        else controller.with_limits(*dinca.actuator.command_limits)
    )
    state = c.init(dinca.sample_time_s)
    replay = []
    for ref, y in zip(r.reference, r.measured, strict=True):
        u, state = c.step(state, ref, y)
        replay.append(u)
    np.testing.assert_array_equal(np.array(replay), r.command)


def test_step_does_not_mutate_the_given_state():
    c = PI(kp=1.0, ki=1.0, u_min=-5, u_max=5)
    s0 = c.init(0.01)
    _, s1 = c.step(s0, 1.0, 0.0)
    assert s0[1][0] == 0.0 and s1[1][0] == pytest.approx(0.01)


def test_p_law_and_limits():
    c = P(gain=10.0, u_min=-3.0, u_max=3.0)
    s = c.init(0.01)
    assert c.step(s, 6.3, 6.25)[0] == pytest.approx(0.5)
    assert c.step(s, 7.2, 6.2)[0] == 3.0
    assert c.step(s, 5.2, 6.2)[0] == -3.0


def test_pi_integrates_and_clamps():
    """Conditional integration: the integral stops growing while the output is saturated
    in the direction of the error (Åström & Hägglund §3.5)."""
    c = PI(kp=1.0, ki=10.0, u_min=-1.0, u_max=1.0)
    s = c.init(0.01)
    u, s = c.step(s, 0.5, 0.0)  # e = 0.5: unsaturated, integrates
    assert u == pytest.approx(0.5) and s[1][0] == pytest.approx(0.005)
    for _ in range(1000):
        u, s = c.step(s, 5.0, 0.0)  # saturated high for 10 s
    assert u == 1.0
    assert s[1][0] == pytest.approx(0.005)  # no wind-up
    u, s = c.step(s, 0.0, 0.1)  # error reverses: leaves saturation at once
    assert u == pytest.approx(-0.1 + 10 * 0.005)


def test_limits_must_be_ordered():
    with pytest.raises(ValueError, match="u_min < u_max"):
        P(gain=1.0, u_min=1.0, u_max=-1.0)


def test_controller_without_limits_gets_the_actuator_range(dinca):
    r = simulate(dinca, P(gain=10.0, name="free"), "pulses", duration_s=3.0)
    lo, hi = dinca.actuator.command_limits  # ±20 mA (issue 11) / 10 mA/V = ±2 V
    assert (lo, hi) == pytest.approx((-2.0, 2.0))
    assert r.command.max() == pytest.approx(2.0)


def test_pi_removes_the_bias_error_p_leaves(dinca, p_k10):
    """Integral action cancels the steady-state error the valve bias causes under P (seed 002 §5)."""
    p_metrics = result_metrics(simulate(dinca, p_k10, "steps")).aggregate
    pi_metrics = result_metrics(simulate(dinca, PI(kp=10.0, ki=20.0, name="pi"), "steps")).aggregate
    assert p_metrics["sse_abs"] > 1e-3
    assert pi_metrics["sse_abs"] < 0.05 * p_metrics["sse_abs"]


def test_packed_layouts_are_declared_by_name():
    """cp/cs slots come from one declaration: pack() needs every slot by name, and the
    kernels, the packer and the generated C read the same indices."""
    from fuzzyservo.controllers.classical import PIDF_PARAMS, PIDF_STATE
    from fuzzyservo.controllers.fuzzy.controller import FUZZY_PARAMS, SYSTEM
    from fuzzyservo.controllers.layout import layout, pack, slots

    cp, cs = PIDF(kp=2.0, ki=3.0, filter_time_s=0.01, form="PI-D").pack(0.001)
    assert cp.size == len(PIDF_PARAMS) and cs.size == len(PIDF_STATE)
    assert (cp[PIDF_PARAMS.kp], cp[PIDF_PARAMS.c], cp[PIDF_PARAMS.sample_time]) == (2.0, 0.0, 0.001)
    assert [s.flag for s in slots(PIDF_STATE)] == [False, False, False, True]
    assert SYSTEM == len(FUZZY_PARAMS)
    with pytest.raises(ValueError, match="missing"):
        pack(PIDF_PARAMS, kp=1.0)
    with pytest.raises(ValueError, match="declared twice"):
        layout("Twice", "a", "a")
