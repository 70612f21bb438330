"""The command line: compare, simulate, bench; outputs and their formats."""

from __future__ import annotations

import json
import subprocess
import sys

from fuzzyservo.cli import main
from fuzzyservo.metrics import METRIC_NAMES


def test_compare_writes_table_plots_json(tmp_path, capsys):
    out = tmp_path / "out"
    code = main(
        ["compare", "dinca_cylinder", "p_k10", "--scenario", "pulses",
         "--out", str(out), "--json", str(tmp_path / "out.json")]
    )  # fmt: skip
    assert code == 0
    printed = capsys.readouterr().out
    for name in METRIC_NAMES:
        assert name in printed
    payload = json.loads((tmp_path / "out.json").read_text())
    assert payload["rig"] == "dinca_cylinder" and payload["scenario"] == "pulses"
    (run,) = payload["runs"]
    assert run["controller"] == "p_k10" and run["status"] == "ok"
    assert set(METRIC_NAMES) <= set(run["metrics"])
    assert len(run["steps"]) == 4
    assert (out / "dinca_cylinder_pulses_p_k10_response.png").stat().st_size > 10_000
    header = (out / "dinca_cylinder_pulses_p_k10.csv").read_text().splitlines()[0]
    assert header.startswith("t_s,ref_V") and "p_a_Pa" in header


def test_compare_defaults_to_the_seed002_baseline(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)  # names resolve in the checkout when not found here
    assert main(["compare", "--out", str(tmp_path / "o")]) == 0
    assert "p_k10" in capsys.readouterr().out


def test_simulate_by_name_on_the_motor(tmp_path, capsys):
    code = main(
        ["simulate", "ehs160_motor", "p_kb0105", "--scenario", "brake", "--out", str(tmp_path)]
    )
    assert code == 0
    assert (tmp_path / "ehs160_motor_brake_p_kb0105_response.png").exists()


def test_bench_json(tmp_path):
    path = tmp_path / "bench.json"
    code = main(
        [
            "bench",
            "--case",
            "ehs160_steps_p",
            "--runs",
            "1",
            "--reference-runs",
            "1",
            "--json",
            str(path),
        ]
    )
    assert code == 0
    (case,) = json.loads(path.read_text())["cases"]
    assert case["name"] == "ehs160_steps_p"
    assert {"median_s", "reference_s", "ratio", "error"} <= set(case)
    assert case["error"]["pressure_bar"] < 0.5  # accuracy, not speed, is what a test may check


def test_module_entry_point():
    done = subprocess.run(
        [sys.executable, "-m", "fuzzyservo", "--help"], capture_output=True, text=True
    )
    assert done.returncode == 0 and "compare" in done.stdout


def test_show_writes_figures_and_describes_rules(tmp_path, capsys):
    assert main(["show", "flc2_reshaped", "--out", str(tmp_path)]) == 0
    printed = capsys.readouterr().out
    assert "4. if e is Z then u is Z" in printed and "trapmf" in printed
    for kind in ("overview", "membership", "curve"):
        assert (tmp_path / f"flc2_reshaped_{kind}.png").stat().st_size > 10_000


def test_export_then_compare_the_fis(tmp_path, capsys):
    fis = tmp_path / "flc1.fis"
    assert main(["export", "flc1_translated", "--fis", str(fis)]) == 0
    assert fis.read_text().startswith("[System]")
    code = main(["compare", "dinca_cylinder", "flc1_translated", str(fis), "--scenario", "steps",
                 "--out", str(tmp_path), "--json", str(tmp_path / "r.json")])  # fmt: skip
    assert code == 0
    runs = json.loads((tmp_path / "r.json").read_text())["runs"]
    assert runs[0]["metrics"] == runs[1]["metrics"]  # same controller, through the .fis


def test_show_rejects_a_classical_controller(capsys):
    assert main(["show", "p_k10"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not a fuzzy one" in err[0]


def test_bench_robust_study_row_shows_the_split_and_skipped_samples():
    """The robust study's row: simulations per second, where the wall time went against
    the simulation limit, and the sampled plants its pruned trials skipped (figures as
    run_study_case reports them)."""
    from fuzzyservo.bench import ROBUST_STUDY, BenchReport, BenchResult

    extra = {"trials": 301, "workers": 2, "trials_pruned": 280, "samples_skipped": 1950,
             "trials_per_s": 25.0, "simulations": 560, "simulations_per_s": 46.7,
             "simulation_s": 8.1, "sampler_s": 4.0, "storage_s": 6.5, "building_s": 1.1,
             "limit_s": 4.05, "of_limit": 2.96, "startup_s": 2.5, "trials_s": 8.0,
             "finish_s": 1.5, "idle_s": 7.9, "parent_wait_s": 3.0}  # fmt: skip
    row = BenchResult.once(ROBUST_STUDY, "robust", 12.0, extra=extra)
    text = BenchReport((row,)).text()
    assert "280 pruned, 1950 sampled plants skipped" in text and "47 simulations/s" in text
    assert (
        "startup 2.5 s + trials 8.0 s (workers idle 7.9 s in all; the parent waited 3.0 s" in text
    )
    assert "at least 4.0 s: 2.96× that" in text
    assert "sampler 4.0 s, storage 6.5 s, building 1.10 s" in text
