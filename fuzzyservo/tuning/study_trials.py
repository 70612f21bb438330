"""A study's Optuna trials, between Optuna and a trial's work (:mod:`~fuzzyservo.tuning.trial`,
pure of Optuna): drawing a trial's numbers, recording its result on the Optuna trial, and
reading the study's trials back (counts by state, the best feasible value). Both modes of
the runner and the outcome use them."""

from __future__ import annotations

from fuzzyservo.tuning.spec import Study
from fuzzyservo.tuning.trial import TrialResult
from fuzzyservo.tuning.warmstart import is_feasible


def suggest(trial, spec: Study) -> dict[str, float]:
    """The trial's numbers, drawn by the study's sampler."""
    params = {}
    for p in spec.parameters:
        if p.integer:
            params[p.path] = trial.suggest_int(p.path, int(p.low), int(p.high), log=p.log)
        else:
            params[p.path] = trial.suggest_float(p.path, p.low, p.high, log=p.log)
    return params


def prunes(spec: Study) -> bool:
    """Robust single-objective trials stop once hopeless (tuning/trial.py)."""
    return spec.uncertainty is not None and spec.objective.n_values == 1


def record(trial, spec: Study, result: TrialResult) -> None:
    """The result's attributes and constraints on the Optuna trial (and, for a pruned
    trial, its last value: TPE ranks a pruned trial by it)."""
    for key, value in result.user_attrs.items():
        trial.set_user_attr(key, value)
    _record_constraints(trial, spec, list(result.constraints))
    if result.pruned_at is not None:
        step, value = result.pruned_at
        trial.report(value, step)


def _record_constraints(trial, spec: Study, violations: list[float]) -> None:
    """Store violations where the samplers look (``set_constraint``, optuna >= 5) and in user_attrs."""
    trial.set_user_attr("constraints", violations)
    if hasattr(trial, "set_constraint"):
        for c, v in zip(spec.constraints, violations, strict=True):
            trial.set_constraint(str(c), v)


def trial_counts(study) -> dict[str, int]:
    """The study's trials: ``asked`` (every state), ``complete``, ``pruned``, ``failed``."""
    from optuna.trial import TrialState

    states = [t.state for t in study.get_trials(deepcopy=False)]
    return {"asked": len(states), "complete": states.count(TrialState.COMPLETE),
            "pruned": states.count(TrialState.PRUNED), "failed": states.count(TrialState.FAIL)}  # fmt: skip


def count_complete(study) -> int:
    """Finished trials: COMPLETE, and PRUNED (a robust trial stopped as hopeless)."""
    return len(study.get_trials(deepcopy=False, states=finished_states()))


def finished_states() -> tuple:
    """The trial states that count towards a study's ``trials``."""
    from optuna.trial import TrialState

    return (TrialState.COMPLETE, TrialState.PRUNED)


def best_feasible_value(study) -> float | None:
    """The lowest value of a COMPLETE feasible trial (the pruning bound), None before one."""
    from optuna.trial import TrialState

    values = [
        t.value
        for t in study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,))
        if is_feasible(t)
    ]
    return min(values) if values else None
