"""A trial's work: turn the proposed numbers into a controller, simulate every scenario, score.

Pure of Optuna: :class:`Evaluator` maps a parameter dictionary to an :class:`Evaluation`,
so a study, a test and the report all score a controller the same way. The controller
comes from the study's template through its own ``with_params``
(:meth:`~fuzzyservo.tuning.spec.Study.trial_controller`): no dictionaries, no re-parsing.
"""

from __future__ import annotations

import dataclasses
import math
import time

from fuzzyservo.controllers.base import Controller
from fuzzyservo.metrics import METRIC_NAMES, result_metrics
from fuzzyservo.rig import Rig
from fuzzyservo.simulation import SimResult, simulate
from fuzzyservo.tuning.evaluation import Evaluation
from fuzzyservo.tuning.spec import MARGIN_METRICS, Constraint, Study
from fuzzyservo.tuning.uncertainty.robust import evaluate_samples, sample_rigs


class Evaluator:
    """Scores controllers built from the template for one study (``spec``)."""

    def __init__(self, spec: Study):
        self.spec = spec
        self.rig: Rig = spec.rig
        self.baseline: Controller = spec.baseline
        self.scale: dict[str, float] = {m: 1.0 for m in spec.objective.metrics}
        self.sample_rigs: list[Rig] = []
        if spec.uncertainty is not None:  # a robust study: every trial on the same samples
            self.sample_rigs = sample_rigs(self.rig, spec)
        self._baseline: Evaluation | None = None
        self._scoring_baseline = False
        if spec.objective.normalize == "baseline":  # the scale is the baseline's: score it now
            self._score_baseline()

    @property
    def baseline_evaluation(self) -> Evaluation:
        """The baseline scored as a trial is (with its results kept, for the report's
        plots). Scored on first use: a worker process that only scores trials needs it
        only when the objective is normalised by it (a robust study's baseline costs a
        run per sample and scenario, and a margin check per sample)."""
        if self._baseline is None:
            self._score_baseline()
        return self._baseline

    def _score_baseline(self) -> None:
        spec = self.spec
        self._scoring_baseline = True
        try:
            base = self.evaluate(self.baseline, keep_results=True)
        finally:
            self._scoring_baseline = False
        if spec.objective.normalize == "baseline":
            for m in spec.objective.metrics:
                v = base.metrics.get(m, math.nan)
                self.scale[m] = v if math.isfinite(v) and v > 0 else 1.0
            base = dataclasses.replace(base, values=self.objective_values(base.metrics))
        self._baseline = base

    def controller(self, params: dict[str, float], name: str | None = None) -> Controller:
        """The template with the trial's ``params`` (``ValueError`` when they make none)."""
        return self.spec.trial_controller(params, name or "")

    def evaluate(
        self, controller: Controller, *, keep_results: bool = False, report=None
    ) -> Evaluation:
        """Simulate every scenario, aggregate the metrics, compute objective(s) and constraints
        (on every sampled plant for a study with ``uncertainty``: tuning/uncertainty/robust.py)."""
        spec = self.spec
        if spec.uncertainty is not None:
            return evaluate_samples(self, controller, keep_results=keep_results, report=report)
        t0 = time.perf_counter()
        per: dict[str, dict[str, float]] = {}
        results: dict[str, SimResult] = {}
        status, message = "ok", ""
        for scenario in spec.scenarios:
            r = simulate(self.rig, controller, scenario)
            if keep_results:
                results[scenario] = r
            per[scenario] = result_metrics(r).aggregate
            if r.status != "ok" and status == "ok":
                status, message = r.status, f"{scenario}: {r.message}"
        sim_time = time.perf_counter() - t0  # the margin checks' runs are added below
        metrics = {}
        for m in METRIC_NAMES:
            vals = [per[s][m] for s in spec.scenarios]
            if any(not math.isfinite(v) for v in vals):
                metrics[m] = math.nan
            elif spec.aggregate == "worst":
                metrics[m] = max(vals)
            else:
                metrics[m] = sum(vals) / len(vals)
        values = self.objective_values(metrics)
        margin_constraints = [c for c in spec.constraints if c.metric in MARGIN_METRICS]
        if status == "ok" and margin_constraints and self._worth_margins(metrics, values):
            checked = time.perf_counter()
            metrics.update(
                margin_metrics(self.rig, controller, spec.scenarios[0], margin_constraints)
            )
            sim_time += time.perf_counter() - checked
        violations = tuple(c.violation(metrics.get(c.metric, math.nan)) for c in spec.constraints)
        if status == "ok" and not all(math.isfinite(v) for v in values):
            bad = [m for m in spec.objective.metrics if not math.isfinite(metrics[m])]
            status, message = (
                "undefined",
                f"metric(s) {', '.join(bad)} undefined (e.g. never settles)",
            )
        if status != "ok":
            values = tuple(spec.penalty for _ in values)
        return Evaluation(
            values=values,
            metrics=metrics,
            scenario_metrics=per,
            violations=violations,
            status=status,
            message=message,
            sim_time_s=sim_time,
            results=results,
        )

    def _worth_margins(self, metrics: dict[str, float], values: tuple[float, ...]) -> bool:
        """Margins cost simulations, so they are decided only for a trial that meets every
        other constraint and, on a single objective, is no worse than the baseline; any
        other trial keeps its margin metrics undefined, which counts as violated."""
        others = [c for c in self.spec.constraints if c.metric not in MARGIN_METRICS]
        if any(c.violation(metrics.get(c.metric, math.nan)) > 0 for c in others):
            return False
        if self._scoring_baseline:
            return True  # the baseline itself: no reference to be worse than
        base = self.baseline_evaluation
        if self.spec.objective.pareto or base.status != "ok":
            return True
        return values[0] <= base.values[0]

    def objective_values(self, metrics: dict[str, float]) -> tuple[float, ...]:
        """The study's objective value(s) of a set of metrics."""
        obj = self.spec.objective
        if obj.pareto:
            return tuple(metrics[m] for m in obj.pareto)
        return (sum(w * metrics[m] / self.scale[m] for m, w in obj.weights.items()),)


