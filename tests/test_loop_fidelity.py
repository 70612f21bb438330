"""The loop as the bench sees it (issue 11, items 1-3): I/O delay, sensor noise and ADC
quantisation, converter limits.

References: the delay against the same run with its input shifted by hand; the ADC step
against range / 2^bits (seed 002: NI-USB 6251, 16 bit, ±10 V); the saturation pattern
against seed 002 §5 (P K=10 saturated most of each transition, FLC1 never, FLC2 briefly).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import yaml
from support import DATA, controller_named, rig_named

from fuzzyservo.components.effects import INPUT_EFFECTS, E
from fuzzyservo.controllers.classical import OpenLoop
from fuzzyservo.errors import ConfigError
from fuzzyservo.io.rigs import load_rig
from fuzzyservo.rig import Scenario
from fuzzyservo.signals import Sampled
from fuzzyservo.simulation import simulate
from fuzzyservo.simulation._loop import LOOP_STAGES, LoopSettings, adc
from fuzzyservo.simulation.closed_loop import loop_settings, prepare
from fuzzyservo.simulation.reference import simulate_reference


@pytest.fixture(scope="module")
def rig():
    return rig_named("dinca_cylinder")


def _open_loop_inputs(dt: float) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(200) * dt
    return t, np.where(t >= 0.5, 6.45, 6.2)


def test_shipped_seed_002_loop_declares_delay_noise_and_adc(rig) -> None:
    assert rig.io_delay_s == pytest.approx(0.020)  # two samples: see the rig file's note
    assert rig.feedback.noise_std == pytest.approx(1e-3)
    assert rig.feedback.adc_bits == 16
    assert (rig.actuator.lower, rig.actuator.upper) == pytest.approx((-0.020, 0.020))


def test_io_delay_shifts_the_command_by_whole_samples(rig) -> None:
    """Two samples of I/O delay equal the undelayed loop fed the input two samples late."""
    dt = rig.sample_time_s
    t, u = _open_loop_inputs(dt)
    ctrl = OpenLoop(gain=0.01, name="open")  # 0.01 V/V: the converter stays unsaturated
    delayed = simulate(rig, ctrl, Scenario("s", 2.0, Sampled(t, u)), noise=False)
    late = Scenario("s", 2.0, Sampled(t, np.concatenate([[u[0]] * 2, u[:-2]])))
    shifted = simulate(dataclasses.replace(rig, io_delay_s=0.0), ctrl, late, noise=False)
    assert np.allclose(delayed.signals["y"], shifted.signals["y"], atol=2e-7)
    # the record keeps the command as sampled; the delay lies between it and the valve
    assert np.allclose(delayed.command, 0.01 * u)


def test_io_delay_is_transport_delay_within_the_hold(rig) -> None:
    """A fractional I/O delay is the transport_delay machinery: the same run to rounding."""
    dt = rig.sample_time_s
    t, u = _open_loop_inputs(dt)
    ctrl, sc = OpenLoop(gain=0.01, name="open"), Scenario("s", 2.0, Sampled(t, u))
    io = simulate(dataclasses.replace(rig, io_delay_s=1.37 * dt), ctrl, sc, noise=False)
    effect = dataclasses.replace(rig, io_delay_s=0.0).with_effect(
        "transport_delay", delay=1.37 * dt
    )
    tr = simulate(effect, ctrl, sc, noise=False)
    assert np.array_equal(io.signals["y"], tr.signals["y"])
    # and both add: 0.37 dt of transport delay behind 1 dt of I/O delay
    both = simulate(
        dataclasses.replace(rig, io_delay_s=dt).with_effect("transport_delay", delay=0.37 * dt),
        ctrl,
        sc,
        noise=False,
    )
    assert np.allclose(both.signals["y"], tr.signals["y"], atol=1e-9)


def test_io_delay_is_its_own_stage_declared_once(rig) -> None:
    """The I/O delay is a loop setting, the transport delay an effect in the packed
    parameters: neither is folded into the other, and the loop's settings are the
    declared stages' parameters."""
    stages = [stage.name for stage in LOOP_STAGES]
    assert stages.index("io_delay") + 1 == stages.index("transport_delay")
    late = rig.with_effect("transport_delay", delay=3e-3)
    prep = prepare(late, controller_named("p_k10"))
    assert prep.p[E.transport_delay_s] == 3e-3
    assert loop_settings(late).io_delay_s == rig.io_delay_s == pytest.approx(0.020)
    compiled = [p.name for stage in LOOP_STAGES for p in stage.params if p.compiled]
    assert LoopSettings._fields == (*compiled, "tol")
    # every input effect is one loop stage, and only input effects are
    effects = [stage.effect for stage in LOOP_STAGES if stage.effect]
    assert sorted(effects) == sorted(INPUT_EFFECTS)


