"""A trial's work: put the proposed numbers into the template, simulate every scenario, score.

Pure of Optuna: :class:`Evaluator` maps a parameter dictionary to an :class:`Evaluation`,
so a study, a test and the report all score a controller the same way.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import re
import time
from dataclasses import dataclass, field
from typing import Any

from fuzzyservo.controllers.base import Controller
from fuzzyservo.metrics import METRIC_NAMES, result_metrics
from fuzzyservo.rig import Rig
from fuzzyservo.simulation import SimResult, simulate
from fuzzyservo.tuning.spec import MARGIN_METRICS, Constraint, StudySpec

_STEP = re.compile(r"([^.\[\]]+)|\[(\d+)\]")


def split_path(path: str) -> list[str | int]:
    """``'input.increments[3]'`` → ``['input', 'increments', 3]``."""
    parts: list[str | int] = []
    for name, index in _STEP.findall(path):
        parts.append(int(index) if index else name)
    rebuilt = "".join(f"[{p}]" if isinstance(p, int) else f".{p}" for p in parts).lstrip(".")
    if not parts or rebuilt != path:
        raise ValueError(
            f"cannot read parameter path {path!r}; write it like 'input.reshape' or 'input.increments[3]'"
        )
    return parts


def set_path(data: dict[str, Any], path: str, value: float) -> None:
    """Set a number inside a template mapping; a missing last key is added, anything else must exist."""
    parts = split_path(path)
    node: Any = data
    for depth, part in enumerate(parts[:-1]):
        nxt = parts[depth + 1]
        where = path_text(parts[: depth + 1])
        if isinstance(part, int):
            if not isinstance(node, list) or part >= len(node):
                raise ValueError(f"{path}: the template has no element {where}")
            node = node[part]
            continue
        if not isinstance(node, dict):
            raise ValueError(f"{path}: {where} is not a mapping in the template")
        if part not in node:
            if isinstance(nxt, int):
                raise ValueError(
                    f"{path}: the template has no list {where}; write the whole list in the template"
                )
            node[part] = {}
        node = node[part]
    last = parts[-1]
    if isinstance(last, int):
        if not isinstance(node, list) or last >= len(node):
            raise ValueError(f"{path}: the template's list has no element [{last}]")
        if not isinstance(node[last], int | float):
            raise ValueError(f"{path}: the template holds {node[last]!r} there, not a number")
        node[last] = value
        return
    if not isinstance(node, dict):
        raise ValueError(f"{path}: the parent of {last!r} is not a mapping in the template")
    if last in node and (isinstance(node[last], bool) or not isinstance(node[last], int | float)):
        raise ValueError(f"{path}: the template holds {node[last]!r} there, not a number")
    node[last] = value


def path_text(parts: list[str | int]) -> str:
    return "".join(f"[{p}]" if isinstance(p, int) else f".{p}" for p in parts).lstrip(".")


@dataclass(frozen=True)
class Evaluation:
    """A controller scored on the study's scenarios."""

    values: tuple[float, ...]
    metrics: dict[str, float]
    scenario_metrics: dict[str, dict[str, float]]
    violations: tuple[float, ...]
    status: str
    message: str = ""
    sim_time_s: float = 0.0
    results: dict[str, SimResult] = field(default_factory=dict, repr=False)
    simulations: int = 0  # runs it took (robust studies count them; 0: not counted)

    @property
    def feasible(self) -> bool:
        return self.status == "ok" and all(v <= 0 for v in self.violations)


class Evaluator:
    """Scores controllers built from the template for one study."""

    def __init__(
        self,
        spec: StudySpec,
        rig: Rig,
        template: dict[str, Any],
        baseline: Controller,
    ):
        from fuzzyservo.io.controllers import controller_from_data

        self.spec = spec
        self.rig = rig
        self.template = template
        self._build = controller_from_data
        self.baseline = baseline
        self.scale: dict[str, float] = {m: 1.0 for m in spec.objective.metrics}
        self.sample_rigs: list[Rig] = []
        if spec.uncertainty is not None:  # a robust study: every trial on the same samples
            from fuzzyservo.tuning.robust import sample_rigs

            self.sample_rigs = sample_rigs(rig, spec)
        self.baseline_evaluation = self.evaluate(baseline, keep_results=True)
        if spec.objective.normalize == "baseline":
            base = self.baseline_evaluation
            for m in spec.objective.metrics:
                v = base.metrics.get(m, math.nan)
                self.scale[m] = v if math.isfinite(v) and v > 0 else 1.0
            self.baseline_evaluation = dataclasses.replace(base, values=self._values(base.metrics))

    def data(self, params: dict[str, float]) -> dict[str, Any]:
        """The template mapping with the parameters filled in."""
        data = copy.deepcopy(self.template)
        for path, value in params.items():
            set_path(data, path, value)
        data["name"] = f"{self.spec.name}_best"
        return data

    def controller(self, params: dict[str, float], name: str | None = None) -> Controller:
        data = self.data(params)
        if name:
            data["name"] = name
        return self._build(
            data, f"{self.spec.controller_file} (with {', '.join(params) or 'no changes'})"
        )

    def evaluate(
        self, controller: Controller, *, keep_results: bool = False, report=None
    ) -> Evaluation:
        """Simulate every scenario, aggregate the metrics, compute objective(s) and constraints
        (on every sampled plant for a study with ``uncertainty``: tuning/robust.py)."""
        spec = self.spec
        if spec.uncertainty is not None:
            from fuzzyservo.tuning.robust import evaluate_samples

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
        sim_time = time.perf_counter() - t0
        metrics = {}
        for m in METRIC_NAMES:
            vals = [per[s][m] for s in spec.scenarios]
            if any(not math.isfinite(v) for v in vals):
                metrics[m] = math.nan
            elif spec.aggregate == "worst":
                metrics[m] = max(vals)
            else:
                metrics[m] = sum(vals) / len(vals)
        values = self._values(metrics)
        margin_constraints = [c for c in spec.constraints if c.metric in MARGIN_METRICS]
        if status == "ok" and margin_constraints and self._worth_margins(metrics, values):
            metrics.update(
                margin_metrics(self.rig, controller, spec.scenarios[0], margin_constraints)
            )
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
        base = getattr(self, "baseline_evaluation", None)
        if base is None or self.spec.objective.pareto or base.status != "ok":
            return True
        return values[0] <= base.values[0]

    def _values(self, metrics: dict[str, float]) -> tuple[float, ...]:
        obj = self.spec.objective
        if obj.pareto:
            return tuple(metrics[m] for m in obj.pareto)
        return (sum(w * metrics[m] / self.scale[m] for m, w in obj.weights.items()),)


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
