"""A trial on a study's sampled plants (its ``uncertainty:``), scored as one Evaluation.

Every sample runs every scenario (metrics aggregated over the scenarios by the study's
``aggregate``); each sample gets its objective value; the trial's value is their worst,
mean or CVaR (:func:`~fuzzyservo.tuning.uncertainty.aggregate`). A trial where any sample
diverges, fails a step or hits an end stop is infeasible with that sample as its reason
(and the remaining samples are skipped); a constraint counts broken when it is broken on
any sample; ``gain_margin >= g`` and ``delay_margin_s >= d`` are checked on every sample
with one run each (:func:`~fuzzyservo.tuning.uncertainty.robustness.margin_checks`), once every
sample ran through: a trial pruned or failed on its k-th sample pays for no margin check
(the checks decide neither, so the result is the same). The samples a trial never ran
are counted (``Evaluation.samples_skipped``; the study's ``samples_skipped``).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from fuzzyservo.analysis.margins import stable_at
from fuzzyservo.controllers.base import Controller
from fuzzyservo.metrics import METRIC_NAMES
from fuzzyservo.rig import Rig
from fuzzyservo.simulation import simulate
from fuzzyservo.tuning.evaluation import Evaluation, Scorer
from fuzzyservo.tuning.spec import Study
from fuzzyservo.tuning.uncertainty.robustness import (
    SUMMARY_METRICS,
    MonteCarlo,
    SampleRun,
    lockstep_runs,
    margin_checks_batch,
    monte_carlo,
    run_sample,
    run_samples,
    summary,
)
from fuzzyservo.tuning.uncertainty.sets import aggregate, sample_rig

#: samples simulated together once a trial's first sample ran through (it is pruned or
#: fails there most often): the results are those of one sample after the other, and
#: are used in the same order, so the trial's value, pruning and counts are the same;
#: a trial stopped at the first of a pair ran the second for nothing
LOCKSTEP = 2


def sample_rigs(rig: Rig, spec: Study) -> list[Rig]:
    """The study's drawn plants (the same for every trial: common random numbers)."""
    u = spec.uncertainty
    return [sample_rig(rig, u.parameters, s) for s in u.draws]


def _partial_is_lower_bound(spec) -> bool:
    """Can a sample be judged after some of its scenarios? Yes when the metrics are the
    worst over the scenarios and the objective weighs them with no negative weight: then
    the value over the scenarios run so far can only grow with the rest."""
    weights = spec.objective.weights.values() if not spec.objective.pareto else [-1.0]
    return spec.aggregate == "worst" and all(w >= 0 for w in weights)


def _margin_bounds(spec) -> tuple[float | None, float | None]:
    gain = delay = None
    for c in spec.constraints:
        if c.metric == "gain_margin" and c.op == ">=":
            gain = c.bound
        elif c.metric == "delay_margin_s" and c.op == ">=":
            delay = c.bound
    return gain, delay


def _worst(spec, values: list[float]) -> float:
    """The worst of the samples' objective values so far; an undefined one (a metric that
    never settles) already fixes the trial's value at the penalty, whatever follows."""
    if any(math.isnan(v) for v in values):
        return spec.penalty
    return max(values)


