"""What a finished (or stopped) study produced: :class:`StudyOutcome`, read back from the
storage by :func:`collect` (the best feasible trial or the Pareto front, re-scored with its
results kept; history, importances, times), and a robust study's best chosen again among
its top trials on fresh samples (:func:`select_on_fresh_samples`)."""

from __future__ import annotations

import dataclasses
import json
import math
import time
from dataclasses import dataclass, field
from typing import Any

from fuzzyservo.display import (
    LOWER_IS_BETTER,
    MetricUnits,
    metric_units,
    metrics_table,
    trial_counts_text,
    undefined_note,
)
from fuzzyservo.metrics import METRIC_NAMES, format_value
from fuzzyservo.results import Result
from fuzzyservo.tuning.evaluation import Evaluation
from fuzzyservo.tuning.objective import build_evaluator
from fuzzyservo.tuning.pipeline import STORAGE_ATTR, WAIT_ATTR
from fuzzyservo.tuning.spec import Study
from fuzzyservo.tuning.storage import open_study
from fuzzyservo.tuning.study_trials import finished_states, trial_counts
from fuzzyservo.tuning.warmstart import is_feasible


@dataclass(frozen=True)
class StudyOutcome(Result):
    """What a finished (or stopped) study produced; ``to_dict()`` its numbers, ``text()``
    the lines ``fuzzyservo tune`` prints (:class:`~fuzzyservo.tuning.report.StudyReport`
    adds the best scored again from its file and a robust study's comparison)."""

    spec: Study
    storage_url: str
    trials_complete: int
    best_params: dict[str, float]
    best: Evaluation
    baseline: Evaluation
    pareto: list[dict[str, Any]] = field(default_factory=list)
    history: list[dict[str, Any]] = field(default_factory=list)
    importances: dict[str, float] = field(default_factory=dict)
    wall_s: float = 0.0
    sim_time_s: float = 0.0
    worker_time_s: float = 0.0
    simulations: int = 0
    trials_pruned: int = 0
    #: robust studies: the top trials scored again on fresh samples (tuning/uncertainty/noise.py), the
    #: winner first; each {number, value, standard_error, fresh_value, fresh_standard_error,
    #: fresh_feasible}
    selection: list[dict[str, Any]] = field(default_factory=list)
    best_number: int | None = None
    samples_skipped: int = 0  # sampled plants the robust trials never ran (decided before)
    sampler_time_s: float = 0.0  # the sampler's time (asking the trials)
    trials_asked: int = 0  # every trial the sampler proposed (any state)
    trials_failed: int = 0  # FAIL: an error or a killed worker (not counted)
    build_time_s: float = 0.0  # in the trials: building controllers
    storage_time_s: float = 0.0  # pipelined mode: the parent writing the trials
    #: where the run's wall time went (:func:`timeline`), when the trials carry their times
    timeline: dict[str, float] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The study's numbers, as ``summary.json`` holds them (NaN and inf before they
        become null): the best trial and the baseline, the Pareto front, the counts and
        times."""
        outcome, baseline_name, trial = self, self.spec.baseline.name, best_trial_number(self)
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

    def text(self) -> str:
        """What ``fuzzyservo tune`` prints when done (before a robust study's comparison):
        the trial counts, the metrics of the baseline and the best in display units
        (``n/a`` explained) and the objective."""
        outcome = self
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
        return "\n".join(lines)


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


def timeline(trials: list, started: float | None, ended: float, workers: int,
             parent_wait: float | None = None) -> dict[str, float]:  # fmt: skip
    """Where a run's wall time went, from its trials' start and end times (seconds since
    the epoch, ``work.started`` and ``work.ended``): ``startup_s`` before the first trial
    started (worker processes starting, the storage opened, the first asks),
    ``trials_s`` from the first trial's start to the last one's end, ``finish_s`` after it
    (the report's checks: the best and the baseline scored again, a robust study's fresh
    samples, importances); in ``trials_s``, ``busy_s`` the trials' own time summed over
    the ``workers`` and ``idle_s`` the workers' time without a trial. Empty when the
    trials carry no times (stored before they did, or run asynchronously on several
    machines' clocks). ``parent_wait``: the time the parent spent waiting for a result
    (pipelined runs): the rest of its time it asked, told and wrote."""
    spans = [(t.user_attrs.get("work", {}).get("started"), t.user_attrs.get("work", {}).get("ended"))
             for t in trials]  # fmt: skip
    spans = [(a, b) for a, b in spans if a is not None and b is not None]
    if not spans or started is None:
        return {}
    first = min(a for a, _ in spans)
    last = max(b for _, b in spans)
    busy = sum(b - a for a, b in spans)
    return {
        "wall_s": ended - started,
        "startup_s": max(first - started, 0.0),
        "trials_s": last - first,
        "finish_s": max(ended - last, 0.0),
        "workers": float(workers),
        "busy_s": busy,
        "idle_s": max((last - first) * workers - busy, 0.0),
        **({"parent_wait_s": parent_wait} if parent_wait is not None else {}),
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


def _objective_value(ev: Evaluation) -> float | list[float]:
    return ev.values[0] if len(ev.values) == 1 else list(ev.values)


def _trial_time(trial) -> float:
    """A trial's own time (a batch's trials all start at its ask and end at its tell)."""
    if "trial_time_s" in trial.user_attrs:
        return trial.user_attrs["trial_time_s"]
    if trial.datetime_complete and trial.datetime_start:
        return (trial.datetime_complete - trial.datetime_start).total_seconds()
    return 0.0


def collect(spec: Study, url: str, *, wall_s: float = 0.0, executor=None,
            study=None, started: float | None = None) -> StudyOutcome:  # fmt: skip
    """Read the study back: best (feasible) trial or Pareto front, history, importances.
    A robust study's best is chosen among its top trials on fresh samples
    (:func:`select_on_fresh_samples`, scored by ``executor``, default this process).
    ``study``: the study at ``url`` already open (default: open it). ``started``: when
    the run began (seconds since the epoch), for the outcome's :func:`timeline`."""
    import optuna
    from optuna.trial import TrialState

    study = study if study is not None else open_study(spec, url)
    stored_time = float(study.user_attrs.get(STORAGE_ATTR, 0.0))
    trials = study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,))
    if not trials:
        raise RuntimeError(f"study {spec.name!r} has no complete trial yet in {url}")

    pool = (
        [t for t in trials if is_feasible(t)]
        or [t for t in trials if t.user_attrs.get("status") == "ok"]
        or trials
    )
    evaluator = build_evaluator(spec)
    pareto = []
    if spec.objective.pareto:
        front = [t for t in study.best_trials if t in pool] or study.best_trials
        pareto = [
            {"number": t.number, "values": list(t.values), "params": dict(t.params)} for t in front
        ]
        # the reported "best": the member of the front closest to the origin, each
        # objective measured in units of the baseline's value
        scale = [
            abs(v) if math.isfinite(v) and v != 0 else 1.0
            for v in evaluator.baseline_evaluation.values
        ]
        best_trial = min(
            front, key=lambda t: math.hypot(*(v / s for v, s in zip(t.values, scale, strict=True)))
        )
    else:
        best_trial = min(pool, key=lambda t: t.value)
    selection: list[dict[str, Any]] = []
    if spec.uncertainty is not None and not spec.objective.pareto:
        best_trial, selection = select_on_fresh_samples(spec, pool, executor)
    best_params = dict(best_trial.params)
    best = evaluator.evaluate(
        evaluator.controller(best_params, name=f"{spec.name}_best"), keep_results=True
    )
    history = [
        {"number": t.number, "values": list(t.values), "status": t.user_attrs.get("status", "?"),
         "feasible": is_feasible(t)}
        for t in trials
    ]  # fmt: skip
    importances: dict[str, float] = {}
    if len(trials) >= 10 and len(spec.parameters) > 1:
        import warnings

        try:
            with warnings.catch_warnings():
                # PED-ANOVA reminds that it ranks for low targets: ours are all minimised
                warnings.simplefilter("ignore", UserWarning)
                importances = dict(
                    optuna.importance.get_param_importances(
                        study, target=(lambda t: t.values[0]) if spec.objective.pareto else None
                    )
                )
        except (RuntimeError, ValueError, ZeroDivisionError):
            importances = {}
    finished = study.get_trials(deepcopy=False, states=finished_states())  # with pruned ones
    sim = sum(t.user_attrs.get("sim_time_s", 0.0) for t in finished)
    worker_time = sum(_trial_time(t) for t in finished)
    counts = trial_counts(study)
    workers = getattr(executor, "workers", 1)
    line = timeline(finished, started, time.time(), workers, study.user_attrs.get(WAIT_ATTR))
    return StudyOutcome(
        spec=spec,
        storage_url=url,
        trials_complete=len(trials),
        best_params=best_params,
        best=best,
        baseline=evaluator.baseline_evaluation,
        pareto=pareto,
        history=history,
        importances=importances,
        wall_s=wall_s,
        sim_time_s=sim,
        worker_time_s=worker_time,
        simulations=sum(t.user_attrs.get("simulations", 0) for t in finished),
        trials_pruned=len(finished) - len(trials),
        selection=selection,
        best_number=best_trial.number,
        samples_skipped=sum(_work(t, "samples_skipped") for t in finished),
        sampler_time_s=sum(_work(t, "sample_s") for t in finished),
        trials_asked=counts["asked"],
        trials_failed=counts["failed"],
        build_time_s=sum(_work(t, "build_s") for t in finished),
        storage_time_s=stored_time,
        timeline=line,
    )


