"""What a finished study concluded, computed once: the best controller scored again, the
margins its constraints bound, a robust study's comparison on fresh plants, and the
numbers of ``summary.json`` (:class:`StudyReport`, from :func:`study_report`).

:func:`fuzzyservo.workflows.write_study_report` writes the best controller's file,
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
from fuzzyservo.display import metric_units
from fuzzyservo.results import Result, json_ready
from fuzzyservo.tuning.evaluation import Evaluation
from fuzzyservo.tuning.objective import build_evaluator, measured_margins
from fuzzyservo.tuning.outcome import (
    StudyOutcome,
    best_trial_number,
    counts_text,
)
from fuzzyservo.tuning.uncertainty.robust import Comparison, compare_controllers
from fuzzyservo.tuning.uncertainty.robustness import comparison_text


@dataclass(frozen=True)
class StudyReport(Result):
    """A finished study with its best controller scored again.

    ``best_controller``: the best trial's controller as its file holds it; ``check``: that
    controller scored again on the study's objective; ``comparison``: a robust study's best,
    baseline and template on plants drawn afresh (None when not run);
    ``measured_margins``: {metric: {"best", "baseline"}} for the margins the constraints
    bound, measured on the nominal plant (None where the loop never oscillates)."""

    outcome: StudyOutcome = field(repr=False)
    best_controller: Controller
    check: Evaluation = field(repr=False)
    comparison: Comparison | None = field(default=None, repr=False)
    measured_margins: dict[str, dict[str, float | None]] = field(default_factory=dict)

    @property
    def trial(self) -> int | None:
        """The best trial's number (None when the outcome cannot name it)."""
        return best_trial_number(self.outcome)

    @property
    def baseline_name(self) -> str:
        return self.outcome.spec.baseline.name

    @property
    def reproduces(self) -> bool:
        """Whether the best controller, scored again, gives the study's objective."""
        return _same(self.check.values, self.outcome.best.values)

    def to_dict(self) -> dict[str, Any]:
        """The ``summary.json`` mapping (before NaN and inf become null): the outcome's
        (:meth:`StudyOutcome.to_dict`), the measured margins and the comparison."""
        summary = self.outcome.to_dict()
        if self.measured_margins:
            summary["measured_margins"] = self.measured_margins
        if self.comparison is not None:
            summary["comparison"] = self._comparison_data()
        return summary

    def _comparison_data(self) -> dict[str, Any]:
        c = self.comparison
        return {"samples": c.samples, "seed": c.seed, "gain_margin_checked": c.gain,
                "uncertainty": c.uncertainty, "controllers": c.rows()}  # fmt: skip

    def text(self) -> str:
        """What ``fuzzyservo tune`` prints when done: the outcome's lines
        (:meth:`StudyOutcome.text`) and, for a robust study, the comparison."""
        if self.comparison is None:
            return self.outcome.text()
        units = metric_units(self.outcome.spec.rig)
        comparison = json_ready(self._comparison_data())  # as summary.json holds it
        return f"{self.outcome.text()}\n{comparison_text(comparison, units)}"


def best_controller(outcome: StudyOutcome) -> Controller:
    """The study's template with the best trial's parameters, named ``<study>_best``."""
    return outcome.spec.trial_controller(outcome.best_params, f"{outcome.spec.name}_best")


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


def _same(a: tuple[float, ...], b: tuple[float, ...]) -> bool:
    return len(a) == len(b) and all(
        x == y or (math.isnan(x) and math.isnan(y)) for x, y in zip(a, b, strict=True)
    )