def evaluate_samples(
    evaluator: Scorer,
    controller: Controller,
    *,
    keep_results: bool = False,
    report: Callable[[int, float], bool] | None = None,
) -> Evaluation:
    """Score ``controller`` on every sample (see the module docstring). ``report(k, value)``
    after sample ``k`` with the worst objective value so far (``worst`` aggregate, one
    objective): True stops the trial (status ``pruned``): the value can only grow. When
    the scenarios too are aggregated by their worst and no weight is negative, it is also
    asked after each scenario of a sample (shortest scenario first), so a lost trial stops
    after one run instead of one per scenario."""
    spec = evaluator.spec
    u = spec.uncertainty
    gain, delay = _margin_bounds(spec)
    t0 = time.perf_counter()
    runs: list[SampleRun] = []
    status, message = "ok", ""
    prunable = report is not None and u.aggregate == "worst" and spec.objective.n_values == 1
    scenarios = list(spec.scenarios)
    within = prunable and _partial_is_lower_bound(spec)
    if within:  # the shortest scenario first: a lost trial stops after the cheapest run
        scenarios.sort(key=lambda s: evaluator.rig.scenario(s).duration_s)
    if report is None:  # only a failure ends the trial early: the samples in lock-step
        seeds = [d.noise_seed for d in u.draws]
        indices = [d.index for d in u.draws]
        runs = run_samples(indices, evaluator.sample_rigs, controller, scenarios, seeds,
                           aggregate=spec.aggregate)  # fmt: skip
        if runs[-1].status != "ok":
            status = runs[-1].status
            message = f"{u.draws[len(runs) - 1].describe(u.parameters)}: {runs[-1].message}"
    else:
        ran: dict[int, dict] = {}  # results simulated ahead, in lock-step, by sample
        for k, (sample, rig) in enumerate(zip(u.draws, evaluator.sample_rigs, strict=True)):
            if k and k not in ran:  # past the first sample: this one and the next together
                group = range(k, min(k + LOCKSTEP, len(u.draws)))
                ahead = lockstep_runs([evaluator.sample_rigs[j] for j in group], controller,
                                      scenarios, [u.draws[j].noise_seed for j in group])  # fmt: skip
                ran.update(zip(group, ahead, strict=True))
            stop = None
            if within:
                before = max(
                    (evaluator.objective_values(r.metrics)[0] for r in runs), default=-math.inf
                )

                def stop(partial, k=sample.index, before=before) -> bool:
                    # a metric still undefined part-way (not settled yet) bounds nothing
                    value = max(before, evaluator.objective_values(partial)[0])
                    return math.isfinite(value) and report(k, value)

            run = run_sample(
                sample.index, rig, controller, scenarios, sample.noise_seed,
                aggregate=spec.aggregate, stop=stop, ran=ran.pop(k, None),
            )  # fmt: skip
            runs.append(run)
            if run.status == "pruned":
                so_far = max(evaluator.objective_values(r.metrics)[0] for r in runs)
                status = "pruned"
                message = f"worst after {len(runs)} sample(s) ({run.message}): {so_far:.4g}"
                break
            if run.status != "ok":
                status = run.status
                message = f"{sample.describe(u.parameters)}: {run.message}"
                break
            if prunable:
                so_far = _worst(spec, [evaluator.objective_values(r.metrics)[0] for r in runs])
                if report(sample.index, so_far):
                    status, message = "pruned", f"worst after {len(runs)} sample(s): {so_far:.4g}"
                    break
    if status == "ok" and (gain is not None or delay is not None):
        # the margin checks last, once every sample ran through: they decide no pruning
        # and no failure, so a trial stopped at its k-th sample does not pay for k of them;
        # all samples' checks in one compiled call (lock-step)
        checks = margin_checks_batch(evaluator.sample_rigs, controller, u.margin_scenario,
                                     [d.noise_seed for d in u.draws], gain, delay)  # fmt: skip
        runs = [dataclasses.replace(r, gain_holds=g, delay_holds=d)
                for r, (g, d) in zip(runs, checks, strict=True)]  # fmt: skip
    results = {}
    if keep_results:  # the nominal plant, for the report's plots
        for scenario in spec.scenarios:
            results[scenario] = simulate(evaluator.rig, controller, scenario)
    sim_time = time.perf_counter() - t0
    sims = sum(len(r.scenario_metrics) + (r.gain_holds is not None) + (r.delay_holds is not None)
               for r in runs)  # fmt: skip
    skipped = len(u.draws) - len(runs)
    n_values = spec.objective.n_values
    if status != "ok":
        return Evaluation(
            values=tuple(spec.penalty for _ in range(n_values)),
            metrics={m: math.nan for m in METRIC_NAMES},
            scenario_metrics=runs[-1].scenario_metrics,
            violations=tuple(math.inf for _ in spec.constraints),
            status=status,
            message=message,
            sim_time_s=sim_time,
            results=results,
            simulations=sims,
            samples_skipped=skipped,
        )
    how, alpha = u.aggregate, u.alpha
    metrics = {m: aggregate([r.metrics[m] for r in runs], how, alpha) for m in METRIC_NAMES}
    per_sample = [evaluator.objective_values(r.metrics) for r in runs]
    values = tuple(aggregate([v[k] for v in per_sample], how, alpha) for k in range(n_values))
    scenario_metrics = {
        s: {m: aggregate([r.scenario_metrics[s][m] for r in runs], "worst") for m in METRIC_NAMES}
        for s in spec.scenarios
    }
    violations = []
    failing = []
    for c in spec.constraints:
        if c.metric == "gain_margin" and c.op == ">=":
            bad = [r.index for r in runs if r.gain_holds is False]
        elif c.metric == "delay_margin_s" and c.op == ">=":
            bad = [r.index for r in runs if r.delay_holds is False]
        else:
            worst = max(c.violation(r.metrics.get(c.metric, math.nan)) for r in runs)
            violations.append(worst)
            continue
        violations.append(float(len(bad)))  # > 0: broken on that many samples
        if bad:
            failing.append(f"{c} fails on sample(s) {', '.join(map(str, bad))}")
        metrics[c.metric] = c.bound if not bad else math.nan
    if not all(math.isfinite(v) for v in values):
        bad = [m for m in spec.objective.metrics if not math.isfinite(metrics[m])]
        status = "undefined"
        message = f"metric(s) {', '.join(bad)} undefined on some sample (e.g. never settles)"
        values = tuple(spec.penalty for _ in values)
    elif failing:
        message = "; ".join(failing)
    return Evaluation(
        values=values,
        metrics=metrics,
        scenario_metrics=scenario_metrics,
        violations=tuple(violations),
        status=status,
        message=message,
        sim_time_s=sim_time,
        results=results,
        simulations=sims,
        sample_values=tuple(v[0] for v in per_sample),
    )


