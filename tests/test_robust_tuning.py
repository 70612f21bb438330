"""Robust studies (issue 13): the uncertainty section, common random numbers, aggregates
over samples, infeasible samples with their reason, pruning, warm start."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import yaml
from support import DATA

from fuzzyservo.errors import ConfigError
from fuzzyservo.io.controllers import load_controller
from fuzzyservo.io.studies import load_study
from fuzzyservo.tuning.integrity import fingerprint
from fuzzyservo.tuning.objective import build_evaluator
from fuzzyservo.tuning.uncertainty import Distribution, Uncertainty, aggregate

ROBUST = DATA / "studies" / "dinca_robust.yaml"


def test_aggregates_over_samples():
    v = [3.0, 1.0, 8.0, 2.0, 7.0, 4.0, 6.0, 5.0]
    assert aggregate(v, "worst") == 8.0
    assert aggregate(v, "mean") == 4.5
    assert aggregate(v, "cvar", 0.25) == 7.5  # mean of the worst 2 of 8
    assert aggregate(v, "cvar", 0.01) == 8.0  # at least one sample
    assert aggregate(v, "cvar", 1.0) == 4.5
    assert math.isnan(aggregate([1.0, math.nan], "mean"))


def test_draws_are_common_random_numbers_within_their_ranges():
    dists = (
        Distribution("bulk_modulus", "uniform", 1.2e9, 1.8e9, "bulk_modulus_pa"),
        Distribution("viscous_friction", "log-uniform", 2.0, 20.0, "viscous_friction"),
        Distribution("bias_current", "normal", 2.83e-3, 0.05e-3, "bias_current_a"),
    )
    u = Uncertainty(parameters=dists, samples=500, seed=3)
    again = Uncertainty(parameters=dists, samples=500, seed=3)
    assert u.draws == again.draws  # every trial sees the same plants and noise
    assert Uncertainty(parameters=dists, samples=500, seed=4).draws != u.draws
    for d in dists:
        x = np.array([s.values[d.target] for s in u.draws])
        lo, hi = d.bounds
        assert lo <= x.min() and x.max() <= hi
    logs = np.log([s.values["viscous_friction"] for s in u.draws])
    assert abs(np.median(logs) - math.log(math.sqrt(40.0))) < 0.2  # log-uniform, not uniform
    seeds = {s.noise_seed for s in u.draws}
    assert len(seeds) == 500  # a noise realisation per sample


def test_shipped_robust_study_loads_with_its_units():
    spec = load_study(ROBUST)
    u = spec.uncertainty
    assert u.samples == 8 and u.aggregate == "worst" and spec.workers == 2
    by = {d.target: d for d in u.parameters}
    assert by["oil.bulk_modulus"].a == pytest.approx(1.2e9)  # 12000 bar in Pa
    assert by["io_delay"].b == pytest.approx(0.023)
    assert by["valve.bias_current"].kind == "normal" and by[
        "valve.bias_current"
    ].b == pytest.approx(5e-5)


def _study_with(tmp_path, uncertainty):
    data = yaml.safe_load(ROBUST.read_text())
    data["rig"] = str(DATA / "rigs" / "dinca_cylinder.yaml")
    data["controller"] = str(DATA / "studies" / "controllers" / "flc2_reshaped.yaml")
    data["baseline"] = str(DATA / "studies" / "controllers" / "p_k10.yaml")
    data["uncertainty"] = uncertainty
    path = tmp_path / "robust.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.mark.parametrize(
    ("uncertainty", "key", "text"),
    [
        (
            {"parameters": {"bulk_modulu": {"uniform": [1, 2]}}},
            "bulk_modulu",
            "unknown rig parameter",
        ),
        (
            {"parameters": {"oil.bulk_modulus": {"uniform": [2, 1], "unit": "bar"}}},
            "uniform",
            "low < high",
        ),
        (
            {"parameters": {"oil.bulk_modulus": {"uniform": [1, 2], "normal": [1, 1]}}},
            "oil.bulk_modulus",
            "exactly one of",
        ),
        (
            {"parameters": {"cylinder.piston_mass": {"normal": [1, 1], "unit": "kg"}}},
            "parameters",
            "no valid rig",
        ),
        ({"aggregate": "median"}, "aggregate", "choose one of"),
        ({"samples": 0}, "samples", ">= 1"),
        (
            {"parameters": {"guides.coefficient": {"interval": [1, 2], "unit": "bar"}}},
            "unit",
            "bar",
        ),
    ],
)
def test_bad_uncertainty_sections_name_the_key(tmp_path, uncertainty, key, text):
    with pytest.raises(ConfigError) as info:
        load_study(_study_with(tmp_path, uncertainty))
    message = str(info.value)
    assert key in message and text in message, message
    assert "\n" not in message


def _small(tmp_path, samples=2):
    path = _study_with(
        tmp_path,
        {
            "samples": samples,
            "seed": 5,
            "margin_scenario": "steps",
            "parameters": {
                "oil.bulk_modulus": {"uniform": [12000, 18000], "unit": "bar"},
                "io_delay": {"interval": [18, 22], "unit": "ms"},
            },
        },
    )
    return load_study(path)


def test_a_failing_sample_makes_the_trial_infeasible_with_its_reason(tmp_path):
    evaluator = build_evaluator(_small(tmp_path))
    ev = evaluator.evaluate(load_controller(DATA / "studies" / "controllers" / "open_loop.yaml"))
    assert not ev.feasible
    assert ev.status in ("end_stop", "diverged", "undefined"), ev
    assert ev.message.startswith("sample 0 (") and "oil.bulk_modulus=" in ev.message, ev.message
    assert all(v == 1e6 for v in ev.values)


def test_robust_value_is_the_worst_sample_and_margin_checks_count(tmp_path):
    spec = _small(tmp_path)
    evaluator = build_evaluator(spec)
    flc2 = load_controller(DATA / "studies" / "controllers" / "flc2_reshaped.yaml")
    ev = evaluator.evaluate(flc2)
    assert ev.status == "ok" and ev.simulations == 2 * (2 + 1)  # 2 scenarios + gain check
    nominal = build_evaluator(dataclasses.replace(spec, uncertainty=None)).evaluate(flc2)
    assert ev.values[0] >= 0.5 * nominal.values[0]
    # pruning: told to stop at the first question, after the shortest scenario (steps)
    asked = []
    pruned = evaluator.evaluate(flc2, report=lambda step, value: asked.append(value) or True)
    assert pruned.status == "pruned" and pruned.simulations == 1  # no margin check paid
    steps_worst = evaluator.objective_values(ev.scenario_metrics["steps"])[0]  # over both samples
    assert len(asked) == 1 and 0 < asked[0] <= steps_worst <= ev.values[0]
    # not stopped: asked after each scenario and each sample, and never above the result
    asked.clear()
    again = evaluator.evaluate(flc2, report=lambda step, value: asked.append(value) and False)
    assert again.values == ev.values and len(asked) == 2 * 2
    assert asked == sorted(asked) and asked[-1] == pytest.approx(ev.values[0])


def test_fingerprint_covers_the_uncertainty(tmp_path):
    spec = _small(tmp_path)
    other = dataclasses.replace(
        spec, uncertainty=dataclasses.replace(spec.uncertainty, samples=3, draws=())
    )
    a, b = fingerprint(spec), fingerprint(other)
    assert a["uncertainty"] != b["uncertainty"]
    assert {k for k in a if a[k] != b[k]} == {"uncertainty"}


def test_warm_start_reads_the_searched_numbers_of_a_controller(tmp_path):
    from fuzzyservo.io.studies import with_warm_start
    from fuzzyservo.tuning.warmstart import start_points

    spec = load_study(ROBUST)
    file = DATA / "studies" / "controllers" / "flc2_reshaped.yaml"
    spec = with_warm_start(spec, [str(file)])
    (params,) = start_points(spec)
    assert set(params) == {p.path for p in spec.parameters} - {"gains.output"}  # left default
    for p in spec.parameters:
        assert p.path not in params or p.low <= params[p.path] <= p.high
    other = tmp_path / "p.yaml"
    other.write_text("kind: P\ngain: 10\n")
    with pytest.raises(ConfigError, match="has none of the searched numbers"):
        with_warm_start(spec, [str(other)])


def test_robustness_command_table_json_and_bad_input(tmp_path, capsys):
    import json

    from fuzzyservo.cli import main

    out, report = tmp_path / "mc", tmp_path / "mc.json"
    code = main(
        ["robustness", "dinca_cylinder", "flc_dinca_robust", "--samples", "2",
         "--scenario", "steps", "--out", str(out), "--json", str(report)]
    )  # fmt: skip
    assert code == 0
    text = capsys.readouterr().out
    assert "flc_dinca_robust" in text and "failures" in text
    rows = json.loads(report.read_text())["controllers"]
    assert rows[0]["samples"] == 2 and rows[0]["gain_margin_checked"] == 2.0
    assert (out / "dinca_cylinder_robustness.png").is_file()
    code = main(["robustness", "dinca_cylinder", "p_k10", "--uncertainty", "dinca_flc"])
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert "uncertainty" in err and "\n" not in err


def _calibrated_rig(tmp_path):
    """A calibrated rig file as `fuzzyservo calibrate` writes it: fitted bulk modulus and
    Coulomb friction with their 95 % intervals, the friction's on a bound."""
    from fuzzyservo.io.rigs import write_calibrated_rig

    return write_calibrated_rig(
        DATA / "rigs" / "dinca_cylinder.yaml",
        tmp_path / "dinca_cylinder_calibrated.yaml",
        parameters={"oil.bulk_modulus": (1.5e9, "Pa", "fitted")},
        effects={"coulomb_friction": {"force": (30.0, "N", "fitted")}},
        header="test",
        intervals={
            "oil.bulk_modulus": (1.4e9, 1.6e9, False),
            "coulomb_friction.force": (20, 40, True),
        },
    )


