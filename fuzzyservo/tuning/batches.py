"""The batch-synchronous loop (the default mode of :func:`~fuzzyservo.tuning.runner.run_study`).

This process owns the sampler and the storage: it replays the stored trials into a study
in memory, asks ``batch_size`` trials, has an executor score them, tells them in
trial-number order and writes each batch in one transaction
(:mod:`~fuzzyservo.tuning.batch_write`). A resume finds the part of a batch a killed run
had begun to write and scores only the rest."""

from __future__ import annotations

import json
import time
from collections.abc import Callable

from fuzzyservo.tuning.integrity import per_trial_seeded
from fuzzyservo.tuning.samplers import make_sampler
from fuzzyservo.tuning.spec import Study
from fuzzyservo.tuning.study_trials import (
    best_feasible_value,
    finished_states,
    prunes,
    record,
    suggest,
)
from fuzzyservo.tuning.trial import TrialResult
from fuzzyservo.tuning.trial_bar import postfix
from fuzzyservo.tuning.warmstart import out_of_patience, start_points

#: a batch-mode trial's user attribute: [its batch's first trial index, the batch's size]
BATCH_ATTR = "batch"
STORAGE_ATTR = "storage_s"  # study attribute: the parent's time writing batches [s]


def run_batches(
    spec: Study,
    stored,
    total: int,
    executor,
    bar=None,
    interrupted: Callable[[], bool] = lambda: False,
) -> None:
    """The batch-synchronous loop: this process owns the sampler and the storage.

    The study lives in memory (the stored trials replayed in order into a fresh sampler
    seeded per trial: :func:`~fuzzyservo.tuning.integrity.per_trial_seeded`); each round
    asks ``spec.batch_size`` trials, has ``executor`` score them
    (:class:`~fuzzyservo.tuning.trial.TrialRunner`, pruning bound: the best feasible value
    told before the batch), tells them in trial-number order and then writes the batch to
    the storage ``stored`` in one transaction (:mod:`~fuzzyservo.tuning.batch_write`).
    Whatever the executor, the sampler sees the same history at every ask, so the trials
    are the same. A run killed before its batch is written loses that batch only and a
    resume asks it again, identically; one killed while writing it (through
    ``Study.add_trials``, on a storage written trial by trial) finds the written part on
    resume and scores only the rest. ``interrupted``: whether a Ctrl-C came; the loop
    stops with KeyboardInterrupt before and after each batch's scoring when it did."""
    import optuna

    from fuzzyservo.tuning.batch_write import BatchWriter
    from fuzzyservo.tuning.integrity import fingerprint
    from fuzzyservo.tuning.trial import Task, TrialRunner

    told = stored.get_trials(deepcopy=False, states=finished_states())
    start, pending = _partial_batch(told)
    memory = optuna.create_study(
        directions=["minimize"] * spec.objective.n_values,
        sampler=per_trial_seeded(make_sampler(spec, spec.seed), spec.seed),
    )
    memory.add_trials(told[:start])
    for point in start_points(spec)[start:]:  # the warm start not run yet
        memory.enqueue_trial(point)
    writer = BatchWriter(stored)
    written = writer.n_trials()
    runner = TrialRunner(spec, json.dumps(fingerprint(spec), sort_keys=True))
    t0 = time.perf_counter()
    storage_s = stored.user_attrs.get(STORAGE_ATTR, 0.0)  # the parent's writes, resumed too
    n = start
    while n < total:
        if interrupted():  # a Ctrl-C whose KeyboardInterrupt something swallowed
            raise KeyboardInterrupt
        size = pending[0] if pending else min(spec.batch_size, total - n)
        asked = time.perf_counter()
        bound = best_feasible_value(memory) if prunes(spec) else None
        trials = [memory.ask() for _ in range(size)]
        tasks = [Task(t.number, suggest(t, spec), bound) for t in trials]
        sample_s = (time.perf_counter() - asked) / size
        kept = {}  # the trials of a half-written batch, asked again identically
        for task in tasks if pending else ():
            old = pending[1].get(task.number)
            if old is not None and old.params == task.params:
                kept[task.number] = _result_of(old)
        todo = [t for t in tasks if t.number not in kept]
        if bar is not None:
            bar.update(len(kept))
        done = None if bar is None else (lambda k: bar.update(1))
        scored = executor.map(runner, todo, done)
        if interrupted():
            raise KeyboardInterrupt
        results = {**kept, **{t.number: r for t, r in zip(todo, scored, strict=True)}}
        for trial in trials:
            result = results[trial.number]
            result.user_attrs.setdefault("work", {})["sample_s"] = sample_s
            _tell(memory, trial, spec, result, [n, size])
        if writer.n_trials() != written:
            from fuzzyservo.errors import ConfigError

            raise ConfigError(
                f"study {spec.name!r}: another process writes to its storage; a batch run "
                "owns its study: run every process sharing one with --async"
            )
        new = [t for t in memory.get_trials(deepcopy=False)[n : n + size] if t.number not in kept]
        writing = time.perf_counter()
        writer.write(new, (STORAGE_ATTR, storage_s))  # one transaction: all or none
        storage_s += time.perf_counter() - writing
        written += len(new)
        pending = None
        n += size
        if bar is not None:
            postfix(bar, memory)
        if (
            spec.patience
            and spec.objective.n_values == 1
            and out_of_patience(memory, spec.patience)
        ):
            break
        if spec.timeout_s is not None and time.perf_counter() - t0 > spec.timeout_s:
            break
    if written:
        stored.set_user_attr(STORAGE_ATTR, storage_s)  # the last batch's write too


def _partial_batch(told: list) -> tuple[int, tuple[int, dict] | None]:
    """Where the replay stops: the stored trials up to the last whole batch, and the part
    of a batch a killed run had begun to write (its size and its trials by index)."""
    if not told:
        return 0, None
    batch = told[-1].user_attrs.get(BATCH_ATTR)
    if not batch:
        return len(told), None
    first, size = batch
    part = told[first:]
    if len(part) >= size or first > len(told):
        return len(told), None
    return first, (size, {first + k: t for k, t in enumerate(part)})


def _result_of(trial) -> TrialResult:
    """A stored trial's result, as :func:`~fuzzyservo.tuning.trial.score` returned it."""
    from optuna.trial import TrialState

    attrs = {k: v for k, v in trial.user_attrs.items() if k not in ("constraints", BATCH_ATTR)}
    pruned = None
    if trial.state == TrialState.PRUNED and trial.intermediate_values:
        step = max(trial.intermediate_values)
        pruned = (step, trial.intermediate_values[step])
    return TrialResult(
        values=tuple(trial.values or ()),
        constraints=tuple(trial.user_attrs.get("constraints", ())),
        user_attrs=attrs,
        pruned_at=pruned,
    )


def _tell(study, trial, spec: Study, result: TrialResult, batch: list[int]) -> None:
    from optuna.trial import TrialState

    record(trial, spec, result)
    trial.set_user_attr(BATCH_ATTR, batch)
    if result.pruned_at is not None:
        study.tell(trial, state=TrialState.PRUNED)
    else:
        study.tell(trial, list(result.values))