def build_evaluator(spec: Study) -> Evaluator:
    """The trial evaluator of a study (it scores the baseline first)."""
    return Evaluator(spec)


def margin_metrics(
    rig: Rig, controller: Controller, scenario: str, constraints: list[Constraint]
) -> dict[str, float]:
    """The margin constraints' verdicts (analysis/margins.py), one simulation of
    ``scenario`` each for a ``>=`` constraint: a loop that does not oscillate at the
    bound (output multiplied by it, or that much extra delay) has its margin recorded as
    the bound itself, a lower bound that meets the constraint; one that oscillates there
    has it undefined (below the bound: violated). The value itself is what `fuzzyservo
    margins` measures on the study's best. A ``<=`` constraint needs the value, by
    bisection to 2 % (about ten simulations per margin)."""
    from fuzzyservo.analysis.margins import delay_margin, gain_margin, stable_at

    out: dict[str, float] = {}
    for c in constraints:
        gain = c.metric == "gain_margin"
        if c.op == ">=":
            kwargs = {"multiplier": c.bound} if gain else {"extra_delay_s": c.bound}
            out[c.metric] = c.bound if stable_at(rig, controller, scenario, **kwargs) else math.nan
        else:
            find = gain_margin if gain else delay_margin
            out[c.metric] = find(rig, controller, scenario, rel_tol=0.02).value
    return out


def measured_margins(
    rig: Rig, controller: Controller, scenario: str, constraints: list[Constraint]
) -> dict[str, float]:
    """The margins the margin constraints bound, measured (by bisection to 2 %, as
    ``fuzzyservo margins`` does) on the nominal ``rig``: what a report puts next to each
    bound, where the search itself only checked the loop at the bound."""
    from fuzzyservo.analysis.margins import delay_margin, gain_margin

    out: dict[str, float] = {}
    for c in constraints:
        if c.metric in MARGIN_METRICS and c.metric not in out:
            find = gain_margin if c.metric == "gain_margin" else delay_margin
            out[c.metric] = find(rig, controller, scenario, rel_tol=0.02).value
    return out