def test_uncertainty_reads_fitted_intervals_from_a_calibrated_rig(tmp_path):
    """`calibrated: FILE` draws every fitted value uniformly in its interval (SI in the
    file, shown in the file's unit); one also under `parameters:` keeps that range."""
    rig = _calibrated_rig(tmp_path)
    spec = load_study(_study_with(tmp_path, {"samples": 8, "calibrated": rig.name}))
    by = {d.target: d for d in spec.uncertainty.parameters}
    assert set(by) == {"oil.bulk_modulus", "coulomb_friction.force"}
    assert (by["oil.bulk_modulus"].a, by["oil.bulk_modulus"].b) == (1.4e9, 1.6e9)
    assert (
        by["oil.bulk_modulus"].field == "oil__bulk_modulus"
        and by["oil.bulk_modulus"].origin == "fitted"
    )
    friction = by["coulomb_friction.force"]
    assert (friction.effect, friction.a, friction.b) == ("coulomb_friction", 20.0, 40.0)
    assert "at a bound" in friction.origin and "at a bound" in spec.uncertainty.describe()
    for s in spec.uncertainty.draws:
        assert 1.4e9 <= s.values["oil.bulk_modulus"] <= 1.6e9
        assert 20.0 <= s.values["coulomb_friction.force"] <= 40.0
    from fuzzyservo.tuning.uncertainty.robust import sample_rigs

    drawn = sample_rigs(spec.rig, spec)[0]
    assert drawn.effect_values("coulomb_friction")["force"] == pytest.approx(
        spec.uncertainty.draws[0].values["coulomb_friction.force"]
    )
    both = {"calibrated": str(rig),
            "parameters": {"oil.bulk_modulus": {"uniform": [12000, 18000], "unit": "bar"}}}  # fmt: skip
    by = {d.target: d for d in load_study(_study_with(tmp_path, both)).uncertainty.parameters}
    assert by["oil.bulk_modulus"].a == pytest.approx(1.2e9) and not by["oil.bulk_modulus"].origin


