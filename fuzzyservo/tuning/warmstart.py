"""Start a study from what is known, and stop it when it stops improving.

* **Warm start**: the searched numbers of a controller file of the template's kind (a
  previous study's best, a named controller) are the study's first trials
  (``enqueue_trial``); a number outside the search range is moved to its nearer bound.
* **Patience**: the study stops once its best trial has not improved for ``n`` finished
  trials (any process's; read from the storage).
"""

from __future__ import annotations

from typing import Any

from fuzzyservo.errors import ConfigError
from fuzzyservo.tuning.objective import split_path
from fuzzyservo.tuning.spec import StudySpec


def get_path(data: Any, path: str) -> float:
    """The number at ``path`` (``input.increments[3]``) of a controller mapping."""
    node = data
    for part in split_path(path):
        try:
            node = node[part]
        except (KeyError, IndexError, TypeError):
            raise KeyError(path) from None
    if isinstance(node, bool) or not isinstance(node, int | float):
        raise KeyError(path)
    return float(node)


def params_from(spec: StudySpec, data: dict[str, Any], source: str) -> dict[str, float]:
    """The study's searched numbers as ``data`` holds them, clipped into their ranges; one
    the controller leaves at its default (e.g. no ``gains:``) is left to the sampler. A
    controller with none of them is no warm start of this study."""
    params = {}
    for p in spec.parameters:
        try:
            value = get_path(data, p.path)
        except KeyError:
            continue
        value = min(max(value, p.low), p.high)
        params[p.path] = round(value) if p.integer else value
    if not params:
        raise ConfigError(
            f"has none of the searched numbers ({', '.join(p.path for p in spec.parameters)}); "
            f"warm-start from a controller of the study's template ({spec.controller_file})",
            file=source,
        )
    return params


def enqueue(study: Any, spec: StudySpec, files: list[str]) -> int:
    """Queue the controllers ``files`` as the first trials of a study that has none yet;
    returns how many were queued."""
    from fuzzyservo.io._yaml import read_yaml

    if not files or study.get_trials(deepcopy=False):
        return 0
    for file in files:
        study.enqueue_trial(params_from(spec, read_yaml(file), file), skip_if_exists=True)
    return len(files)


def patience_callback(n: int):
    """An Optuna callback: ``study.stop()`` when the best (feasible first) trial is ``n`` or
    more finished trials old."""

    def callback(study, trial) -> None:
        from optuna.trial import TrialState

        from fuzzyservo.tuning.runner import _constraints

        done = study.get_trials(deepcopy=False, states=(TrialState.COMPLETE, TrialState.PRUNED))
        complete = [t for t in done if t.state == TrialState.COMPLETE]
        if not complete:
            return
        feasible = [
            t for t in complete
            if t.user_attrs.get("status") == "ok" and all(v <= 0 for v in _constraints(t))
        ] or complete  # fmt: skip
        best = min(feasible, key=lambda t: t.values[0])
        if sum(t.number > best.number for t in done) >= n:
            study.stop()

    return callback
