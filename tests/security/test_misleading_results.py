"""No plausible-looking nonsense (issue 36, item 5): a piston that does not move has no
rise time or overshoot, a run that hits an end stop says when, and a held-out part that
does not move gets no fit percentage.

The cases replay what a probe of the command line found: a 1e300 kg piston drifting
4e-15 m reported a rise time and an overshoot of that drift; a record whose held-out
part was constant reported "held-out fit -9.8e17 %" with every score inf, exit 0.
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from support import DATA, controller_named, ideal_sensor, rig_named

import fuzzyservo
from fuzzyservo.calibration import prepare
from fuzzyservo.calibration.candidates import fit_table
from fuzzyservo.calibration.synthetic import synthetic_run
from fuzzyservo.cli import main
from fuzzyservo.io.measured import read_rig_data, write_measured
from fuzzyservo.io.rigs import load_rig
from fuzzyservo.metrics import NOT_MOVED, result_metrics, step_metrics

# a step of the shipped `steps` scenario and one second after it (warm-up 2 s)
SHORT = ["--scenario", "steps", "--duration", "3"]
# a number no fit percentage or score can honestly be: 1e10 and beyond
HUGE = re.compile(r"\d[eE]\+?(1\d|[2-9]\d|\d{3})\b|\binf\b")


def _dinca(tmp_path: Path, name: str, edit) -> Path:
    """The shipped seed-002 rig file with ``edit(data)`` applied, written to ``tmp_path``."""
    data = yaml.safe_load((DATA / "rigs" / "dinca_cylinder.yaml").read_text(encoding="utf-8"))
    edit(data)
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


def _heavy(data: dict) -> None:
    data["plant"]["components"]["cylinder"]["parameters"]["piston_mass"]["value"] = 1e300


def _into_stop(data: dict) -> None:
    """A step to 9.5 V: 19.4 cm on the transducer, past the 14.3 cm end of the stroke."""
    data["scenarios"]["into_stop"] = {
        "description": "a step past the end of the stroke",
        "duration": {"value": 3, "unit": "s"},
        "warmup": {"value": 1, "unit": "s"},
        "reference": {"type": "steps", "unit": "V", "initial": 6.2, "times_s": [1],
                      "values": [9.5]},
    }  # fmt: skip


# --------------------------------------------------------------------- did not move


def test_a_piston_that_does_not_move_has_no_rise_time_or_overshoot(tmp_path, capsys):
    rig = _dinca(tmp_path, "heavy", _heavy)
    out = tmp_path / "run.json"
    code = main(["compare", str(rig), *SHORT, "--out", str(tmp_path / "out"), "--json", str(out)])
    printed = capsys.readouterr().out
    assert code == 0
    rows = {line.split()[0]: line.split()[-1] for line in printed.splitlines() if "[" in line}
    for metric in NOT_MOVED:
        assert rows[metric] == "n/a", printed
    note = next(line for line in printed.splitlines() if "did not move" in line)
    # e.g. "p_k10: did not move (4.2 fm peak to peak, below the 15.8 µm resolution: the
    # feedback ADC's step, 16 bits over -10..10 V); ..."
    assert note.startswith("p_k10: did not move (") and "15.8 µm resolution" in note
    assert "ADC" in note
    run = json.loads(out.read_text())["runs"][0]
    assert run["moved"] is False and run["not_moved"] == note.removeprefix("p_k10: ")
    assert run["motion"] < 1e-12 and run["resolution"] == pytest.approx(20 / 2**16 / 19.36)
    assert all(run["metrics"][m] is None for m in NOT_MOVED)
    assert run["metrics"]["sse_abs"] > 0.02  # the error stays: 2.5 cm asked, nothing done


def test_the_api_says_so_too_and_a_rig_without_a_sensor_resolution_falls_back():
    rig = fuzzyservo.load_rig("dinca_cylinder")
    heavy = rig.with_params(cylinder__piston_mass=1e300)
    p_k10 = controller_named("p_k10")
    result = fuzzyservo.compare(heavy, [p_k10], "steps", duration_s=3.0)
    assert not result.metrics["p_k10"].moved and "did not move" in result.text()
    # without an ADC or noise on the sensor: 0.01 % of the reference's range, said so
    bare = ideal_sensor(heavy)
    metrics = fuzzyservo.compare(bare, [p_k10], "steps", duration_s=3.0).metrics["p_k10"]
    assert not metrics.moved and "declares no ADC or noise" in metrics.resolution_source
    assert metrics.resolution == pytest.approx(1e-4 * 2.5e-2)  # the 2.5 cm step


def test_a_normal_run_is_scored_exactly_as_before():
    """The motion check changes no number of a run that moves: the same metrics as
    with a resolution nothing falls below."""
    result = fuzzyservo.simulate(rig_named("dinca_cylinder"), controller_named("p_k10"), "steps")
    metrics = result_metrics(result)
    assert metrics.moved and metrics.motion > 1e3 * metrics.resolution
    plain = step_metrics(result.t, result.reference_output, result.output, result.command,
                         result.saturated, warmup_s=result.warmup_s, resolution=1e-300)  # fmt: skip
    assert metrics.steps == plain.steps
    assert all(np.isfinite(metrics.aggregate[m]) for m in NOT_MOVED)


def test_step_metrics_on_arrays_judge_motion_against_the_resolution():
    t = np.arange(0.0, 2.0, 0.01)
    r = np.where(t >= 1.0, 1.0, 0.0)
    drift = 1e-9 * np.clip(t - 1.0, 0.0, None)  # a 1 nm creep after a 1 m step
    still = step_metrics(t, r, drift, resolution=1e-6, resolution_source="a 1 µm encoder")
    assert not still.moved and math.isnan(still.aggregate["overshoot_pct"])
    assert still.aggregate["sse_abs"] == pytest.approx(1.0, rel=1e-6)
    assert still.to_dict()["moved"] is False
    moved = step_metrics(t, r, drift, resolution=1e-12)
    assert moved.moved and math.isfinite(moved.aggregate["rise_time_s"])


# --------------------------------------------------------------------- end stop


def test_a_run_into_the_end_stop_says_when(tmp_path, capsys):
    rig = _dinca(tmp_path, "stop", _into_stop)
    out = tmp_path / "run.json"
    code = main(["compare", str(rig), "--scenario", "into_stop", "--out", str(tmp_path / "out"),
                 "--json", str(out)])  # fmt: skip
    captured = capsys.readouterr()
    assert code == 0
    lines = [line for line in captured.err.splitlines() if "end stop" in line]
    assert len(lines) == 1, captured.err
    found = re.search(r"hit the end stop at t = ([\d.]+) s", lines[0])
    assert found, lines[0]
    run = json.loads(out.read_text())["runs"][0]
    assert run["status"] == "end_stop" and "hit the end stop" in run["message"]
    assert run["end_stop_s"] == pytest.approx(float(found.group(1)), abs=1e-3)
    assert 1.0 < run["end_stop_s"] < 3.0  # after the step at 1 s


def test_a_run_inside_the_stroke_has_no_end_stop():
    result = fuzzyservo.simulate(rig_named("dinca_cylinder"), controller_named("p_k10"), "steps")
    assert result.status == "ok" and result.end_stop_s is None


# --------------------------------------------------------------------- held-out part


def _record(path: Path, *, pressure_moves: bool) -> Path:
    """A 2 s record at 100 Hz: the valve current on for the first second, the position
    ramping 3 mm and then constant to the end (the held-out part, the last 30 %, does
    not move); ``pressure_moves`` adds a chamber pressure that keeps moving."""
    header = ["t_s", "i_mA", "y_cm"] + (["p_a_bar"] if pressure_moves else [])
    rows = [",".join(header)]
    for k in range(200):
        row = [f"{0.01 * k:.2f}", "2.0" if k < 100 else "0.0", f"{0.3 * min(k, 100) / 100:.6g}"]
        if pressure_moves:
            row.append(f"{35 + 5 * np.sin(0.05 * k):.6g}")
        rows.append(",".join(row))
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    return path


def test_a_held_out_part_that_does_not_move_is_refused(tmp_path, capsys):
    data = _record(tmp_path / "flat.csv", pressure_moves=False)
    code = main(["calibrate", "dinca_cylinder", str(data), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert "\n" not in err and err.startswith("fuzzyservo: error: ")
    assert str(data) in err and "held-out part" in err and "does not move" in err
    assert "y (0 mm peak to peak" in err and "give a record whose held-out part moves" in err
    assert not (tmp_path / "out").exists()  # refused before anything is written


def test_a_held_out_part_that_does_not_move_in_one_channel_has_no_fit_there(tmp_path):
    rig = rig_named("dinca_cylinder")
    data = read_rig_data(_record(tmp_path / "part.csv", pressure_moves=True), rig.measured)
    replay = prepare(rig, data).replay
    assert set(replay.still_channels()) == {"y"}
    model = {c: replay.measured(c) + 1e-3 * replay.sigma[c] for c in replay.channels}
    fit = fit_table(replay, model)
    assert math.isnan(fit["y"]) and 99 < fit["p_a"] <= 100


def _flat_tail(tmp_path: Path) -> tuple[Path, Path]:
    """A seed-002 P K=10 record (test_calibration's logger), 4 s of the `steps` scenario,
    whose position is constant from 2.75 s on, the pressures still moving; and the rig
    file it was taken on."""
    from test_calibration import HEADER_UNITS, NOISE, old_loop

    rig_file = old_loop(tmp_path)
    data = synthetic_run(load_rig(rig_file), controller_named("p_k10"), "steps", {}, NOISE,
                         seed=7, duration_s=4.0)  # fmt: skip
    y = data.signals["y"].copy()
    y[275:] = y[275]
    data = dataclasses.replace(data, signals={**data.signals, "y": y})
    return write_measured(tmp_path / "flat_y.csv", data, HEADER_UNITS), rig_file


def test_calibrate_prints_no_fit_for_a_channel_whose_held_out_part_is_constant(tmp_path, capsys):
    data, rig_file = _flat_tail(tmp_path)
    summary = tmp_path / "summary.json"
    code = main(["calibrate", str(rig_file), str(data), "--controller", "p_k10",
                 "--effects", "valve_bias", "--max-effects", "1", "--bootstrap-draws", "0",
                 "--out", str(tmp_path / "out"), "--json", str(summary)])  # fmt: skip
    printed = capsys.readouterr().out
    assert code == 0
    warning = next(line for line in printed.splitlines() if line.startswith("warning:"))
    assert str(data) in warning and "does not move in y (" in warning and "n/a" in warning
    fit_lines = next(x for x in printed.splitlines() if x.strip().startswith("held-out fit %"))
    assert re.search(r"\by n/a -> n/a(,|$)", fit_lines), fit_lines
    assert not HUGE.search(fit_lines), fit_lines  # no -9.8e17 %, no inf
    result = json.loads(summary.read_text())
    assert result["fit_before_pct"]["y"] is None and result["fit_after_pct"]["y"] is None
    assert all(v is not None for c, v in result["fit_before_pct"].items() if c != "y")
    report = (tmp_path / "out" / "report.md").read_text(encoding="utf-8")
    assert "does not move in y" in report and not HUGE.search(report.split("## Fit")[1][:2000])