@pytest.mark.parametrize(
    ("edit", "text"),
    [
        (
            lambda d: d["plant"]["components"]["oil"]["parameters"]["bulk_modulus"].pop("interval"),
            "no fitted interval",
        ),
        (
            lambda d: d["plant"]["components"]["oil"]["parameters"]["bulk_modulus"].update(
                interval=[2, 1]
            ),
            "[low, high]",
        ),
    ],
)
def test_bad_calibrated_rig_names_the_file_and_key(tmp_path, edit, text):
    rig = _calibrated_rig(tmp_path)
    data = yaml.safe_load(rig.read_text())
    data["effects"]["coulomb_friction"]["force"].pop("interval")
    edit(data)
    rig.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError) as info:
        load_study(_study_with(tmp_path, {"calibrated": str(rig)}))
    message = str(info.value)
    assert text in message and "calibrated" in message and "\n" not in message, message


def test_report_compares_best_baseline_and_template_nominal_and_monte_carlo(tmp_path):
    """A robust study's report: the tuned controller beside P K=10 and the template (FLC2)
    on the nominal plant and on fresh samples, each with its gain check."""
    from fuzzyservo.display import metric_units
    from fuzzyservo.tuning.report import comparison_controllers
    from fuzzyservo.tuning.report_markdown import comparison_lines
    from fuzzyservo.tuning.uncertainty.robust import CHECK_SEED, compare_controllers

    spec = dataclasses.replace(_small(tmp_path, samples=1), scenarios=("steps",))
    evaluator = build_evaluator(spec)
    best = load_controller(DATA / "studies" / "controllers" / "flc_dinca_robust.yaml")
    c = compare_controllers(evaluator, comparison_controllers(evaluator, best), samples=2)
    assert c.names == ["flc_dinca_robust", "p_k10", "flc2_reshaped"]
    assert (c.samples, c.seed, c.gain) == (2, CHECK_SEED, 2.0)  # gain from the constraint
    rows = {r["controller"]: r for r in c.rows()}
    assert rows["p_k10"]["nominal"]["gain_margin_holds"] is False  # P K=10: margin 1.67
    assert rows["flc_dinca_robust"]["nominal"]["gain_margin_holds"] is True
    assert rows["flc_dinca_robust"]["failures"] == 0 and rows["p_k10"]["failures"] == 2
    assert rows["flc_dinca_robust"]["nominal"]["objective"] < rows["p_k10"]["nominal"]["objective"]
    text = "\n".join(comparison_lines(c, lambda key: f"{key}.png", metric_units(spec.rig)))
    assert "### Nominal plant" in text and "2 plants the study never saw" in text
    assert "| steady-state error [cm] |" in text  # the rig's display unit, as in the plots
    assert "| failures | 0 / 2 | 2 / 2 |" in text and "**oscillates**" in text


