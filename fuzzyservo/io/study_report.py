"""What a finished study leaves in its output folder: the best controller, a summary, figures, a report.

:func:`write_study_report` turns an :class:`~fuzzyservo.tuning.runner.StudyOutcome` into

- ``best_controller.yaml``: the template with the best parameters, a controller file
  ``fuzzyservo simulate``/``compare`` take as it is (and ``best_controller.fis`` for a
  fuzzy controller, for MATLAB's Fuzzy Logic Designer);
- ``summary.json``: the numbers (NaN and infinities as ``null``);
- PNG figures: responses of baseline and best per scenario, trial history,
  importances, Pareto front, control curve and membership functions before/after;
- ``report.md``: all of it on one page, figures linked relatively.

The best controller file is read back and simulated again before the report claims it
reproduces the study's objective. matplotlib is imported only inside :func:`write_study_report`.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

from fuzzyservo.analysis.robustness import SUMMARY_METRICS, comparison_text
from fuzzyservo.atomic import ensure_folder, write_text
from fuzzyservo.display import (
    LOWER_IS_BETTER,
    TRIAL_COUNTS_NOTE,
    MetricUnits,
    change_text,
    elapsed_text,
    metric_units,
    metrics_table,
    trial_counts_text,
    undefined_note,
)
from fuzzyservo.io.jsonfile import write_json
from fuzzyservo.metrics import METRIC_DOCS, METRIC_NAMES, format_value
from fuzzyservo.tuning.evaluation import Evaluation
from fuzzyservo.tuning.objective import measured_margins
from fuzzyservo.tuning.robust import Comparison, compare_controllers
from fuzzyservo.tuning.runner import StudyOutcome, build_evaluator

CONTROLLER_FILE = "best_controller.yaml"
FIS_FILE = "best_controller.fis"
SUMMARY_FILE = "summary.json"
REPORT_FILE = "report.md"


def write_study_report(
    outcome: StudyOutcome,
    out_dir: Path,
    *,
    check_samples: int | None = None,
    progress: Callable[[int], object] | None = None,
) -> dict[str, Path]:
    """Write the best controller, ``summary.json``, the figures and ``report.md`` into ``out_dir``.

    Returns the written files by role: ``controller``, ``fis`` (fuzzy controllers),
    ``summary``, ``report``, ``history``, ``importances`` (when computed), ``pareto``
    (Pareto studies), ``curve``, ``membership_before``, ``membership_after`` (fuzzy),
    ``response_<scenario>`` per scenario and, for a robust study, ``check`` (the Monte
    Carlo distributions).

    A robust study's report compares the best controller with the baseline and the
    template on the nominal plant and on ``check_samples`` plants drawn afresh from its
    uncertainty (default: as many as the study's own samples; 0: no comparison), each
    with its gain check (:func:`~fuzzyservo.tuning.robust.compare_controllers`;
    ``progress(1)`` per sampled plant and controller).
    """
    from fuzzyservo.controllers.fuzzy.controller import FuzzyController
    from fuzzyservo.io.controllers import controller_data, load_controller, write_controller_file

    out_dir = ensure_folder(out_dir)
    spec = outcome.spec
    paths: dict[str, Path] = {}
    evaluator = build_evaluator(spec)
    trial = best_trial_number(outcome)

    data = controller_data(evaluator.controller(outcome.best_params, name=f"{spec.name}_best"))
    data["description"] = (
        f"Best {'trial' if trial is None else f'trial #{trial}'} of tuning study {spec.name} "
        f"({spec.path or 'no study file'}; trials {_counts(outcome)}) on "
        f"scenarios {', '.join(spec.scenarios)}; objective {spec.objective.describe()} = "
        f"{_values_text(outcome.best.values)} (baseline {_values_text(outcome.baseline.values)}). "
        f"Template: {spec.template.name}."
    )
    paths["controller"] = write_controller_file(data, out_dir / CONTROLLER_FILE)

    # the file, not the in-memory mapping, is what users run: score the file
    best_controller = load_controller(paths["controller"])
    check = evaluator.evaluate(best_controller)
    fuzzy = isinstance(best_controller, FuzzyController)
    if fuzzy:
        from fuzzyservo.io.fis import write_fis

        paths["fis"] = write_fis(best_controller.system, out_dir / FIS_FILE)

    paths.update(_figures(outcome, out_dir, best_controller, fuzzy))
    comparison = None
    units = metric_units(spec.rig)
    if spec.uncertainty is not None and check_samples != 0:
        comparison = _compare(evaluator, best_controller, check_samples, progress)
        paths["check"] = _check_figure(comparison, out_dir, units)
    summary = study_summary(outcome, evaluator.baseline.name, trial)
    measured = _measured_margins(evaluator, best_controller)
    if measured:
        summary["measured_margins"] = measured
    if comparison is not None:
        summary["comparison"] = {
            "samples": comparison.samples,
            "seed": comparison.seed,
            "gain_margin_checked": comparison.gain,
            "uncertainty": comparison.uncertainty,
            "controllers": comparison.rows(),
        }
    paths["summary"] = write_json(out_dir / SUMMARY_FILE, summary)
    paths["report"] = out_dir / REPORT_FILE
    text = _report(outcome, evaluator, trial, check, paths, out_dir, comparison, measured, units)
    write_text(paths["report"], text)
    return paths


def tuning_text(outcome: StudyOutcome, summary: dict[str, Any]) -> str:
    """What ``fuzzyservo tune`` prints when done: the trial counts, the metrics of the
    baseline and the best in display units (``n/a`` explained), the objective and, for a
    robust study, the comparison of its ``summary`` (as written)."""
    units = metric_units(outcome.spec.rig)
    best, base = outcome.best, outcome.baseline
    rows = [base.metrics, best.metrics]
    names = [f"baseline {outcome.spec.baseline.name}", "best"]
    lines = [
        f"trials: {_counts(outcome)}",
        f"metrics, worst over the scenarios{' and samples' if outcome.spec.uncertainty else ''}"
        f" ({LOWER_IS_BETTER}; change: best against the baseline):",
        metrics_table(names, rows, units, change=True),
    ]
    if note := undefined_note(METRIC_NAMES, rows):
        lines.append(note)
    values = [", ".join(format_value(v) for v in e.values) for e in (best, base)]
    lines.append(f"objective: best {values[0]} against baseline {values[1]} "
                 f"({outcome.spec.objective.describe()}{_si_note(outcome.spec, units)})")  # fmt: skip
    for who, e in (("best", best), ("baseline", base)):
        if e.status != "ok":  # its objective is the penalty or undefined: say why
            lines.append(f"{who}: status {_status(e)}")
    if "comparison" in summary:
        lines.append(comparison_text(summary["comparison"], units))
    return "\n".join(lines)


def _measured_margins(evaluator, best_controller) -> dict[str, dict[str, float | None]]:
    """The margins the constraints bound, measured on the nominal plant for the best and
    the baseline: {metric: {"best", "baseline"}} (None where the loop never oscillates in
    the searched range)."""
    spec = evaluator.spec
    scenario = spec.uncertainty.margin_scenario if spec.uncertainty is not None else ""
    scenario = scenario or spec.scenarios[0]
    out: dict[str, dict[str, float | None]] = {}
    for who, controller in (("best", best_controller), ("baseline", evaluator.baseline)):
        found = measured_margins(evaluator.rig, controller, scenario, list(spec.constraints))
        for metric, value in found.items():
            out.setdefault(metric, {})[who] = value if math.isfinite(value) else None
    return out


def comparison_controllers(evaluator, best_controller) -> list:
    """The best controller, the baseline and the template (when it is not the baseline)."""
    spec = evaluator.spec
    controllers = [best_controller, evaluator.baseline]
    if spec.template != spec.baseline:
        controllers.append(spec.template)
    return controllers


def _compare(evaluator, best_controller, samples: int | None, progress) -> Comparison:
    spec = evaluator.spec
    n = spec.uncertainty.samples if samples is None else samples
    return compare_controllers(
        evaluator, comparison_controllers(evaluator, best_controller), samples=n, progress=progress
    )


def _check_figure(comparison: Comparison, out_dir: Path, units: MetricUnits) -> Path:
    from fuzzyservo import plots

    values = {
        m: {mc.controller: mc.values(m) * units.factor(m) for mc in comparison.monte_carlo}
        for m in SUMMARY_METRICS
    }
    fig = plots.distribution_figure(values, {m: units.unit(m) for m in SUMMARY_METRICS})
    return plots.save(fig, out_dir / "check.png")


def _comparison_lines(comparison: Comparison, link, units: MetricUnits) -> list[str]:
    """The report's comparison: nominal plant, then the Monte Carlo table."""
    names = comparison.names
    rows = comparison.rows()
    labels = {"settling_time_s": "settling time 2 %", "sse_abs": "steady-state error",
              "overshoot_pct": "overshoot", "saturation_time_s": "converter saturated"}  # fmt: skip
    shown = [(m, label, units.unit(m), units.factor(m)) for m, label in labels.items()]
    head = "| | " + " | ".join(f"`{n}`" for n in names) + " |"
    rule = "|---|" + "---:|" * len(names)
    lines = ["## Against the baseline and the template", "", "### Nominal plant", "", head, rule]
    lines.append(
        "| objective | " + " | ".join(_num(r["nominal"]["objective"]) for r in rows) + " |"
    )
    for key, label, unit, k in shown:
        cells = [_num(r["nominal"][key] * k) for r in rows]
        lines.append(f"| {label} [{unit}] | " + " | ".join(cells) + " |")
    lines.append(
        f"| gain margin >= {comparison.gain:g} | "
        + " | ".join(
            {True: "holds", False: "**oscillates**", None: "n/a"}[r["nominal"]["gain_margin_holds"]]
            for r in rows
        )
        + " |"
    )
    lines += [
        "",
        f"### Monte Carlo: {comparison.samples} plants the study never saw",
        "",
        f"Drawn with seed {comparison.seed} from the study's uncertainty ({comparison.uncertainty}); "
        "metrics are the worst scenario of each sample; a failure is a failed run or an "
        f"oscillation at {comparison.gain:g} times the controller output on any scenario. "
        "`fuzzyservo robustness` runs the same check on more samples.",
        "",
        head,
        rule,
        "| failures | " + " | ".join(f"{r['failures']} / {r['samples']}" for r in rows) + " |",
        f"| gain margin >= {comparison.gain:g} holds | "
        + " | ".join(f"{r['gain_margin_holds']} / {r['samples']}" for r in rows)
        + " |",
    ]
    for key, label, unit, k in shown:
        cells = [
            "/".join(_num(r[key][q] * k, "never") for q in ("p50", "p90", "worst")) for r in rows
        ]
        lines.append(f"| {label}: median/90 %/worst [{unit}] | " + " | ".join(cells) + " |")
    lines += ["", f"![Monte Carlo distributions]({link('check')})", ""]
    return lines


def best_trial_number(outcome: StudyOutcome) -> int | None:
    """The number of the trial the outcome reports as best (as :func:`runner.collect` picks it)."""
    if outcome.best_number is not None:
        return outcome.best_number
    if outcome.pareto:
        for p in outcome.pareto:
            if p["params"] == outcome.best_params:
                return int(p["number"])
        return None
    history = outcome.history
    pool = (
        [h for h in history if h["feasible"]]
        or [h for h in history if h["status"] == "ok"]
        or history
    )
    if not pool:
        return None
    return int(min(pool, key=lambda h: h["values"][0])["number"])


def study_summary(outcome: StudyOutcome, baseline_name: str, trial: int | None) -> dict[str, Any]:
    """The ``summary.json`` mapping (before NaN/inf become null)."""
    spec = outcome.spec
    best, base = outcome.best, outcome.baseline
    return {
        "study": spec.name,
        # every metric below is SI, in the unit this maps it to (the units schema,
        # fuzzyservo.metrics.METRIC_UNITS, for this rig's output)
        "units": metric_units(spec.rig).si_units(),
        "trials": outcome.trials_complete,
        "objective": spec.objective.describe(),
        "best": {
            "trial": trial,
            "params": dict(outcome.best_params),
            "objective": _objective_value(best),
            "metrics": dict(best.metrics),
            "scenarios": {s: dict(m) for s, m in best.scenario_metrics.items()},
            "status": best.status,
            "message": best.message,
            "feasible": best.feasible,
            "violations": list(best.violations),
            # robust studies: the value's standard error over the samples, and its value
            # on fresh samples (the winner of the top trials there: tuning/noise.py)
            **(
                {
                    k: outcome.selection[0][k]
                    for k in ("standard_error", "fresh_value", "fresh_standard_error")
                }
                if outcome.selection
                else {}
            ),
        },
        "selection": [dict(row) for row in outcome.selection],
        "baseline": {
            "controller": baseline_name,
            "objective": _objective_value(base),
            "metrics": dict(base.metrics),
            "scenarios": {s: dict(m) for s, m in base.scenario_metrics.items()},
            "status": base.status,
            "feasible": base.feasible,
        },
        "constraints": [str(c) for c in spec.constraints],
        "sampler": spec.sampler,
        "pareto": [
            {"number": p["number"], "values": list(p["values"]), "params": dict(p["params"])}
            for p in outcome.pareto
        ],
        "importances": dict(outcome.importances),
        "storage": outcome.storage_url,
        "wall_s": outcome.wall_s,
        "sim_time_s": outcome.sim_time_s,
        "time_split_s": time_split(outcome),
        "simulations": outcome.simulations,
        "trials_asked": outcome.trials_asked,
        "trials_pruned": outcome.trials_pruned,
        "trials_failed": outcome.trials_failed,
        # robust studies: sampled plants the trials never ran (pruned or failed before them)
        "samples_skipped": outcome.samples_skipped,
    }


def _si_note(spec, units: MetricUnits) -> str:
    """The objective weighs metrics in SI: say so for those the tables show in another
    unit (``sse_abs`` in m, shown in mm)."""
    si = [f"{m} in {units.si(m)}" for m in spec.objective.metrics if units.unit(m) != units.si(m)]
    return f"; over the metrics in SI: {', '.join(si)}" if si else ""


def _counts(outcome: StudyOutcome) -> str:
    """Asked, complete, pruned and failed trials (a study collected before the asked
    and failed ones were counted: complete and pruned are all it asked)."""
    asked = outcome.trials_asked or outcome.trials_complete + outcome.trials_pruned
    return trial_counts_text(asked, outcome.trials_complete, outcome.trials_pruned,
                             outcome.trials_failed)  # fmt: skip


def _trials_text(outcome: StudyOutcome) -> str:
    """Asked, complete, pruned and failed trials, and for a robust study its simulations
    and the sampled plants its trials skipped."""
    text = _counts(outcome)
    if outcome.samples_skipped:
        text += f" ({outcome.samples_skipped} sampled plants skipped: decided before them)"
    if outcome.simulations:
        text += f"; {outcome.simulations} simulations"
    return text


def _split_text(outcome: StudyOutcome) -> str:
    """The trials' time by what it went to (a study stored before the split was
    recorded: simulation and the rest)."""
    if not outcome.sampler_time_s:
        rest_s = max(0.0, outcome.worker_time_s - outcome.sim_time_s)
        return (f"simulation {elapsed_text(outcome.sim_time_s)}, sampler, storage and controller "
                f"building {elapsed_text(rest_s)}")  # fmt: skip
    return ", ".join(f"{k} {elapsed_text(v)}" for k, v in time_split(outcome).items())


def time_split(outcome: StudyOutcome) -> dict[str, float]:
    """The study's time by what it went to: the trials' simulations and controller
    building, the sampler's asks, and ``storage``: the parent writing the batches (batch
    mode), or the rest of each trial (``--async``: writing it, storage reads)."""
    rest = outcome.worker_time_s - outcome.sim_time_s - outcome.sampler_time_s
    return {
        "simulation": outcome.sim_time_s,
        "sampler": outcome.sampler_time_s,
        "building": outcome.build_time_s,
        "storage": outcome.storage_time_s or max(0.0, rest - outcome.build_time_s),
    }


def _selection_lines(outcome: StudyOutcome) -> list[str]:
    """The robust study's top trials on fresh samples (the winner first), values ± their
    standard errors over the samples."""
    if not outcome.selection:
        return []

    def pm(value: float, se: float | None) -> str:
        return f"{value:.4g}" + (f" ± {se:.2g}" if se is not None else "")

    lines = [
        f"The {len(outcome.selection)} best trials scored again on fresh samples (a search's "
        "best over noisy values is biased low); the lowest feasible fresh value wins:",
        "",
        "| trial | objective (study samples) | objective (fresh samples) | feasible there |",
        "|---|---|---|---|",
    ]
    for row in outcome.selection:
        lines.append(f"| #{row['number']} | {pm(row['value'], row['standard_error'])} | "
                     f"{pm(row['fresh_value'], row['fresh_standard_error'])} | "
                     f"{'yes' if row['fresh_feasible'] else 'no'} |")  # fmt: skip
    return [*lines, ""]


def _status(ev: Evaluation) -> str:
    """A scored controller's status and why (an objective that is the penalty or n/a)."""
    return ev.status + (f" ({ev.message})" if ev.message else "")


def _objective_value(ev: Evaluation) -> float | list[float]:
    return ev.values[0] if len(ev.values) == 1 else list(ev.values)


# -- figures ---------------------------------------------------------------------------


def _figures(outcome: StudyOutcome, out_dir: Path, best_controller, fuzzy: bool) -> dict[str, Path]:
    from fuzzyservo import plots

    spec = outcome.spec
    paths: dict[str, Path] = {}
    for scenario in spec.scenarios:
        runs = [
            r
            for r in (outcome.baseline.results.get(scenario), outcome.best.results.get(scenario))
            if r is not None
        ]
        if runs:
            key = f"response_{_file_part(scenario)}"
            paths[key] = plots.save(plots.response_figure(runs), out_dir / f"{key}.png")
    if fuzzy:
        from fuzzyservo.controllers.fuzzy.controller import FuzzyController

        template = spec.template
        one_input = len(best_controller.system.inputs) == 1
        compare = (
            [template]
            if isinstance(template, FuzzyController)
            and one_input
            and len(template.system.inputs) == 1
            and template.form == best_controller.form
            else []
        )
        fig = plots.control_curve_figure(best_controller, compare=compare)
        paths["curve"] = plots.save(fig, out_dir / "curve.png")
        if isinstance(template, FuzzyController):
            fig = plots.membership_figure(template)
            paths["membership_before"] = plots.save(fig, out_dir / "membership_before.png")
        fig = plots.membership_figure(best_controller)
        paths["membership_after"] = plots.save(fig, out_dir / "membership_after.png")
    names = list(spec.objective.pareto) or ["objective"]
    if outcome.history:
        fig = plots.history_figure(
            outcome.history, names, title=f"{spec.name}: {spec.objective.describe()}"
        )
        paths["history"] = plots.save(fig, out_dir / "history.png")
    if outcome.importances:
        target = f" (of {names[0]})" if spec.objective.pareto else ""
        fig = plots.importance_figure(
            outcome.importances, title=f"{spec.name}: parameter importances{target}"
        )
        paths["importances"] = plots.save(fig, out_dir / "importances.png")
    if spec.objective.pareto and outcome.pareto:
        measured = [
            h["values"]
            for h in outcome.history
            if h["status"] == "ok" and all(math.isfinite(v) for v in h["values"])
        ]
        fig = plots.pareto_figure(
            measured,
            [p["values"] for p in outcome.pareto],
            names,
            baseline=outcome.baseline.values if outcome.baseline.status == "ok" else None,
            best=outcome.best.values,
            title=f"{spec.name}: objectives of every trial, Pareto front in red",
        )
        paths["pareto"] = plots.save(fig, out_dir / "pareto.png")
    return paths


def _file_part(name: str) -> str:
    return re.sub(r"[^\w.-]", "_", name)


# -- report.md -------------------------------------------------------------------------


def _report(
    outcome: StudyOutcome,
    evaluator,
    trial: int | None,
    check: Evaluation,
    paths: dict[str, Path],
    out_dir: Path,
    comparison: Comparison | None = None,
    measured: dict[str, dict[str, float | None]] | None = None,
    units: MetricUnits | None = None,
) -> str:
    spec = outcome.spec
    best, base = outcome.best, outcome.baseline

    def link(key: str) -> str:
        return paths[key].relative_to(out_dir).as_posix()

    def image(key: str, alt: str) -> list[str]:
        return [f"![{alt}]({link(key)})", ""] if key in paths else []

    lines = [f"# Tuning study `{spec.name}`", ""]
    if spec.description:
        lines += [spec.description.strip(), ""]
    sampler = spec.sampler + (f" (seed {spec.seed})" if spec.seed is not None else "")
    units = units or metric_units(spec.rig)
    lines += [
        "| | |",
        "|---|---|",
        f"| study file | `{spec.path or '-'}` |",
        f"| rig | {spec.rig.name}" + (f" (`{spec.rig.path}`)" if spec.rig.path else "") + " |",
        f"| scenarios | {', '.join(spec.scenarios)} ({spec.aggregate} over scenarios) |",
        f"| template | {spec.template.name} |",
        f"| baseline | {evaluator.baseline.name} |",
        f"| objective | {spec.objective.describe()} (minimised{_si_note(spec, units)}) |",
        f"| constraints | {', '.join(f'`{c}`' for c in spec.constraints) or 'none'} |",
        *(
            [
                f"| uncertainty | {spec.uncertainty.describe()}; metrics and objective are over "
                "these samples, the plots show the nominal plant |"
            ]
            if spec.uncertainty is not None
            else []
        ),
        f"| sampler | {sampler} |",
        f"| trials | {_trials_text(outcome)} |",
        f"| optimisation time (this run) | {elapsed_text(outcome.wall_s)} (compiling and the "
        "trials; not the check on fresh samples nor this report) |",
        f"| time in trials | {_split_text(outcome)} (summed over the stored trials) |",
        f"| storage | `{outcome.storage_url}` |",
        "",
        f"Trials: {TRIAL_COUNTS_NOTE}.",
        "",
        "## Result",
        "",
    ]
    lines += _selection_lines(outcome)
    which = "the reported best" if trial is None else f"trial #{trial}"
    lines += [
        f"Best: {which}, objective {_values_text(best.values)} against the baseline's "
        f"{_values_text(base.values)}; status {_status(best)}, "
        f"{'feasible' if best.feasible else 'infeasible'}."
        + (f" The baseline's status: {_status(base)}." if base.status != "ok" else ""),
        "",
    ]
    for c, v in zip(spec.constraints, best.violations, strict=True):
        met = "met" if v <= 0 else "broken"
        if measured and c.metric in measured:  # the search checked the loop at the bound
            m = measured[c.metric]
            where = "on every sampled plant" if spec.uncertainty is not None else "at the bound"
            lines.append(
                f"- `{c}`: best {units.text(c.metric, m['best'])} measured on the nominal "
                f"plant ({met} {where}), baseline {units.text(c.metric, m['baseline'])} "
                "(`fuzzyservo margins`: the loop gain or added delay at which the loop starts "
                "to oscillate)"
            )
            continue
        lines.append(
            f"- `{c}`: best {units.text(c.metric, best.metrics.get(c.metric))} ({met}), "
            f"baseline {units.text(c.metric, base.metrics.get(c.metric))}"
        )
    if spec.constraints:
        lines.append("")
    if _same(check.values, best.values):
        lines.append(
            f"Re-simulating [{CONTROLLER_FILE}]({link('controller')}) reproduces the objective "
            f"{_values_text(best.values)}."
        )
    else:
        lines.append(
            f"**Warning:** re-simulating [{CONTROLLER_FILE}]({link('controller')}) gives "
            f"{_values_text(check.values)}, not the study's {_values_text(best.values)}."
        )
    files = [f"[{SUMMARY_FILE}]({link('summary')})"]
    if "fis" in paths:
        files.append(f"[{FIS_FILE}]({link('fis')}) (MATLAB Fuzzy Logic Designer)")
    lines += ["", "Also written: " + ", ".join(files) + ".", ""]

    if comparison is not None:
        lines += _comparison_lines(comparison, link, units)

    lines += ["## Best parameters", "", "| parameter | template | best | searched range |"]
    lines.append("|---|---:|---:|---|")
    for p in spec.parameters:
        scale = ", log" if p.log else (", integer" if p.integer else "")
        lines.append(
            f"| `{p.path}` | {_num(spec.template.params().get(p.path), 'not set')} | "
            f"{_num(outcome.best_params.get(p.path))} | [{p.low:g}, {p.high:g}]{scale} |"
        )
    lines.append("")

    lines += ["## Metrics", ""]
    lines += [f"### Aggregated ({spec.aggregate} over scenarios)", ""]
    lines += _metrics_table(base.metrics, best.metrics, evaluator.baseline.name, units)
    for scenario in spec.scenarios:
        lines += [f"### Scenario `{scenario}`", ""]
        lines += _metrics_table(
            base.scenario_metrics.get(scenario, {}),
            best.scenario_metrics.get(scenario, {}),
            evaluator.baseline.name,
            units,
        )
        lines += image(f"response_{_file_part(scenario)}", f"response on {scenario}")

    if spec.objective.pareto and outcome.pareto:
        names = spec.objective.pareto
        lines += ["## Pareto front", ""]
        lines += [
            f"{len(outcome.pareto)} non-dominated trials; the reported best is the one closest "
            "to the origin with each objective in units of the baseline's value.",
            "",
        ]
        lines.append("| trial | " + " | ".join(names) + " | |")
        lines.append("|---:|" + "---:|" * len(names) + "---|")
        for p in sorted(outcome.pareto, key=lambda p: p["values"][0]):
            mark = "reported best" if p["number"] == trial else ""
            lines.append(
                f"| {p['number']} | " + " | ".join(_num(v) for v in p["values"]) + f" | {mark} |"
            )
        lines.append("")
        lines += image("pareto", "Pareto front")

    lines += ["## Search", ""]
    lines += image("history", "trial history")
    if outcome.importances:
        lines += [
            "Parameter importances (Optuna's `get_param_importances`, normalised to sum to 1):",
            "",
            "| parameter | importance |",
        ]
        lines.append("|---|---:|")
        for name, value in sorted(outcome.importances.items(), key=lambda kv: -kv[1]):
            lines.append(f"| `{name}` | {value:.3f} |")
        lines.append("")
        lines += image("importances", "parameter importances")

    if "curve" in paths:
        lines += ["## Controller", ""]
        lines += image("curve", "control curve, template and best")
        lines += image("membership_before", "membership functions of the template")
        lines += image("membership_after", "membership functions of the best controller")

    lines += [
        "## Viewing the study in optuna-dashboard",
        "",
        "```",
        "pip install optuna-dashboard",
        f"optuna-dashboard {outcome.storage_url}",
        "```",
        "",
        "## Metric definitions",
        "",
    ]
    lines += [f"- `{m}`: {METRIC_DOCS[m]}" for m in METRIC_NAMES]
    return "\n".join(lines) + "\n"


def _metrics_table(
    base: dict[str, float], best: dict[str, float], base_name: str, units: MetricUnits
) -> list[str]:
    """Baseline and best side by side in display units; the ``n/a`` ones explained under it."""
    lines = [
        f"{LOWER_IS_BETTER.capitalize()}; change is the best against the baseline.",
        "",
        f"| metric | baseline ({base_name}) | best | change |",
        "|---|---:|---:|---:|",
    ]
    for m in METRIC_NAMES:
        b, n = base.get(m, math.nan), best.get(m, math.nan)
        unit = units.unit(m)
        lines.append(f"| `{m}`{f' [{unit}]' if unit else ''} | {_num(units.value(m, b))} | "
                     f"{_num(units.value(m, n))} | {change_text(b, n)} |")  # fmt: skip
    note = undefined_note(METRIC_NAMES, [base, best])
    return [*lines, "", *([note, ""] if note else [])]


def _same(a: tuple[float, ...], b: tuple[float, ...]) -> bool:
    return len(a) == len(b) and all(
        x == y or (math.isnan(x) and math.isnan(y)) for x, y in zip(a, b, strict=True)
    )


def _num(value: float | None, missing: str = "n/a") -> str:
    if value is None or not math.isfinite(value):
        return missing
    if value == 0:
        return "0"
    return f"{value:.4g}" if 1e-3 <= abs(value) < 1e5 else f"{value:.3e}"


def _values_text(values: tuple[float, ...] | list[float]) -> str:
    text = ", ".join(_num(v) for v in values)
    return text if len(values) == 1 else f"({text})"
