"""The segmented replay (calibration/segments.py): the record cut into segments, each
restarted from the state the record shows, so that a friction's fit has a valley where
the whole replay is chaotic."""

from __future__ import annotations

import numpy as np
import pytest
from support import controller_named, rig_named

from fuzzyservo.calibration import calibrate
from fuzzyservo.calibration.replay import make_replay
from fuzzyservo.calibration.segments import probe_rigs, segmented
from fuzzyservo.calibration.synthetic import synthetic_run
from fuzzyservo.simulation import Resets, simulate

NOISE = {"y": 5e-6, "p_s": 5e3, "p_t": 5e3, "p_a": 5e3, "p_b": 5e3}
FORCE = 300.0  # N: the record's Coulomb friction


@pytest.fixture(scope="module")
def friction_record():
    """30 s of the seed-002 rig under P K=10 with 300 N of Coulomb friction undeclared,
    its replay through the controller, whole and segmented."""
    rig, controller = rig_named("dinca_cylinder"), controller_named("p_k10")
    data = synthetic_run(rig, controller, "pulses", {"coulomb_friction": {"force": FORCE}},
                         NOISE, duration_s=30.0)  # fmt: skip
    replay = make_replay(rig, data, controller)
    seg = segmented(replay, rig, probe_rigs(rig, ["coulomb_friction"]))
    return rig, controller, data, replay, seg


def _friction(rig, force: float):
    return rig.with_effect("coulomb_friction", force=force)


def _cost(replay, rig) -> float:
    model, _ = replay.run(rig, training=True)
    return replay.cost(model, slice(0, replay.split))


def test_a_state_reset_to_the_runs_own_value_changes_nothing():
    """The compiled loop's resets: setting every plant state to the value the run has
    there anyway leaves the run bit for bit as it was."""
    rig, controller = rig_named("dinca_cylinder"), controller_named("p_k10")
    plain = simulate(rig, controller, "pulses")
    at = np.arange(7, plain.t.size, 7)
    states = rig.plant.states
    values = np.column_stack([plain.signals[s][at] for s in states])
    reset = simulate(rig, controller, "pulses", resets=Resets(at, states, values))
    assert reset.status == plain.status
    for name in plain.signals:
        np.testing.assert_array_equal(reset.signals[name], plain.signals[name], err_msg=name)


def test_a_reset_moves_the_state_it_names_and_the_run_goes_on_from_there():
    rig, controller = rig_named("dinca_cylinder"), controller_named("p_k10")
    plain = simulate(rig, controller, "pulses")
    at = np.array([500])
    moved = plain.signals["y"][500] + 1e-3
    reset = simulate(rig, controller, "pulses", resets=Resets(at, ("y",), np.array([[moved]])))
    np.testing.assert_array_equal(reset.signals["y"][:500], plain.signals["y"][:500])
    assert reset.signals["y"][500] == moved
    assert reset.status == "ok"


def test_the_segmented_cost_is_smooth_where_the_whole_replay_is_chaotic(friction_record):
    """A millionth more friction: the segmented training cost moves by under 1 % (the
    docs' chaos table), and its valley holds the record's friction within 5 %."""
    rig, _, _, whole, seg = friction_record
    assert seg.segment_s < whole.training_s / 4 and seg.segment_words
    at_truth = _cost(seg, _friction(rig, FORCE))
    nudged = _cost(seg, _friction(rig, FORCE * (1 + 1e-6)))
    assert abs(nudged / at_truth - 1.0) < 1e-2
    forces = np.linspace(0.8 * FORCE, 1.2 * FORCE, 9)
    best = forces[int(np.argmin([_cost(seg, _friction(rig, f)) for f in forces]))]
    assert abs(best / FORCE - 1.0) <= 0.05
    assert seg.whole().resets.at.size == 0 and whole.whole() is whole


@pytest.mark.slow
def test_a_segmented_calibration_finds_the_friction_and_shows_the_whole_record(friction_record):
    """``calibrate(..., segments=True)`` adds the Coulomb friction alone, its 95 %
    interval holds 300 N, and what it shows (the overlays, fit % before → after) is
    the whole record's replay, not the segments'."""
    rig, controller, data, _, _ = friction_record
    result = calibrate(rig, data, controller, segments=True, workers=2)
    assert [c.name for c in result.added] == ["coulomb_friction"]
    lo, hi = result.uncertainty["coulomb_force_si"].interval
    assert lo <= FORCE <= hi
    assert result.replay.resets.at.size == 0
    shown, _ = result.replay.run(result.calibrated, result.outcome.controller)
    for channel, values in shown.items():
        np.testing.assert_array_equal(result.models["calibrated"][channel], values)
    assert result.cost_final < result.cost_declared


def test_writing_a_calibrations_files_simulates_nothing(tmp_path, friction_record):
    """The result carries everything computed (calibration/run.py ``conclude``): writing
    its report, figures, summary and calibrated rig from ``io`` calls no function of
    the simulation, the plants' compilers or the search, directly or through others
    (every Python call is followed while it writes)."""
    import sys

    from fuzzyservo.io.calibration_report import write_calibration

    rig, controller, data, _, _ = friction_record
    result = calibrate(rig, data, controller, effects=["valve_bias"], max_effects=1,
                       bootstrap_draws=0)  # fmt: skip
    forbidden = ("fuzzyservo/simulation/", "fuzzyservo/plants/native", "fuzzyservo/codegen/",
                 "fuzzyservo/calibration/search", "fuzzyservo/calibration/candidates",
                 "fuzzyservo/calibration/replay")  # fmt: skip
    called: set[str] = set()

    def watch(frame, event, arg):
        if event == "call":
            name = frame.f_code.co_filename.replace("\\", "/")
            if any(part in name for part in forbidden):
                called.add(f"{name}:{frame.f_code.co_name}")

    sys.setprofile(watch)
    try:
        paths = write_calibration(result, tmp_path / "out", "friction.csv")
        result.to_dict()
        result.text()
    finally:
        sys.setprofile(None)
    assert paths["report"].is_file() and paths["summary"].is_file()
    allowed = {"measured", "t", "split_s"}  # the replay's recorded data, read
    assert {c for c in called if c.rsplit(":", 1)[1] not in allowed} == set()