def test_monte_carlo_in_batches_matches_one_by_one(tmp_path):
    """The batched, parallel Monte Carlo gives each sample exactly the runs and verdicts of
    run_sample and stable_at, one by one."""
    from fuzzyservo.analysis.margins import stable_at
    from fuzzyservo.tuning.uncertainty.robust import sample_rigs
    from fuzzyservo.tuning.uncertainty.robustness import monte_carlo, run_sample

    spec = _small(tmp_path, samples=3)
    rig = spec.rig
    rigs = sample_rigs(rig, spec)
    seeds = [d.noise_seed for d in spec.uncertainty.draws]
    names = ("p_k10", "flc2_reshaped")
    controllers = [load_controller(DATA / "studies" / "controllers" / f"{n}.yaml") for n in names]
    seen = []
    mcs = monte_carlo(rig, controllers, rigs, seeds, ["steps"], chunk=2, progress=seen.append)
    assert seen == [2, 1, 2, 1]
    for mc, controller in zip(mcs, controllers, strict=True):
        for run, r, seed in zip(mc.runs, rigs, seeds, strict=True):
            alone = run_sample(run.index, r, controller, ["steps"], seed)
            assert (run.status, run.metrics) == (alone.status, alone.metrics)
            assert run.gain_holds == stable_at(r, controller, "steps", multiplier=2.0,
                                              noise_seed=seed)  # fmt: skip


