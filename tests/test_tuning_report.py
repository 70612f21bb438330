"""The files a finished study leaves: best controller, summary, figures, report.

Studies are kept short (≤ 30 trials, one worker) and run once per module.
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from support import DATA

from fuzzyservo.io.controllers import load_controller, write_controller_file
from fuzzyservo.io.studies import load_study
from fuzzyservo.tuning.objective import build_evaluator
from fuzzyservo.tuning.runner import run_study
from fuzzyservo.workflows import write_study_report

SUMMARY_KEYS = {
    "study", "trials", "objective", "best", "baseline", "pareto", "importances", "storage",
    "wall_s", "sim_time_s", "time_split_s", "units", "trials_asked", "trials_pruned",
    "trials_failed",
}  # fmt: skip
BEST_KEYS = {"params", "objective", "metrics", "scenarios", "status", "feasible"}
BASELINE_KEYS = {"controller", "objective", "metrics", "scenarios"}


def _run(study: Path, out: Path, trials: int):
    outcome = run_study(load_study(study), out, trials=trials, workers=1, progress=False)
    return outcome, write_study_report(outcome, out)[1]


@pytest.fixture(scope="module")
def fuzzy_study(tmp_path_factory):
    out = tmp_path_factory.mktemp("dinca_flc")
    return (*_run(DATA / "studies" / "dinca_flc.yaml", out, trials=20), out)


@pytest.fixture(scope="module")
def pareto_study(tmp_path_factory):
    folder = tmp_path_factory.mktemp("pareto")
    template = DATA / "studies" / "controllers" / "flc2_reshaped.yaml"
    study = folder / "pareto_small.yaml"
    study.write_text(
        f"""name: pareto_small
rig: dinca_cylinder
scenarios: [pulses]
controller: {template.as_posix()}
baseline: p_k10
parameters:
  input.reshape: {{low: 0.5, high: 4.0, log: true}}
  output.translate: {{low: 0.0, high: 0.5}}
  gains.output: {{low: 0.5, high: 1.5}}
