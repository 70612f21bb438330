"""Several records calibrated together (issue 12, item 6; fuzzyservo/calibration/joint.py).

Two seed-002 records of one rig with a 150 N Coulomb friction: position steps, and the
same steps under a 20 % stall-force load. The valve null drifted between the sessions
(+0.4 mA, then −0.3 mA): the null is fitted per record, the friction is shared.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from support import controller_named
from test_calibration import NOISE, old_loop

from fuzzyservo.calibration import calibrate as api_calibrate
from fuzzyservo.calibration.joint import joint_replay
from fuzzyservo.calibration.replay import make_replay
from fuzzyservo.calibration.search import search_effects
from fuzzyservo.calibration.summary import calibration_summary
from fuzzyservo.calibration.synthetic import synthetic_run
from fuzzyservo.errors import DataError
from fuzzyservo.io.rigs import load_rig
from fuzzyservo.signals import Constant

FRICTION = {"coulomb_friction": {"force": 150.0}}
DRIFT = (0.4e-3, -0.3e-3)  # the valve null in each session [A]


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    rig = load_rig(old_loop(tmp_path_factory.mktemp("rig")))
    ctl = controller_named("p_k10")
    steps = rig.scenarios["steps"]
    loaded = dataclasses.replace(steps, load=Constant(0.2 * rig.scales().force))
    bias = rig.params.valve__bias_current
    data = [
        synthetic_run(
            rig.with_params(valve__bias_current=bias + d), ctl, s, FRICTION, NOISE, seed=k
        )
        for k, (s, d) in enumerate(zip((steps, loaded), DRIFT, strict=True))
    ]
    unknown = dataclasses.replace(rig, unknowns={"valve__bias_current": (bias - 1e-3, bias + 1e-3)})
    return unknown, ctl, [make_replay(unknown, d, ctl) for d in data]


@pytest.mark.slow  # 3-7 s here
def test_shared_effect_and_per_record_null_from_two_records(records) -> None:
    rig, ctl, replays = records
    data = [r.data for r in replays]  # the API: a list of records is calibrated together
    effects = ["coulomb_friction", "valve_lag"]
    outcome = api_calibrate(
        rig, data, ctl, effects=effects, max_effects=1, per_record=["valve.bias_current"]
    )
    joint = joint_replay(replays, rig, per_record=["valve__bias_current"])
    assert [c.name for c in outcome.added] == ["coulomb_friction"]
    assert outcome.added[0].params["force"] == pytest.approx(150.0, rel=0.05)
    bias = rig.params.valve__bias_current
    fitted = np.array(outcome.per_record["valve__bias_current"]) - bias
    assert fitted == pytest.approx(DRIFT, abs=2e-5)
    assert outcome.cost_final < 1.2  # both records to the noise floor
    summary = calibration_summary(outcome, joint)
    assert summary["per_record"]["valve.bias_current"] == pytest.approx(
        [bias + d for d in DRIFT], abs=2e-5
    )
    # one null shared by both records cannot follow the drift
    shared = search_effects(joint_replay(replays, rig), rig, max_effects=0)
    assert shared.cost_nominal > 10 * outcome.cost_final


def test_records_with_other_channels_are_refused(records, tmp_path: Path) -> None:
    rig, ctl, replays = records
    data = replays[0].data
    fewer = dataclasses.replace(
        data,
        signals={k: v for k, v in data.signals.items() if k != "p_s"},
        units={k: v for k, v in data.units.items() if k != "p_s"},
    )
    with pytest.raises(DataError, match="same channels"):
        joint_replay([replays[0], make_replay(rig, fewer, ctl)], rig)


@pytest.mark.slow
def test_cli_calibrates_two_files_with_a_per_record_null(records, tmp_path: Path) -> None:
    """``fuzzyservo calibrate RIG a.csv b.csv --per-record valve.bias_current``: one run, one
    report; a key that is not an unknown is refused on one line."""
    import json

    import yaml
    from test_calibration import HEADER_UNITS

    from fuzzyservo.cli import main
    from fuzzyservo.io.measured import write_measured

    rig, _, replays = records
    text = yaml.safe_load(old_loop(tmp_path / "rig").read_text(encoding="utf-8"))
    text["plant"]["components"]["valve"]["parameters"]["bias_current"]["fit"] = [1.83, 3.83]  # mA
    rig_file = tmp_path / "rig" / "drifting_null.yaml"
    rig_file.write_text(yaml.safe_dump(text, sort_keys=False), encoding="utf-8")
    files = [
        write_measured(tmp_path / f"{k}.csv", r.data, HEADER_UNITS) for k, r in enumerate(replays)
    ]
    args = ["calibrate", str(rig_file), *map(str, files), "--controller", "p_k10"]
    args += ["--effects", "coulomb_friction", "--max-effects", "1", "--workers", "1"]
    code = main([*args, "--per-record", "valve.bias_current", "--out", str(tmp_path / "o")])
    assert code == 0
    summary = json.loads((tmp_path / "o" / "summary.json").read_text(encoding="utf-8"))
    assert summary["decision"] == "coulomb_friction"
    fitted = np.array(summary["per_record"]["valve.bias_current"]) - rig.params.valve__bias_current
    assert fitted == pytest.approx(DRIFT, abs=2e-5)
    assert "2 records calibrated together" in (tmp_path / "o" / "report.md").read_text(
        encoding="utf-8"
    )
    assert main([*args, "--per-record", "valve.closing_current", "--out", str(tmp_path / "p")]) == 2