@pytest.mark.slow  # a whole `tune` with its report and figures (about 10-35 s here)
def test_tune_prints_and_reports_the_comparison(tmp_path, capsys):
    """`fuzzyservo tune` of a robust study ends with the comparison (nominal and fresh
    samples) on screen, in report.md and in summary.json; a bad --check-samples is one line."""
    import json

    from fuzzyservo.cli import main

    path = _study_with(
        tmp_path,
        {"samples": 1, "seed": 5, "margin_scenario": "steps",
         "parameters": {"io_delay": {"interval": [18, 22], "unit": "ms"}}},
    )  # fmt: skip
    data = yaml.safe_load(path.read_text())
    data["scenarios"] = ["steps"]
    path.write_text(yaml.safe_dump(data))
    out = tmp_path / "out"
    args = ["tune", str(path), "--trials", "2", "--workers", "1", "--out", str(out)]
    assert main([*args, "--check-samples", "-1"]) == 2
    assert "--check-samples" in capsys.readouterr().err
    assert main([*args, "--check-samples", "1"]) == 0
    text = capsys.readouterr().out
    assert "nominal plant" in text and "Monte Carlo on 1 fresh samples (seed 2026)" in text
    assert "p_k10" in text and "flc2_reshaped" in text
    assert "## Against the baseline and the template" in (out / "report.md").read_text()
    c = json.loads((out / "summary.json").read_text())["comparison"]
    assert c["samples"] == 1 and [r["controller"] for r in c["controllers"]][1:] == [
        "p_k10", "flc2_reshaped"]  # fmt: skip
    assert (out / "check.png").is_file()


def test_standard_error_of_the_mean_and_of_the_worst():
    """Of the mean: s/sqrt(n) (here s = 1 for 1, 2, 3 and n = 3); of the worst: the bootstrap
    spread, zero when every sample gives the same value, a fraction of the range otherwise."""
    from fuzzyservo.tuning.uncertainty.noise import fresh_uncertainty, standard_error

    assert standard_error([1.0, 2.0, 3.0], "mean") == pytest.approx(1 / math.sqrt(3))
    assert standard_error([2.0] * 8, "worst") == 0.0
    spread = standard_error([1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0], "worst")
    assert 0.1 < spread < 7.0
    assert math.isnan(standard_error([1.0], "worst"))
    assert math.isnan(standard_error([1.0, math.nan], "mean"))
    u = load_study(DATA / "studies" / "dinca_robust.yaml").uncertainty
    fresh = fresh_uncertainty(u)
    assert fresh.samples == u.samples and fresh.seed != u.seed
    assert fresh.draws[0].values != u.draws[0].values


def test_lock_step_runs_equal_one_by_one(tmp_path):
    """Sampled plants whose loop settings differ (their I/O delay, a scaled actuator) go
    through one compiled call and each gets exactly the run it gets alone; so do the
    margin checks of a trial."""
    from fuzzyservo.analysis.margins import scaled
    from fuzzyservo.simulation import simulate
    from fuzzyservo.simulation.closed_loop import simulate_batch
    from fuzzyservo.tuning.uncertainty.robust import sample_rigs
    from fuzzyservo.tuning.uncertainty.robustness import margin_checks, margin_checks_batch

    spec = _small(tmp_path, samples=3)
    rigs = sample_rigs(spec.rig, spec)
    assert len({r.io_delay_s for r in rigs}) == 3
    seeds = [d.noise_seed for d in spec.uncertainty.draws]
    flc2 = load_controller(DATA / "studies" / "controllers" / "flc2_reshaped.yaml")
    pairs = [scaled(r, flc2, 2.0) for r in rigs]
    for batch, controller in ((rigs, flc2), ([r for r, _ in pairs], pairs[0][1])):
        together = simulate_batch(batch, controller, "steps", seeds)
        for rig, seed, run in zip(batch, seeds, together, strict=True):
            alone = simulate(rig, controller, "steps", noise_seed=seed)
            assert (run.status, run.integration_steps) == (alone.status, alone.integration_steps)
            for name in ("output", "command", "measured", "actuator"):
                np.testing.assert_array_equal(getattr(run, name), getattr(alone, name))
    checks = margin_checks_batch(rigs, flc2, "steps", seeds, 2.0, 0.004)
    assert checks == [
        margin_checks(r, flc2, "steps", s, 2.0, 0.004) for r, s in zip(rigs, seeds, strict=True)
    ]


