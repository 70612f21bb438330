"""Tuning studies: study files, parameter paths, the trial objective, and the results they must show."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml
from support import DATA, controller_named

from fuzzyservo.controllers.base import parameter_path
from fuzzyservo.errors import ConfigError
from fuzzyservo.io.studies import load_study
from fuzzyservo.metrics import result_metrics
from fuzzyservo.simulation import simulate
from fuzzyservo.tuning.objective import build_evaluator
from fuzzyservo.tuning.runner import run_study

STUDIES = DATA / "studies"


@pytest.mark.parametrize("name", ["dinca_flc", "dinca_pareto", "ehs160_flc", "dinca_pi"])
def test_shipped_studies_load(name):
    spec = load_study(STUDIES / f"{name}.yaml")
    assert spec.parameters and spec.trials >= 100


def _bad_study(tmp_path: Path, **changes) -> Path:
    data = yaml.safe_load((STUDIES / "dinca_flc.yaml").read_text())
    for key, value in changes.items():
        if value is None:
            data.pop(key, None)
        else:
            data[key] = value
    data["rig"] = str(DATA / "rigs" / "dinca_cylinder.yaml")
    data["controller"] = str(STUDIES / "controllers" / "flc2_reshaped.yaml")
    data["baseline"] = str(STUDIES / "controllers" / "p_k10.yaml")
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.mark.parametrize(
    ("changes", "key", "text"),
    [
        ({"trails": 10}, "trails", "did you mean 'trials'"),
        (
            {"parameters": {"input.reshap": {"low": 1, "high": 2}}},
            "parameters.input.reshap",
            "reshape",
        ),
        (
            {"parameters": {"input.reshape": {"low": 2, "high": 1}}},
            "parameters.input.reshape",
            "low < high",
        ),
        (
            {"parameters": {"input.increments[9]": {"low": 1, "high": 2}}},
            "parameters.input.increments[9]",
            "no searchable number",
        ),
        (
            {"parameters": {"kp": {"low": 1, "high": 2}}},
            "parameters.kp",
            "no searchable number 'kp'",
        ),
        ({"objective": {"metric": "speed"}}, "objective", "unknown metric 'speed'"),
        ({"objective": {"metric": "iae", "weights": {"iae": 1}}}, "objective", "exactly one"),
        ({"constraints": ["overshoot <= 5"]}, "constraints[0]", "unknown metric 'overshoot'"),
        ({"constraints": ["overshoot_pct < 5"]}, "constraints[0]", "cannot read constraint"),
        ({"scenarios": ["pulses", "nope"]}, "scenarios[1]", "unknown scenario 'nope'"),
        ({"sampler": "bayes"}, "sampler", "unknown sampler"),
        ({"trials": 0}, "trials", ">= 1"),
        ({"batch_size": 2.5}, "batch_size", "whole number of trials >= 1"),
    ],
)
def test_bad_study_files_name_file_key_and_fix(tmp_path, changes, key, text):
    path = _bad_study(tmp_path, **changes)
    with pytest.raises(ConfigError) as info:
        load_study(path)
    message = str(info.value)
    assert str(path) in message and key in message and text in message
    assert "\n" not in message


def test_cli_rejects_a_bad_study_with_exit_2(tmp_path, capsys):
    from fuzzyservo.cli import main

    path = _bad_study(tmp_path, sampler="bayes")
    assert main(["tune", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("fuzzyservo: error:")


def test_parameter_paths_are_parsed_in_one_place():
    """Warm start reads a controller file's numbers, and a design changes its own, by
    one parser of paths like ``input.increments[3]``."""

    assert parameter_path("input.increments[3]") == ("input", "increments", 3)
    with pytest.raises(ValueError, match="cannot read"):
        parameter_path("input..reshape")
    design = controller_named("flc2_reshaped").design
    changed = design.with_params(**{"input.increments[3]": 0.5, "output.reshape": 1.5})
    assert changed.params()["input.increments[3]"] == 0.5
    assert changed.params()["output.reshape"] == 1.5
    assert changed.params()["input.increments[2]"] == design.params()["input.increments[2]"]


def test_a_trial_changes_the_design_through_its_own_api():
    """A trial's numbers go through the template's ``with_params`` (no dict, no parse):
    the template is untouched, the new design holds exactly the numbers given."""
    from fuzzyservo.io.controllers import load_controller

    flc = load_controller(STUDIES / "controllers" / "flc2_reshaped.yaml")
    before = flc.params()
    tuned = flc.with_params(**{"input.increments[1]": 0.5, "input.reshape": 2.0,
                               "gains.output": 3.0})  # fmt: skip
    assert flc.params() == before
    after = tuned.params()
    assert after["input.increments[1]"] == 0.5 and after["input.reshape"] == 2.0
    assert tuned.output_gain == 3.0 and tuned.design.inputs[0].reshape == 2.0
    assert {k for k in after if after[k] != before[k]} <= {
        "input.increments[1]", "input.reshape", "gains.output"
    }  # fmt: skip
    with pytest.raises(ValueError, match=r"no searchable number 'output.increments\[9\]'"):
        flc.with_params(**{"output.increments[9]": 1.0})
    with pytest.raises(ValueError, match="increments must all be > 0"):
        flc.with_params(**{"input.increments[2]": -1.0})
    pi = load_controller(STUDIES / "controllers" / "pi_dinca.yaml")
    assert pi.with_params(kp=2.5).kp == 2.5 and pi.params().keys() == {"kp", "ki"}


def test_an_invalid_sampled_value_names_where_the_parameter_was_declared():
    spec = load_study(STUDIES / "dinca_flc.yaml")
    name = spec.parameters[0].path
    with pytest.raises(ValueError) as info:
        spec.trial_controller({name: -1.0})
    assert f"dinca_flc.yaml: parameters.{name}" in str(info.value)


def test_evaluator_scores_the_template_and_penalises_a_failed_run(dinca):
    spec = load_study(STUDIES / "dinca_flc.yaml")
    ev = build_evaluator(spec)
    base = ev.baseline_evaluation
    # the baseline: worst case of the scenarios' aggregated metrics (worst over steps)
    per = [result_metrics(simulate(dinca, ev.baseline, s)).aggregate for s in spec.scenarios]
    assert base.metrics["settling_time_s"] == max(p["settling_time_s"] for p in per)
    expected = sum(w * base.metrics[m] for m, w in spec.objective.weights.items())
    assert base.values == pytest.approx((expected,))
    # a controller that drives into the end stop gets the penalty and the reason
    wild = ev.controller({"output.translate": 3.0}, name="wild")
    bad = ev.evaluate(wild)
    assert bad.status != "ok" and bad.values == (spec.penalty,) and bad.message


@pytest.mark.slow
def test_dinca_flc_beats_the_p_baseline():
    """Issues 4 and 11: on the shipped loop (20 ms I/O delay, sensor noise, ADC, ±20 mA,
    spool lag) the shipped tuned controller, scored by its study, meets the margin and
    chatter constraints and beats P K=10 on the objective, on steady-state error (the
    valve bias is removed) and on saturation time. The study itself needs about 100
    trials to find its first feasible controller (300 shipped it: 4 min), so the test
    scores the shipped result rather than re-running it. (It no longer settles as fast as
    FLC2, which saturates 0.22 s and chatters: the constraints cost speed.)"""
    from fuzzyservo.io.controllers import load_controller

    spec = load_study(STUDIES / "dinca_flc.yaml")
    ev = build_evaluator(spec)
    best = ev.evaluate(load_controller(STUDIES / "controllers" / "flc_dinca_tuned.yaml"))
    base = ev.baseline_evaluation
    assert best.status == "ok" and max(best.violations) <= 0, best.violations
    assert best.metrics["gain_margin"] >= 2 and best.metrics["delay_margin_s"] >= 0.01
    assert best.values[0] < base.values[0]
    assert best.metrics["sse_abs"] < 0.1 * base.metrics["sse_abs"]
    assert best.metrics["saturation_time_s"] < base.metrics["saturation_time_s"]


def test_ehs160_flc_beats_kb0105(tmp_path):
    """Issue 4: the tuned fuzzy PI beats P Kb = 0.105 on settling time and steady-state error."""
    spec = load_study(STUDIES / "ehs160_flc.yaml")
    outcome = run_study(spec, tmp_path, trials=40, progress=False)
    best, base = outcome.best, outcome.baseline
    assert best.status == "ok"
    assert best.metrics["settling_time_s"] < base.metrics["settling_time_s"]
    assert best.metrics["sse_abs"] < 0.01 * base.metrics["sse_abs"]


def test_resumed_study_keeps_its_trials_and_adds_the_rest(tmp_path):
    spec = load_study(STUDIES / "dinca_pi.yaml")
    first = run_study(spec, tmp_path, trials=8, progress=False)
    second = run_study(spec, tmp_path, trials=14, progress=False)
    assert first.trials_complete == 8 and second.trials_complete == 14
    before = {h["number"]: h["values"] for h in first.history}
    after = {h["number"]: h["values"] for h in second.history}
    assert all(after[n] == v for n, v in before.items())
    assert not math.isnan(second.best.values[0])


def test_the_default_sampler_follows_the_sampler_table(tmp_path):
    """docs/samplers.md: CMA-ES had the best median on the nominal studies, TPE on the
    robust one; a Pareto study gets NSGA-II. The shipped studies leave it to the default."""
    from fuzzyservo.tuning.spec import default_sampler

    assert default_sampler(pareto=False, robust=False) == "cmaes"
    assert default_sampler(pareto=False, robust=True) == "tpe"
    assert default_sampler(pareto=True, robust=True) == "nsga2"
    shipped = {n: load_study(STUDIES / f"{n}.yaml").sampler
               for n in ("dinca_flc", "ehs160_flc", "dinca_robust", "dinca_pareto")}  # fmt: skip
    assert shipped == {"dinca_flc": "cmaes", "ehs160_flc": "cmaes", "dinca_robust": "tpe",
                       "dinca_pareto": "nsga2"}  # fmt: skip
    assert load_study(_bad_study(tmp_path, sampler=None)).sampler == "cmaes"
    assert load_study(_bad_study(tmp_path, sampler="auto")).sampler == "cmaes"
    assert load_study(_bad_study(tmp_path, sampler="tpe")).sampler == "tpe"
