"""What a finished study concluded, computed once: the best controller scored again, the
margins its constraints bound, a robust study's comparison on fresh plants, and the
numbers of ``summary.json`` (:class:`StudyReport`, from :func:`study_report`).

:func:`fuzzyservo.io.study_report.write_study_report` writes the best controller's file,
reads it back and has it scored here (the file, not the in-memory mapping, is what users
run), then writes the report's files; ``fuzzyservo tune`` prints :meth:`StudyReport.text`
and ``--json`` is :meth:`StudyReport.to_dict`, the same mapping as ``summary.json``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from fuzzyservo.controllers.base import Controller
from fuzzyservo.display import (
    LOWER_IS_BETTER,
    MetricUnits,
    metric_units,
    metrics_table,
    trial_counts_text,
    undefined_note,
)
from fuzzyservo.metrics import METRIC_NAMES, format_value
from fuzzyservo.results import Result, json_ready
from fuzzyservo.tuning.evaluation import Evaluation
from fuzzyservo.tuning.objective import build_evaluator, measured_margins
from fuzzyservo.tuning.outcome import StudyOutcome
from fuzzyservo.tuning.uncertainty.robust import Comparison, compare_controllers
from fuzzyservo.tuning.uncertainty.robustness import comparison_text


@dataclass(frozen=True)
class StudyReport(Result):
    """A finished study with its best controller scored again.

    ``best_controller``: the best trial's controller as its file holds it; ``check``: that
    controller scored again on the study's objective; ``trial``: the best trial's number
    (None when the outcome cannot name it); ``comparison``: a robust study's best,
    baseline and template on plants drawn afresh (None when not run);
    ``measured_margins``: {metric: {"best", "baseline"}} for the margins the constraints
    bound, measured on the nominal plant (None where the loop never oscillates)."""

    outcome: StudyOutcome = field(repr=False)
    best_controller: Controller
    baseline_name: str
    trial: int | None
    check: Evaluation = field(repr=False)
    comparison: Comparison | None = field(default=None, repr=False)
    measured_margins: dict[str, dict[str, float | None]] = field(default_factory=dict)

    @property
    def reproduces(self) -> bool:
        """Whether the best controller, scored again, gives the study's objective."""
        return _same(self.check.values, self.outcome.best.values)

    def to_dict(self) -> dict[str, Any]:
        """The ``summary.json`` mapping (before NaN and inf become null)."""
        summary = _summary(self.outcome, self.baseline_name, self.trial)
        if self.measured_margins:
            summary["measured_margins"] = self.measured_margins
        if self.comparison is not None:
            summary["comparison"] = {
                "samples": self.comparison.samples,
                "seed": self.comparison.seed,
                "gain_margin_checked": self.comparison.gain,
                "uncertainty": self.comparison.uncertainty,
                "controllers": self.comparison.rows(),
            }
        return summary

    def text(self) -> str:
        """What ``fuzzyservo tune`` prints when done: the trial counts, the metrics of the
        baseline and the best in display units (``n/a`` explained), the objective and,
        for a robust study, the comparison."""
        outcome = self.outcome
        units = metric_units(outcome.spec.rig)
        best, base = outcome.best, outcome.baseline
        rows = [base.metrics, best.metrics]
        names = [f"baseline {outcome.spec.baseline.name}", "best"]
        lines = [
            f"trials: {counts_text(outcome)}",
            f"metrics, worst over the scenarios{' and samples' if outcome.spec.uncertainty else ''}"
            f" ({LOWER_IS_BETTER}; change: best against the baseline):",
            metrics_table(names, rows, units, change=True),
        ]
        if note := undefined_note(METRIC_NAMES, rows):
            lines.append(note)
        values = [", ".join(format_value(v) for v in e.values) for e in (best, base)]
        lines.append(f"objective: best {values[0]} against baseline {values[1]} "
                     f"({outcome.spec.objective.describe()}{si_note(outcome.spec, units)})")  # fmt: skip
        for who, e in (("best", best), ("baseline", base)):
            if e.status != "ok":  # its objective is the penalty or undefined: say why
                lines.append(f"{who}: status {status_text(e)}")
        if self.comparison is not None:
            lines.append(comparison_text(json_ready(self.to_dict())["comparison"], units))
        return "\n".join(lines)


def best_controller(outcome: StudyOutcome) -> Controller:
    """The study's template with the best trial's parameters, named ``<study>_best``."""
    spec = outcome.spec
    return build_evaluator(spec).controller(outcome.best_params, name=f"{spec.name}_best")


def best_description(outcome: StudyOutcome, trial: int | None) -> str:
    """The best controller file's ``description``: where it comes from and what it scored."""
    spec = outcome.spec
    return (
        f"Best {'trial' if trial is None else f'trial #{trial}'} of tuning study {spec.name} "
        f"({spec.path or 'no study file'}; trials {counts_text(outcome)}) on "
        f"scenarios {', '.join(spec.scenarios)}; objective {spec.objective.describe()} = "
        f"{values_text(outcome.best.values)} (baseline {values_text(outcome.baseline.values)}). "
        f"Template: {spec.template.name}."
    )