#: the seed of the report's Monte Carlo check (as `fuzzyservo robustness`): plants the
#: study never saw
CHECK_SEED = 2026


@dataclass(frozen=True)
class Comparison:
    """Controllers side by side on the nominal plant (``nominal``, noise seed 0) and on
    ``samples`` plants drawn afresh from the study's uncertainty (``monte_carlo``, seed
    ``seed``), with the gain check ``gain`` (from ``gain_margin >= g``, else 2) on every
    scenario."""

    names: list[str]
    nominal: list[SampleRun]
    objective: list[float]  # the study's objective of each on the nominal plant
    monte_carlo: list[MonteCarlo]
    samples: int
    seed: int
    gain: float
    uncertainty: str

    def rows(self) -> list[dict[str, object]]:
        """Per controller: the Monte Carlo summary (:func:`.robustness.summary`)
        with the nominal metrics, objective and gain check beside it."""
        out = []
        for row, run, value in zip(summary(self.monte_carlo, self.gain), self.nominal,
                                   self.objective, strict=True):  # fmt: skip
            row = dict(row)
            row["nominal"] = {
                "status": run.status,
                "objective": value,
                "gain_margin_holds": run.gain_holds,
                **{m: run.metrics.get(m, math.nan) for m in SUMMARY_METRICS},
            }
            out.append(row)
        return out


def compare_controllers(
    evaluator: Scorer,
    controllers: Sequence[Controller],
    *,
    samples: int,
    seed: int = CHECK_SEED,
    progress: Callable[[int], object] | None = None,
) -> Comparison:
    """``controllers`` on the study's nominal plant and on ``samples`` fresh draws of its
    uncertainty (the report's comparison of the tuned controller with the baseline and
    the template). Metrics: the worst scenario of each sample, as the study counts them."""
    spec = evaluator.spec
    u = dataclasses.replace(spec.uncertainty, samples=samples, seed=seed, draws=())
    gain, _ = _margin_bounds(spec)
    gain = gain if gain is not None else 2.0
    rigs = [sample_rig(evaluator.rig, u.parameters, s) for s in u.draws]
    scenarios = list(spec.scenarios)
    nominal, objective = [], []
    for controller in controllers:
        run = run_sample(-1, evaluator.rig, controller, scenarios, 0, aggregate=spec.aggregate)
        if run.status == "ok":
            ok = all(stable_at(evaluator.rig, controller, s, multiplier=gain) for s in scenarios)
            run = dataclasses.replace(run, gain_holds=ok)
        nominal.append(run)
        objective.append(
            evaluator.objective_values(run.metrics)[0] if run.status == "ok" else math.nan
        )
    mcs = monte_carlo(
        evaluator.rig, controllers, rigs, [d.noise_seed for d in u.draws], scenarios,
        gain=gain, progress=progress,
    )  # fmt: skip
    return Comparison(
        [c.name for c in controllers], nominal, objective, mcs, samples, seed, gain,
        u.describe(),
    )  # fmt: skip
