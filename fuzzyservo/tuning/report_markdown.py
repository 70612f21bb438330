"""A tuned study's ``report.md`` as text (as :mod:`fuzzyservo.calibration.report` renders a
calibration's): the study, the result, the comparison on fresh plants, the best
parameters, the metrics per scenario, the Pareto front, the search and the controller,
figures linked by the paths :func:`fuzzyservo.io.study_report.write_study_files` gives."""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from pathlib import Path

from fuzzyservo.display import (
    LOWER_IS_BETTER,
    TRIAL_COUNTS_NOTE,
    MetricUnits,
    change_text,
    elapsed_text,
    metric_units,
    undefined_note,
)
from fuzzyservo.metrics import METRIC_DOCS, METRIC_NAMES
from fuzzyservo.tuning.outcome import (
    StudyOutcome,
    counts_text,
    si_note,
    status_text,
    time_split,
)
from fuzzyservo.tuning.report import StudyReport, number_text, values_text
from fuzzyservo.tuning.uncertainty.robust import Comparison


def comparison_lines(comparison: Comparison, link, units: MetricUnits) -> list[str]:
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
        "| objective | " + " | ".join(number_text(r["nominal"]["objective"]) for r in rows) + " |"
    )
    for key, label, unit, k in shown:
        cells = [number_text(r["nominal"][key] * k) for r in rows]
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
            "/".join(number_text(r[key][q] * k, "never") for q in ("p50", "p90", "worst"))
            for r in rows
        ]
        lines.append(f"| {label}: median/90 %/worst [{unit}] | " + " | ".join(cells) + " |")
    lines += ["", f"![Monte Carlo distributions]({link('check')})", ""]
    return lines


def trials_text(outcome: StudyOutcome) -> str:
    """Asked, complete, pruned and failed trials, and for a robust study its simulations
    and the sampled plants its trials skipped."""
    text = counts_text(outcome)
    if outcome.samples_skipped:
        text += f" ({outcome.samples_skipped} sampled plants skipped: decided before them)"
    if outcome.simulations:
        text += f"; {outcome.simulations} simulations"
    return text


def split_text(outcome: StudyOutcome) -> str:
    """The trials' time by what it went to (a study stored before the split was
    recorded: simulation and the rest)."""
    if not outcome.sampler_time_s:
        rest_s = max(0.0, outcome.worker_time_s - outcome.sim_time_s)
        return (f"simulation {elapsed_text(outcome.sim_time_s)}, sampler, storage and controller "
                f"building {elapsed_text(rest_s)}")  # fmt: skip
    return ", ".join(f"{k} {elapsed_text(v)}" for k, v in time_split(outcome).items())


def selection_lines(outcome: StudyOutcome) -> list[str]:
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


def file_part(name: str) -> str:
    return re.sub(r"[^\w.-]", "_", name)


def report_markdown(report: StudyReport, links: Mapping[str, str]) -> str:
    """The study's ``report.md``: ``links`` maps each written file's role (``controller``,
    ``summary``, ``fis``, ``check``, ``history``, ``response_<scenario>`` ...; see
    :func:`fuzzyservo.io.study_report.write_study_files`) to its path relative to the
    report; a figure whose role is absent is left out."""
    outcome, trial = report.outcome, report.trial
    spec = outcome.spec
    best, base = outcome.best, outcome.baseline
    measured = report.measured_margins
    units = metric_units(spec.rig)

    def link(key: str) -> str:
        return links[key]

    def image(key: str, alt: str) -> list[str]:
        return [f"![{alt}]({link(key)})", ""] if key in links else []

    lines = [f"# Tuning study `{spec.name}`", ""]
    if spec.description:
        lines += [spec.description.strip(), ""]
    sampler = spec.sampler + (f" (seed {spec.seed})" if spec.seed is not None else "")
    lines += [
        "| | |",
        "|---|---|",
        f"| study file | `{spec.path or '-'}` |",
        f"| rig | {spec.rig.name}" + (f" (`{spec.rig.path}`)" if spec.rig.path else "") + " |",
        f"| scenarios | {', '.join(spec.scenarios)} ({spec.aggregate} over scenarios) |",
        f"| template | {spec.template.name} |",
        f"| baseline | {report.baseline_name} |",
        f"| objective | {spec.objective.describe()} (minimised{si_note(spec, units)}) |",
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
        f"| trials | {trials_text(outcome)} |",
        f"| optimisation time (this run) | {elapsed_text(outcome.wall_s)} (compiling and the "
        "trials; not the check on fresh samples nor this report) |",
        f"| time in trials | {split_text(outcome)} (summed over the stored trials) |",
        f"| storage | `{outcome.storage_url}` |",
        "",
        f"Trials: {TRIAL_COUNTS_NOTE}.",
        "",
        "## Result",
        "",
    ]
    lines += selection_lines(outcome)
    which = "the reported best" if trial is None else f"trial #{trial}"
    lines += [
        f"Best: {which}, objective {values_text(best.values)} against the baseline's "
        f"{values_text(base.values)}; status {status_text(best)}, "
        f"{'feasible' if best.feasible else 'infeasible'}."
        + (f" The baseline's status: {status_text(base)}." if base.status != "ok" else ""),
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
    if report.reproduces:
        lines.append(
            f"Re-simulating [{Path(link('controller')).name}]({link('controller')}) reproduces the objective "
            f"{values_text(best.values)}."
        )
    else:
        lines.append(
            f"**Warning:** re-simulating [{Path(link('controller')).name}]({link('controller')}) gives "
            f"{values_text(report.check.values)}, not the study's {values_text(best.values)}."
        )
    files = [f"[{Path(link('summary')).name}]({link('summary')})"]
    if "fis" in links:
        files.append(f"[{Path(link('fis')).name}]({link('fis')}) (MATLAB Fuzzy Logic Designer)")
    lines += ["", "Also written: " + ", ".join(files) + ".", ""]

    if report.comparison is not None:
        lines += comparison_lines(report.comparison, link, units)

    lines += ["## Best parameters", "", "| parameter | template | best | searched range |"]
    lines.append("|---|---:|---:|---|")
    for p in spec.parameters:
        scale = ", log" if p.log else (", integer" if p.integer else "")
        lines.append(
            f"| `{p.path}` | {number_text(spec.template.params().get(p.path), 'not set')} | "
            f"{number_text(outcome.best_params.get(p.path))} | [{p.low:g}, {p.high:g}]{scale} |"
        )
    lines.append("")

    lines += ["## Metrics", ""]
    lines += [f"### Aggregated ({spec.aggregate} over scenarios)", ""]
    lines += metrics_lines(base.metrics, best.metrics, report.baseline_name, units)
    for scenario in spec.scenarios:
        lines += [f"### Scenario `{scenario}`", ""]
        lines += metrics_lines(
            base.scenario_metrics.get(scenario, {}),
            best.scenario_metrics.get(scenario, {}),
            report.baseline_name,
            units,
        )
        lines += image(f"response_{file_part(scenario)}", f"response on {scenario}")

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
                f"| {p['number']} | "
                + " | ".join(number_text(v) for v in p["values"])
                + f" | {mark} |"
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

    if "curve" in links:
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


def metrics_lines(
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
        lines.append(f"| `{m}`{f' [{unit}]' if unit else ''} | {number_text(units.value(m, b))} | "
                     f"{number_text(units.value(m, n))} | {change_text(b, n)} |")  # fmt: skip
    note = undefined_note(METRIC_NAMES, [base, best])
    return [*lines, "", *([note, ""] if note else [])]