def study_report(
    outcome: StudyOutcome,
    best: Controller | None = None,
    *,
    check_samples: int | None = None,
    progress: Callable[[int], object] | None = None,
) -> StudyReport:
    """Score ``best`` (default: :func:`best_controller`) again on the study's objective,
    measure the margins its constraints bound and, for a robust study, compare it with
    the baseline and the template on ``check_samples`` plants drawn afresh from the
    study's uncertainty (default: as many as the study's own samples; 0: no comparison;
    :func:`~fuzzyservo.tuning.uncertainty.robust.compare_controllers`, ``progress(1)`` per sampled
    plant and controller)."""
    spec = outcome.spec
    evaluator = build_evaluator(spec)
    best = best if best is not None else best_controller(outcome)
    comparison = None
    if spec.uncertainty is not None and check_samples != 0:
        n = spec.uncertainty.samples if check_samples is None else check_samples
        comparison = compare_controllers(evaluator, comparison_controllers(evaluator, best),
                                         samples=n, progress=progress)  # fmt: skip
    return StudyReport(
        outcome=outcome,
        best_controller=best,
        baseline_name=evaluator.baseline.name,
        trial=best_trial_number(outcome),
        check=evaluator.evaluate(best),
        comparison=comparison,
        measured_margins=_measured_margins(evaluator, best),
    )


def comparison_controllers(evaluator: Any, best: Controller) -> list[Controller]:
    """The best controller, the baseline and the template (when it is not the baseline)."""
    spec = evaluator.spec
    controllers = [best, evaluator.baseline]
    if spec.template != spec.baseline:
        controllers.append(spec.template)
    return controllers


def _measured_margins(evaluator: Any, best: Controller) -> dict[str, dict[str, float | None]]:
    spec = evaluator.spec
    scenario = spec.uncertainty.margin_scenario if spec.uncertainty is not None else ""
    scenario = scenario or spec.scenarios[0]
    out: dict[str, dict[str, float | None]] = {}
    for who, controller in (("best", best), ("baseline", evaluator.baseline)):
        found = measured_margins(evaluator.rig, controller, scenario, list(spec.constraints))
        for metric, value in found.items():
            out.setdefault(metric, {})[who] = value if math.isfinite(value) else None
    return out


def best_trial_number(outcome: StudyOutcome) -> int | None:
    """The number of the trial the outcome reports as best (as the runner picks it)."""
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


def _summary(outcome: StudyOutcome, baseline_name: str, trial: int | None) -> dict[str, Any]:
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
            # on fresh samples (the winner of the top trials there: tuning/uncertainty/noise.py)
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


def counts_text(outcome: StudyOutcome) -> str:
    """Asked, complete, pruned and failed trials (a study collected before the asked
    and failed ones were counted: complete and pruned are all it asked)."""
    asked = outcome.trials_asked or outcome.trials_complete + outcome.trials_pruned
    return trial_counts_text(asked, outcome.trials_complete, outcome.trials_pruned,
                             outcome.trials_failed)  # fmt: skip


def si_note(spec: Any, units: MetricUnits) -> str:
    """The objective weighs metrics in SI: say so for those the tables show in another
    unit (``sse_abs`` in m, shown in mm)."""
    si = [f"{m} in {units.si(m)}" for m in spec.objective.metrics if units.unit(m) != units.si(m)]
    return f"; over the metrics in SI: {', '.join(si)}" if si else ""


def status_text(ev: Evaluation) -> str:
    """A scored controller's status and why (an objective that is the penalty or n/a)."""
    return ev.status + (f" ({ev.message})" if ev.message else "")


def number_text(value: float | None, missing: str = "n/a") -> str:
    """A number for a report's table: four significant digits, ``missing`` for none."""
    if value is None or not math.isfinite(value):
        return missing
    if value == 0:
        return "0"
    return f"{value:.4g}" if 1e-3 <= abs(value) < 1e5 else f"{value:.3e}"


def values_text(values: tuple[float, ...] | list[float]) -> str:
    """An objective's value, or its values in parentheses (a Pareto study)."""
    text = ", ".join(number_text(v) for v in values)
    return text if len(values) == 1 else f"({text})"


def _objective_value(ev: Evaluation) -> float | list[float]:
    return ev.values[0] if len(ev.values) == 1 else list(ev.values)


def _same(a: tuple[float, ...], b: tuple[float, ...]) -> bool:
    return len(a) == len(b) and all(
        x == y or (math.isnan(x) and math.isnan(y)) for x, y in zip(a, b, strict=True)
    )
