"""Start a study from what is known, and stop it when it stops improving.

* **Warm start**: a study's ``warm_start`` points (searched numbers by name: a previous
  study's best, a named controller's :meth:`~fuzzyservo.controllers.base.Controller.params`)
  are its first trials (``enqueue_trial``); a number outside its search range is moved to
  the nearer bound, one left out is sampled.
* **Patience**: the study stops once its best trial has not improved for ``n`` finished
  trials (any process's; read from the storage).

Also what a stored trial says about itself (its constraint violations, feasible or not),
which the runner reads too.
"""

from __future__ import annotations

import math
from typing import Any

from fuzzyservo.tuning.spec import Study


def stored_violations(trial: Any) -> list[float]:
    """A stored trial's constraint violations (> 0: broken); none stored counts as broken."""
    return list(trial.user_attrs.get("constraints", [math.inf]))


def is_feasible(trial: Any) -> bool:
    """A stored trial that ran (status ``ok``) and meets every constraint."""
    return trial.user_attrs.get("status") == "ok" and all(v <= 0 for v in stored_violations(trial))


def start_points(spec: Study) -> list[dict[str, float]]:
    """The study's warm-start points, each number clipped into its parameter's range."""
    by_name = {p.path: p for p in spec.parameters}
    return [
        {name: by_name[name].clip(float(value)) for name, value in point.items() if name in by_name}
        for point in spec.warm_start
    ]


def enqueue(study: Any, spec: Study) -> int:
    """Queue the study's warm-start points as the first trials of a study that has none
    yet; returns how many were queued."""
    points = start_points(spec)
    if not points or study.get_trials(deepcopy=False):
        return 0
    for point in points:
        study.enqueue_trial(point, skip_if_exists=True)
    return len(points)


def patience_callback(n: int):
    """An Optuna callback: ``study.stop()`` when the best (feasible first) trial is ``n`` or
    more finished trials old."""

    def callback(study, trial) -> None:
        if out_of_patience(study, n):
            study.stop()

    return callback


def out_of_patience(study: Any, n: int) -> bool:
    """Is the study's best (feasible first) trial ``n`` or more finished trials old?"""
    from optuna.trial import TrialState

    done = study.get_trials(deepcopy=False, states=(TrialState.COMPLETE, TrialState.PRUNED))
    complete = [t for t in done if t.state == TrialState.COMPLETE]
    if not complete:
        return False
    feasible = [t for t in complete if is_feasible(t)] or complete
    best = min(feasible, key=lambda t: t.values[0])
    return sum(t.number > best.number for t in done) >= n