def test_lock_step_trial_equals_sequential_and_pruning_is_exact(tmp_path):
    """A trial scored in lock-step (nothing can stop it) equals one scored sample by
    sample; a trial is pruned exactly when its full value exceeds the bound, and an
    unpruned one scores the same; a pruned one counts the samples it skipped."""
    evaluator = build_evaluator(_small(tmp_path, samples=3))
    flc2 = load_controller(DATA / "studies" / "controllers" / "flc2_reshaped.yaml")
    full = evaluator.evaluate(flc2)
    one_by_one = evaluator.evaluate(flc2, report=lambda step, value: False)

    def key(ev):
        return ev.status, ev.values, ev.violations, ev.metrics, ev.scenario_metrics

    assert full.status == "ok" and key(full) == key(one_by_one)
    assert full.samples_skipped == 0 and full.simulations == 3 * (2 + 1)
    value = full.values[0]
    kept = evaluator.evaluate(flc2, report=lambda step, v: v > value)
    assert key(kept) == key(full)
    lost = evaluator.evaluate(flc2, report=lambda step, v: v > value * (1 - 1e-9))
    assert lost.status == "pruned" and lost.simulations <= 3 * 2  # no margin check paid
    first = evaluator.evaluate(flc2, report=lambda step, v: True)
    assert first.status == "pruned" and first.samples_skipped == 2 and first.simulations == 1


def test_pruned_trials_in_lock_step_pairs_equal_one_sample_at_a_time(tmp_path, monkeypatch):
    """Past its first sample a prunable trial runs its samples two at a time in one
    compiled call (robust.LOCKSTEP): every report the pruning sees, the value, the prune
    step and the counts are those of one sample after the other, whatever the bound."""
    from fuzzyservo.tuning.uncertainty import robust

    evaluator = build_evaluator(_small(tmp_path, samples=5))
    flc2 = load_controller(DATA / "studies" / "controllers" / "flc2_reshaped.yaml")
    value = evaluator.evaluate(flc2).values[0]

    def scored(pairs: int, bound: float):
        monkeypatch.setattr(robust, "LOCKSTEP", pairs)
        reports = []

        def report(step, v):
            reports.append((step, v))
            return v > bound

        ev = evaluator.evaluate(flc2, report=report)
        return (ev.status, ev.values, ev.violations, ev.metrics, ev.simulations,
                ev.samples_skipped, reports)  # fmt: skip

    for bound in (math.inf, value, value * (1 - 1e-9), 0.0):
        assert scored(2, bound) == scored(1, bound), bound


def test_evaluator_scores_its_baseline_when_asked(tmp_path):
    """A worker that only scores trials does not pay for the baseline (a run per sample
    and scenario): it is scored on first use, and then as before."""
    spec = _small(tmp_path)
    evaluator = build_evaluator(spec)
    assert evaluator._baseline is None
    base = evaluator.baseline_evaluation
    assert base is evaluator.baseline_evaluation and base.results  # kept for the report
    assert key_values(base) == key_values(build_evaluator(spec).evaluate(spec.baseline))


def key_values(ev):
    return ev.status, ev.values, ev.violations
