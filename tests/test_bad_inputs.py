"""Every bad input of the audit table (tests/bad_inputs.py) gives one clear line and exit
status 2, writes nothing outside the working folder; plus the hardening that is not a
single bad input: streaming CSV memory, progress lines off a terminal, metrics that do not
apply, the shipped network file."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from bad_inputs import CASES, run_inprocess

from fuzzyservo.cli import main


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_bad_input_is_one_clear_line(case, tmp_path):
    outcome = run_inprocess(case, tmp_path)
    assert outcome.verdict(case, tmp_path) == "clear", (
        outcome.code,
        outcome.stderr,
        outcome.outside,
    )


def test_audit_table_is_large_enough():
    assert len(CASES) >= 120
    assert len({c.id for c in CASES}) == len(CASES)


@pytest.mark.slow
def test_a_135_mb_csv_is_read_in_little_memory(tmp_path):
    """A 135 MB CSV with a bad cell in its last row: the error comes after streaming the
    file, with the values held as floats (not 1.9 GB of text cells)."""
    path = tmp_path / "big.csv"
    row = "{t:.6f},{v:.9f},{v:.9f},{v:.9f},{v:.9f},{v:.9f}\n"
    with path.open("w") as fh:
        fh.write("t_s,i_mA,y_cm,p1_bar,p2_bar,p3_bar\n")
        n = 0
        while fh.tell() < 135e6:
            fh.writelines(row.format(t=k * 1e-3, v=0.5) for k in range(n, n + 50_000))
            n += 50_000
        fh.write(f"{n * 1e-3:.6f},0.5,x,0.5,0.5,0.5\n")
    script = textwrap.dedent(
        f"""
        import sys
        from fuzzyservo.errors import DataError
        from fuzzyservo.io.measured import read_measured
        try:
            read_measured({str(path)!r})
        except DataError as exc:
            print(str(exc))
        # VmHWM: this process's own peak (ru_maxrss would keep the forking pytest
        # process's size across exec on Linux)
        status = open("/proc/self/status").read().split("VmHWM:")[1]
        print(int(status.split()[0]))
        """
    )
    out = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, check=True
    ).stdout.splitlines()
    assert "'x'" in out[0] and "y_cm" in out[0] and "is not a number" in out[0]
    peak_mb = int(out[-1]) / 1024
    # 8.6 M values are 69 MB as floats; the interpreter with numpy about 40 MB
    assert peak_mb < 400, f"peak resident memory {peak_mb:.0f} MB"


def test_progress_lines_when_not_on_a_terminal(tmp_path, capsys):
    code = main(["bench", "--case", "ehs160_steps_p", "--runs", "1", "--reference-runs", "1"])
    assert code == 0
    err = capsys.readouterr().err
    assert "ehs160_steps_p: 1/1" in err


def test_fit_valve_progress_and_the_shipped_file_kept(tmp_path, capsys, monkeypatch):
    from bad_inputs import valve_csv
    from support import shipped

    network = shipped("hydroprax_pdcv").parent / "hydroprax_nn_valve.json"
    before = network.read_bytes()
    data = tmp_path / "v.csv"
    valve_csv()(data)
    monkeypatch.chdir(tmp_path)
    assert main(["fit-valve", str(data), "--restarts", "2"]) == 0
    captured = capsys.readouterr()
    assert "restarts: 1/2" in captured.err and "restarts: 2/2" in captured.err
    assert (tmp_path / "out" / "valve_network.json").is_file()  # no --rig: a file of its own
    assert network.read_bytes() == before


def test_calibrate_progress_lines(tmp_path, capsys):
    from bad_inputs import measured

    data = tmp_path / "d.csv"
    measured()(data)
    code = main(
        [
            "calibrate",
            "dinca_cylinder",
            str(data),
            "--effects",
            "valve_bias",
            "--max-effects",
            "1",
            "--bootstrap-draws",
            "30",
            "--out",
            str(tmp_path / "c"),
        ]
    )
    assert code == 0
    assert "candidates: 1/1 valve_bias" in capsys.readouterr().err
    summary = json.loads((tmp_path / "c" / "summary.json").read_text())
    assert summary["rounds"][0]["null"]["draws"] == 30  # --bootstrap-draws reaches the null


def test_heave_shows_only_metrics_that_apply(tmp_path, capsys):
    code = main(
        [
            "simulate",
            "ahc_motor",
            "p_ahc_motor",
            "--scenario",
            "heave",
            "--duration",
            "20",
            "--out",
            str(tmp_path),
        ]
    )
    assert code == 0
    out = capsys.readouterr().out
    table = out.split("not shown:")[0]
    for name in ("sse_pct", "itae", "overshoot_pct", "rise_time_s"):
        assert name not in table
    for name in ("iae", "saturation_time_s", "peak_command"):
        assert name in table
    assert "not shown: rise_time_s" in out


def test_steps_show_every_metric(tmp_path, capsys):
    from fuzzyservo.metrics import METRIC_NAMES

    code = main(
        ["simulate", "dinca_cylinder", "p_k10", "--scenario", "steps", "--out", str(tmp_path)]
    )
    assert code == 0
    out = capsys.readouterr().out
    assert all(name in out for name in METRIC_NAMES) and "not shown" not in out


def test_duplicate_key_message_names_both_lines(tmp_path):
    from fuzzyservo.errors import ConfigError
    from fuzzyservo.io._yaml import read_yaml

    path = tmp_path / "x.yaml"
    path.write_text("a: 1\nb:\n  c: 1\n  c: 2\n")
    with pytest.raises(ConfigError, match=r"c: given twice \(lines 3 and 4\)"):
        read_yaml(path)
    path.write_text("a: &x {c: 1}\nb:\n  <<: *x\n  d: 2\n")  # merge keys stay allowed
    assert read_yaml(path)["b"] == {"c": 1, "d": 2}


def test_a_valid_file_named_like_a_path_is_still_found(tmp_path):
    """Names are refused, paths are not: a rig file in a sub-folder loads by its path."""
    from support import shipped

    sub = tmp_path / "my rigs"
    sub.mkdir()
    target = sub / "dinca.yaml"
    target.write_text(shipped("dinca_cylinder").read_text())
    from fuzzyservo.io.rigs import load_rig

    assert load_rig(Path(target)).name == "dinca_cylinder"
