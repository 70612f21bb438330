"""Measured channels of outside rigs: scale, offset and tare per column, DAQ text layouts
(preamble lines, no header, text columns), a recorded load force driving the replay and
a force compared as an output channel; each bad input one line naming file and key."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from support import rig_named, shipped

from fuzzyservo.calibration.candidates import fit_table
from fuzzyservo.calibration.replay import make_replay
from fuzzyservo.calibration.synthetic import synthetic_run
from fuzzyservo.cli import main
from fuzzyservo.controllers.classical import P
from fuzzyservo.errors import ConfigError, DataError
from fuzzyservo.io.measured import ColumnScaling, Measured, read_measured, read_rig_data
from fuzzyservo.io.rigs import load_rig

DAQ = """DAQ export, bench 3
operator: test
date,time_s,pos_V,F_tf
2026-01-05 10:00:00,0.00,1.00,0.101
2026-01-05 10:00:00,0.01,1.10,0.099
"""

MEASURED = """
measured:
  skip_lines: 2
  drop: [date]
  columns:
    time_s: t_s
    pos_V: {as: y_mm, from: V, scale: {value: 20, unit: mm/V}, offset: {value: -1, unit: cm}}
    F_tf: {as: load_N, from: tf, tare: 2}
"""


def _daq(path: Path, rows: int = 30) -> Path:
    lines = DAQ.splitlines()[:3]
    for k in range(rows):
        lines.append(f"2026-01-05 10:00:{k:02d},{0.01 * k:.2f},{1.0 + 0.1 * k:.2f},{0.1 + k:.3f}")
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def _rig_with(tmp_path: Path, measured: str) -> Path:
    text = shipped("servo_lift").read_text(encoding="utf-8")
    rig = tmp_path / "rig.yaml"
    rig.write_text(text + measured, encoding="utf-8")
    return rig


def test_daq_file_scaled_through_the_rig_files_measured_section(tmp_path):
    rig = load_rig(_rig_with(tmp_path, MEASURED))
    data = read_rig_data(_daq(tmp_path / "daq.csv"), rig.measured)
    assert set(data.signals) == {"y", "load"}
    k = np.arange(30)
    # 20 mm/V · V − 10 mm, in m
    np.testing.assert_allclose(data.signals["y"], (20 * (1.0 + 0.1 * k) - 10) * 1e-3, rtol=1e-12)
    # tonne-force to N, zeroed on the mean of the first two samples
    load = 9806.65 * (0.1 + k)
    np.testing.assert_allclose(data.signals["load"], load - load[:2].mean(), rtol=1e-12)
    assert data.sample_period_s == pytest.approx(0.01)


def test_header_less_file_takes_its_names_from_the_rig_file(tmp_path):
    path = tmp_path / "h.csv"
    path.write_text("\n".join(f"{0.02 * k:.2f},1,{0.5 + 0.01 * k:.3f}" for k in range(25)) + "\n")
    data = read_measured(
        path,
        names=("t", "r", "y"),
        mapping={"t": "t_s", "r": "ref_V", "y": "y_mm"},
        scaling={"y": ColumnScaling(scale=20.0)},
    )
    np.testing.assert_allclose(data.signals["y"][:2], [0.01, 0.0102], rtol=1e-12)
    assert len(data) == 25


@pytest.mark.parametrize(
    ("measured", "key", "says"),
    [
        ("    pos_V: {as: y_mm, from: V, scale: {value: 20, unit: bar/V}}", "scale.unit", "mm/V"),
        ("    pos_V: {as: y_mm, from: V}", "from", "give a scale"),
        ("    pos_V: {as: mm, scale: 2}", "as", "<signal>_<unit>"),
        ("    pos_V: {as: y_mm, tare: 1.5}", "tare", "whole number"),
        ("    pos_V: {as: y_mm, gain: 2}", "gain", "unknown key"),
        ("    pos_V: {as: y_mm, from: volt}", "from", "volt"),
    ],
)
def test_bad_column_scaling_names_the_key(tmp_path, measured, key, says):
    text = "\nmeasured:\n  columns:\n" + measured + "\n"
    with pytest.raises(ConfigError) as err:
        load_rig(_rig_with(tmp_path, text))
    message = str(err.value)
    assert "rig.yaml" in message and key in message and says in message


@pytest.mark.parametrize(
    ("edit", "says"),
    [
        ({"drop": ("when",)}, "drop names column 'when'"),
        ({"drop": ()}, "measured: drop: [date]"),
        ({"scaling": {"speed": ColumnScaling()}}, "scales column 'speed'"),
        ({"scaling": {"pos_V": ColumnScaling(tare_samples=99)}}, "at most 30"),
        ({"names": ("t_s", "b_V"), "drop": (), "mapping": {}}, "measured: names gives 2"),
        ({"skip_lines": 0}, "skip them with measured: skip_lines"),
    ],
)
def test_bad_daq_layouts_are_one_line(tmp_path, edit, says):
    path = _daq(tmp_path / "daq.csv")
    kwargs = {
        "skip_lines": 2,
        "drop": ("date",),
        "mapping": {"time_s": "t_s", "pos_V": "y_V", "F_tf": "load_1"},
    }
    kwargs.update(edit)
    with pytest.raises(DataError) as err:
        read_measured(path, **kwargs)
    message = str(err.value)
    assert "daq.csv" in message and says in message and "\n" not in message


def test_cli_reports_a_bad_scale_in_one_line(tmp_path, capsys):
    text = "\nmeasured:\n  columns:\n    pos_V: {as: y_mm, from: V, scale: 0}\n"
    rig = _rig_with(tmp_path, text)
    code = main(
        ["calibrate", str(rig), str(_daq(tmp_path / "d.csv")), "--out", str(tmp_path / "o")]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    assert "rig.yaml" in err[0] and "scale" in err[0]


def test_a_recorded_load_drives_the_replay_and_force_is_compared():
    """servo_lift holding 150 mm under P 4 V/V while 500 N pushes down for a second
    (`disturbed`): replayed with the recorded load the model gives the record back (fit
    of position and load-cell force near 100 %); without it the dip is missing."""
    rig = rig_named("servo_lift")
    controller = P(gain=4.0, u_min=-10, u_max=10)
    run = synthetic_run(rig, controller, "disturbed", {}, {"y": 1e-6, "f_loads": 0.5})
    t = np.asarray(run.t)
    load = np.where((t >= 0.5) & (t < 1.5), 500.0, 0.0)
    signals = {k: v for k, v in run.signals.items() if k != "f_loads"}
    signals.update(force=run.signals["f_loads"], load=load)
    units = {k: v for k, v in run.units.items() if k != "f_loads"}
    units.update(force="N", load="N")
    data = Measured(t=t, signals=signals, units=units, source="disturbed", sample_period_s=0.001)
    replay = make_replay(rig, data, controller)
    assert replay.channels == {"y": "y", "force": "f_loads"}
    model, status = replay.run(rig)
    assert status == "ok"
    fits = fit_table(replay, model)
    assert fits["y"] > 95 and fits["force"] > 95
    without = {k: v for k, v in signals.items() if k != "load"}
    data_without = Measured(
        t=t,
        signals=without,
        units={k: units[k] for k in without},
        source="no load",
        sample_period_s=0.001,
    )
    replay_without = make_replay(rig, data_without, controller)
    model_without, _ = replay_without.run(rig)
    fit_without = fit_table(replay, model_without)["y"]
    assert fit_without < fits["y"] - 20


def test_a_load_in_the_wrong_unit_is_refused():
    rig = rig_named("servo_lift")
    t = np.arange(50) * 0.001
    data = Measured(
        t=t,
        signals={"ref": np.full(50, 0.15), "y": 0.15 + 1e-4 * np.sin(t), "load": np.zeros(50)},
        units={"ref": "m", "y": "m", "load": "Pa"},
        source="d.csv",
        sample_period_s=0.001,
    )
    with pytest.raises(DataError, match=r"column 'load' is in Pa.*load_N"):
        make_replay(rig, data, P(gain=4.0))


def test_a_synthetic_record_with_the_noise_in_the_loop_logs_what_the_controller_read():
    """``in_loop``: the feedback sensor's declared noise (1 mV, about 52 µm on the seed-002
    rig) is in the loop, so the current answers it, and the recorded position is the
    reading the controller had: on the 16-bit converter's steps (0.31 mV, 16 µm)."""
    rig = rig_named("dinca_cylinder")
    controller = P(gain=10.0, u_min=-10, u_max=10)
    clean = synthetic_run(rig, controller, "pulses", {}, {"y": 5e-6}, seed=1, duration_s=1.0)
    noisy = synthetic_run(rig, controller, "pulses", {}, {"y": 5e-6}, seed=1, duration_s=1.0,
                          in_loop=True)  # fmt: skip
    y = np.asarray(noisy.signals["y"])
    step = 20.0 / 2**16 / 0.1936 * 1e-2  # the converter's step in metres
    assert np.allclose((y - y[0]) / step, np.round((y - y[0]) / step), atol=1e-6)
    assert 30e-6 < np.std(y - clean.signals["y"]) < 80e-6
    assert not np.allclose(noisy.signals["i"], clean.signals["i"])
