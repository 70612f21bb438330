"""One trial's work, pure of Optuna: sampled numbers in, a :class:`TrialResult` out.

The same function scores a trial in the parent (one worker), in a local worker process
and on a Dask worker (:mod:`fuzzyservo.executor`), so where a trial runs never changes
its result. A trial uses no random number of its own: a robust study's plants and noise
are the study's draws (:func:`~fuzzyservo.tuning.uncertainty.robust.sample_rigs`, fixed by the
study's uncertainty seed), the same for every trial.

Pruning (robust studies, one objective, ``worst`` aggregate): the trial stops once its
worst sample so far exceeds ``bound``, the best feasible value told before the trial's
batch, which is exact (the worst can only grow) and the same wherever the trial runs.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

from fuzzyservo.tuning.objective import Evaluator
from fuzzyservo.tuning.spec import Study


@dataclass(frozen=True)
class TrialResult:
    """What a trial tells the study: its value(s), or that it was pruned at ``step`` with
    ``value`` (its worst sample so far); its constraint violations and the attributes the
    report reads (status, message, metrics, simulations, times)."""

    values: tuple[float, ...]
    constraints: tuple[float, ...]
    user_attrs: dict[str, Any] = field(default_factory=dict)
    pruned_at: tuple[int, float] | None = None


@dataclass(frozen=True)
class Task:
    """A trial to score: its number in the study, its sampled numbers, the pruning bound."""

    number: int
    params: dict[str, float]
    bound: float | None = None


def score(spec: Study, evaluator: Evaluator, params: dict[str, float],
          bound: float | None) -> TrialResult:  # fmt: skip
    """Score the template with ``params`` (see the module docstring)."""
    t0 = time.perf_counter()
    started = time.time()
    try:
        controller = evaluator.controller(params)  # the template's name: no second build
    except ValueError as exc:  # a combination the template rejects: penalised, reason kept
        return TrialResult(
            values=tuple(spec.penalty for _ in range(spec.objective.n_values)),
            constraints=tuple(1e300 for _ in spec.constraints),
            user_attrs={"status": "invalid", "message": str(exc)},
        )
    built = time.perf_counter()
    report = None
    last: list[tuple[int, float]] = []
    if spec.uncertainty is not None and spec.objective.n_values == 1:

        def report(step: int, value: float) -> bool:
            last[:] = [(step, value)]
            return bound is not None and value > bound

    ev = evaluator.evaluate(controller, report=report)
    attrs: dict[str, Any] = {"status": ev.status}
    if ev.message:
        attrs["message"] = ev.message
    attrs["metrics"] = {k: (v if math.isfinite(v) else None) for k, v in ev.metrics.items()}
    attrs["sim_time_s"] = ev.sim_time_s
    if ev.simulations:
        attrs["simulations"] = ev.simulations
    if ev.sample_values:
        attrs["sample_values"] = [v if math.isfinite(v) else None for v in ev.sample_values]
    attrs["trial_time_s"] = time.perf_counter() - t0
    # where the time went besides simulating (bench, the report); the runner adds its
    # sampler's share (sample_s)
    # and when it ran (seconds since the epoch: where the workers' time went, outcome.py)
    attrs["work"] = {"build_s": built - t0, "samples_skipped": ev.samples_skipped,
                     "started": started, "ended": time.time()}  # fmt: skip
    return TrialResult(
        values=ev.values,
        constraints=tuple(v if math.isfinite(v) else 1e300 for v in ev.violations),
        user_attrs=attrs,
        pruned_at=last[0] if ev.status == "pruned" else None,
    )


_EVALUATORS: dict[str, Evaluator] = {}


class TrialRunner:
    """A picklable ``Task -> TrialResult`` for an executor: the study travels with it and
    each process builds its :class:`Evaluator` (the baseline's score, the sampled plants,
    the compiled kernels) once per study (``key``: the study's fingerprint)."""

    def __init__(self, spec: Study, key: str):
        self.spec = spec
        self.key = key

    def evaluator(self) -> Evaluator:
        found = _EVALUATORS.get(self.key)
        if found is None:
            _EVALUATORS.clear()  # one study at a time per process
            found = _EVALUATORS[self.key] = Evaluator(self.spec)
        return found

    def __call__(self, task: Task) -> TrialResult:
        return score(self.spec, self.evaluator(), task.params, task.bound)

    def warm(self, worker: int = 0) -> None:
        """Make a worker ready before its first trial: the evaluator built, the compiled
        kernels loaded (``worker``: which of the executor's warm-up tasks this is)."""
        self.evaluator()
        warm_kernels(self.spec)


def warm_kernels(spec: Study) -> None:
    """Run the study's kernels once, briefly: the first time on a machine this compiles
    them (minutes' worth of work done once, then cached); afterwards it loads them from
    the cache, which takes a fraction of a second."""
    from fuzzyservo.simulation import simulate

    rig = spec.rig
    simulate(rig, spec.template, spec.scenarios[0], duration_s=10 * rig.sample_time_s)
    if spec.uncertainty is not None:  # its trials run their samples' checks in lock-step
        from fuzzyservo.simulation.closed_loop import simulate_batch
        from fuzzyservo.tuning.uncertainty.robust import sample_rigs

        seeds = [d.noise_seed for d in spec.uncertainty.draws[:2]]
        simulate_batch(sample_rigs(rig, spec)[:2], spec.template, spec.scenarios[0], seeds)