def _work(trial, key: str) -> float:
    """One figure of a stored trial's ``work`` record (0 for a study stored before it)."""
    return trial.user_attrs.get("work", {}).get(key, 0)


def select_on_fresh_samples(spec: Study, pool: list, executor=None) -> tuple[Any, list[dict]]:
    """The best of the :data:`~fuzzyservo.tuning.uncertainty.noise.TOP` lowest trials of ``pool`` on
    fresh samples (:func:`~fuzzyservo.tuning.uncertainty.noise.fresh_uncertainty`; feasible there
    first, then by value), and every candidate's values with their standard errors."""
    from fuzzyservo.executor import Inline
    from fuzzyservo.tuning.integrity import fingerprint
    from fuzzyservo.tuning.trial import Task, TrialRunner
    from fuzzyservo.tuning.uncertainty.noise import TOP, fresh_uncertainty, standard_error

    u = spec.uncertainty
    top = sorted(pool, key=lambda t: (t.value, t.number))[:TOP]
    fresh = dataclasses.replace(spec, uncertainty=fresh_uncertainty(u))
    runner = TrialRunner(fresh, "fresh " + json.dumps(fingerprint(fresh), sort_keys=True))
    results = (executor or Inline()).map(runner, [Task(t.number, dict(t.params)) for t in top])

    def se(values) -> float | None:
        value = standard_error([math.nan if v is None else v for v in values or ()],
                               u.aggregate, u.alpha)  # fmt: skip
        return value if math.isfinite(value) else None

    rows = []
    for t, r in zip(top, results, strict=True):
        feasible = r.user_attrs.get("status") == "ok" and all(c <= 0 for c in r.constraints)
        rows.append({"number": t.number, "value": t.value,
                     "standard_error": se(t.user_attrs.get("sample_values")),
                     "fresh_value": r.values[0], "fresh_standard_error":
                     se(r.user_attrs.get("sample_values")), "fresh_feasible": feasible})  # fmt: skip
    rows.sort(key=lambda row: (not row["fresh_feasible"], row["fresh_value"], row["number"]))
    winner = next(t for t in top if t.number == rows[0]["number"])
    return winner, rows