objective: {{pareto: [settling_time_s, saturation_time_s, sse_abs]}}
sampler: nsga2
seed: 3
""",
        encoding="utf-8",
    )
    return (*_run(study, folder / "out", trials=24), folder / "out")


def test_fuzzy_study_writes_every_file(fuzzy_study):
    outcome, paths, out = fuzzy_study
    expected = {
        "best_controller.yaml", "best_controller.fis", "summary.json", "report.md",
        "history.png", "curve.png", "membership_before.png", "membership_after.png",
        "response_pulses.png", "response_steps.png",
    }  # fmt: skip
    if outcome.importances:
        expected.add("importances.png")
    assert expected <= {p.name for p in out.iterdir()}
    assert all(p.is_file() and p.stat().st_size > 0 for p in paths.values())
    assert {"report", "summary", "controller", "fis"} <= set(paths)
    assert "pareto" not in paths  # one objective: no front


def test_summary_has_the_documented_keys(fuzzy_study):
    outcome, paths, _ = fuzzy_study
    summary = json.loads(paths["summary"].read_text(encoding="utf-8"))
    assert SUMMARY_KEYS <= set(summary)
    assert BEST_KEYS <= set(summary["best"])
    assert BASELINE_KEYS <= set(summary["baseline"])
    assert summary["study"] == "dinca_flc"
    assert summary["trials"] == outcome.trials_complete == 20
    assert summary["best"]["objective"] == outcome.best.values[0]
    assert summary["best"]["params"] == outcome.best_params
    assert set(summary["best"]["scenarios"]) == {"pulses", "steps"}
    assert summary["baseline"]["controller"] == "p_k10"
    assert summary["pareto"] == []
    assert summary["storage"] == outcome.storage_url
    assert summary["time_split_s"]["sampler"] >= 0 and "sampler_time_s" not in summary
    assert summary["units"]["sse_abs"] == "m"  # SI, the unit named beside the numbers
    assert summary["trials_asked"] >= summary["trials"] + summary["trials_pruned"]


def test_best_controller_file_reproduces_the_objective(fuzzy_study):
    outcome, paths, _ = fuzzy_study
    controller = load_controller(paths["controller"])
    assert controller.name == "dinca_flc_best"
    assert "dinca_flc" in controller.description
    evaluation = build_evaluator(outcome.spec).evaluate(controller)
    assert evaluation.values == outcome.best.values  # exactly: the file holds every digit
    assert load_controller(paths["fis"]).system.inputs[0].name == "e"


def test_the_report_object_is_what_the_files_say(fuzzy_study):
    """Issue 38: tuning computes its report (tuning.report), io only writes it:
    ``to_dict()`` is summary.json as written, and the report holds the best controller
    as its file does, scored again."""
    import json

    from fuzzyservo.results import json_ready
    from fuzzyservo.tuning.report import study_report

    outcome, paths, _ = fuzzy_study
    report = study_report(outcome, load_controller(paths["controller"]), check_samples=0)
    written = json.loads(paths["summary"].read_text(encoding="utf-8"))
    assert json_ready(report.to_dict()) == written
    assert report.reproduces and report.trial == written["best"]["trial"]
    assert report.text().startswith("trials: ") and "objective: best" in report.text()
    # what tune returns is a result too: its numbers are summary.json's, its text the start
    outcome_dict = json_ready(outcome.to_dict())
    assert {k: written[k] for k in outcome_dict} == outcome_dict
    assert str(outcome) == report.text()  # a study without uncertainty: nothing to add
    with pytest.raises(dataclasses.FrozenInstanceError):
        outcome.wall_s = 0.0


def test_report_links_resolve_and_state_the_reproduction(fuzzy_study):
    outcome, paths, out = fuzzy_study
    text = paths["report"].read_text(encoding="utf-8")
    links = re.findall(r"\]\(([^)]+)\)", text)
    assert {"history.png", "curve.png", "best_controller.yaml", "summary.json"} <= set(links)
    for link in links:
        assert not Path(link).is_absolute()
        assert (out / link).is_file(), link
    assert "reproduces the objective" in text
    assert f"optuna-dashboard {outcome.storage_url}" in text
    assert "overshoot_pct <= 5" in text


def test_pareto_study_writes_the_front(pareto_study):
    outcome, paths, out = pareto_study
    assert (out / "pareto.png").is_file()
    assert paths["pareto"] == out / "pareto.png"
    summary = json.loads(paths["summary"].read_text(encoding="utf-8"))
    assert summary["pareto"]
    assert {"number", "values", "params"} <= set(summary["pareto"][0])
    assert all(len(p["values"]) == 3 for p in summary["pareto"])
    assert summary["best"]["objective"] == list(outcome.best.values)
    assert summary["best"]["trial"] in {p["number"] for p in summary["pareto"]}
    text = paths["report"].read_text(encoding="utf-8")
    assert "## Pareto front" in text and "](pareto.png)" in text
    controller = load_controller(paths["controller"])
    assert build_evaluator(outcome.spec).evaluate(controller).values == outcome.best.values


def test_non_fuzzy_template_writes_no_fuzzy_files(tmp_path):
    study = tmp_path / "p_gain.yaml"
    study.write_text(
        "name: p_gain\nrig: dinca_cylinder\nscenarios: [steps]\n"
        f"controller: {(DATA / 'studies' / 'controllers' / 'p_k10.yaml').as_posix()}\n"
        "parameters:\n  gain: {low: 2, high: 20, log: true}\n"
        "objective: {metric: itae}\nsampler: random\nseed: 0\n",
        encoding="utf-8",
    )
    outcome, paths = _run(study, tmp_path / "out", trials=5)
    assert not {"fis", "curve", "membership_before", "membership_after"} & set(paths)
    controller = load_controller(paths["controller"])
    assert controller.gain == outcome.best_params["gain"]
    assert build_evaluator(outcome.spec).evaluate(controller).values == outcome.best.values


def test_summary_writes_nan_as_null(fuzzy_study):
    _, paths, _ = fuzzy_study
    text = paths["summary"].read_text(encoding="utf-8")
    assert "NaN" not in text and "Infinity" not in text


def test_controller_file_writer_round_trips_numpy_numbers(tmp_path):
    data = {
        "name": "k", "kind": "PI", "kp": np.float64(0.1) + np.float64(0.2),
        "ki": np.float32(0.5), "output_limits": (np.int64(-3), 3.0),
    }  # fmt: skip
    path = write_controller_file(data, tmp_path / "sub" / "k.yaml")
    text = path.read_text(encoding="utf-8")
    assert "!!" not in text  # no python/numpy tags: any YAML reader takes it
    controller = load_controller(path)
    assert controller.kp == 0.1 + 0.2  # repr round-trips every digit
    assert (controller.u_min, controller.u_max) == (-3.0, 3.0)


def test_controller_file_writer_rejects_non_finite_numbers(tmp_path):
    with pytest.raises(ValueError, match=r"gains\.output.*finite"):
        write_controller_file({"kind": "fuzzy", "gains": {"output": math.nan}}, tmp_path / "x.yaml")


def test_report_module_does_not_import_matplotlib():
    code = "import sys, fuzzyservo.io.study_report; print('matplotlib' in sys.modules)"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "False"


def test_history_figure_uses_log_axis_beyond_two_decades():
    from fuzzyservo.plots import history_figure

    def trial(n, v, status="ok", feasible=True):
        return {"number": n, "values": [v], "status": status, "feasible": feasible}

    wide = [trial(0, 1.0), trial(1, 500.0), trial(2, 1e6, "diverged", False)]
    narrow = [trial(0, 1.0), trial(1, 50.0), trial(2, 1e6, "diverged", False)]
    assert history_figure(wide, ["objective"]).axes[0].get_yscale() == "log"
    ax = history_figure(narrow, ["objective"]).axes[0]
    # the penalty (1e6) is marked at the top edge, not plotted at its value
    assert ax.get_yscale() == "linear" and ax.get_ylim()[1] < 100
    with pytest.raises(ValueError, match="one name per value"):
        history_figure(wide, ["a", "b"])