def test_noise_reproduces_with_its_seed_and_switches_off(rig) -> None:
    ctrl = controller_named("p_k10")
    one = simulate(rig, ctrl, "steps", duration_s=3.0)
    again = simulate(rig, ctrl, "steps", duration_s=3.0)
    other = simulate(rig, ctrl, "steps", duration_s=3.0, noise_seed=1)
    assert np.array_equal(one.measured, again.measured)
    assert np.array_equal(one.signals["y"], again.signals["y"])
    assert not np.array_equal(one.measured, other.measured)
    # the controller saw a reading about 1 mV off the true one; the record keeps both
    seen = one.measured - one.feedback
    assert 0.7e-3 < np.std(seen) < 1.3e-3
    # switched off per run or per scenario: the reading is the true one, only quantised
    quiet = simulate(rig, ctrl, "steps", duration_s=3.0, noise=False)
    fb = rig.feedback
    assert np.array_equal(quiet.measured, adc(quiet.feedback, -10.0, 10.0, fb.adc_step))
    assert np.max(np.abs(quiet.measured - quiet.feedback)) <= fb.adc_step / 2 * (1 + 1e-9)
    off = dataclasses.replace(rig.scenario("steps"), noise=False)
    by_scenario = simulate(rig, ctrl, off, duration_s=3.0)
    assert np.array_equal(by_scenario.measured, quiet.measured)


def test_adc_step_is_range_over_two_to_the_bits(rig) -> None:
    fb = rig.feedback
    assert fb.adc_step == pytest.approx(20.0 / 2**16)
    res = simulate(rig, controller_named("p_k10"), "steps", duration_s=3.0)
    codes = (res.measured - fb.adc_lower) / fb.adc_step
    assert np.allclose(codes, np.round(codes), atol=1e-6)
    # readings beyond the range clip to its first and last codes
    assert adc(12.0, -10.0, 10.0, fb.adc_step) == pytest.approx(10.0 - fb.adc_step)
    assert adc(-12.0, -10.0, 10.0, fb.adc_step) == -10.0
    assert adc(0.123, -10.0, 10.0, 0.0) == 0.123


def test_compiled_and_reference_paths_agree_with_delay_and_noise(rig) -> None:
    ctrl = controller_named("p_k10")
    fast = simulate(rig, ctrl, "steps", duration_s=3.0)
    ref = simulate_reference(rig, ctrl, "steps", duration_s=3.0, rtol=1e-8)
    # both saw the same noise: their readings sit at most one ADC code apart (where the
    # integrators' µm-level difference crosses a code edge), and so do the positions
    step = rig.feedback.adc_step
    assert np.max(np.abs(fast.measured - ref.measured)) <= step * (1 + 1e-9)
    assert np.max(np.abs(fast.signals["y"] - ref.signals["y"])) < step / rig.feedback.slope


def _saturated_per_transition(res) -> float:
    """Saturated time [s] per reference transition after the warm-up."""
    scored = res.t >= res.warmup_s
    transitions = np.count_nonzero(np.diff(res.reference[scored]) != 0)
    return float(res.saturated[scored].sum() * res.sample_time_s / transitions)


def test_seed_002_saturation_pattern(rig) -> None:
    """Seed 002 §5: P K=10 saturates most of each transition, FLC1 never, FLC2 briefly
    (delay and noise on, the shipped ±20 mA converter)."""
    sat = {
        name: _saturated_per_transition(simulate(rig, controller_named(name), "pulses"))
        for name in ("p_k10", "flc1_translated", "flc2_reshaped")
    }
    assert sat["flc1_translated"] == 0.0
    assert 0.0 < sat["flc2_reshaped"] < 0.5 * sat["p_k10"]
    # most of each transition: P takes 0.24-0.28 s to reach 90 % of a 1 V step, 0.22-0.25 s
    # of it in saturation
    assert sat["p_k10"] > 0.15


def _rig_file_with(tmp_path: Path, section: str, key: str, value: object) -> Path:
    data = yaml.safe_load((DATA / "rigs" / "dinca_cylinder.yaml").read_text(encoding="utf-8"))
    data[section][key] = value
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


@pytest.mark.parametrize(
    ("section", "key", "value", "hint"),
    [
        ("controller", "io_delay", {"value": -5, "unit": "ms"}, "must lie in 0 .. 100 sample"),
        ("feedback", "noise", {"value": -1, "unit": "mV"}, "must be >= 0"),
        ("feedback", "adc_bits", {"value": 12.5, "unit": "1"}, "whole number of bits"),
        ("feedback", "adc_upper", {"value": -20, "unit": "V"}, "`adc_lower < adc_upper`"),
    ],
)
def test_bad_loop_keys_name_file_and_key(tmp_path, section, key, value, hint) -> None:
    path = _rig_file_with(tmp_path, section, key, value)
    with pytest.raises(ConfigError) as info:
        load_rig(path)
    assert info.value.key == f"{section}.{key}"
    assert hint in str(info.value)


def test_scenario_noise_switch_is_read_and_checked(tmp_path) -> None:
    data = yaml.safe_load((DATA / "rigs" / "dinca_cylinder.yaml").read_text(encoding="utf-8"))
    data["scenarios"]["steps"]["noise"] = False
    path = tmp_path / "quiet.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    assert load_rig(path).scenario("steps").noise is False
    data["scenarios"]["steps"]["noise"] = "off"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        load_rig(path)
    assert info.value.key == "scenarios.steps.noise"
