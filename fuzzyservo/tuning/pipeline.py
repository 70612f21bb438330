"""The pipelined loop (the default mode of :func:`~fuzzyservo.tuning.runner.run_study`).

This process owns the sampler and the storage; the study lives in memory. ``batch_size``
trials are in flight at every moment: the first ``batch_size`` are asked at once, and
each time trial ``m`` is told, trial ``m + batch_size`` is asked. So trial ``n`` is
sampled knowing exactly the trials up to ``n - batch_size``, whatever the executor and
however many workers it has, and the workers never wait for the sampler, for the
storage or for the slowest trial of a batch (:func:`~fuzzyservo.executor.stream`).
Told trials are written ``batch_size`` at a time, in one transaction
(:mod:`~fuzzyservo.tuning.batch_write`), while the workers go on.

A resume replays the stored trials: it asks again, in the same order, and tells each
stored result in place of scoring it. The sampler, seeded by trial number, asks the same
numbers, so the study goes on as if it had never stopped; the trials that were in
flight when it stopped are scored again. A study stored another way (by the
batch-synchronous loop of before, or with another ``batch_size``) proposes other numbers
at some trial: from there its stored trials are taken as they are, and the study goes on
from them."""

from __future__ import annotations

import json
import time
from collections import deque
from collections.abc import Callable, Iterator
from itertools import chain

from fuzzyservo.tuning.integrity import per_trial_seeded
from fuzzyservo.tuning.samplers import make_sampler
from fuzzyservo.tuning.spec import Study
from fuzzyservo.tuning.study_trials import best_feasible_value, prunes, record, suggest
from fuzzyservo.tuning.trial import Task, TrialResult, TrialRunner
from fuzzyservo.tuning.trial_bar import postfix
from fuzzyservo.tuning.warmstart import out_of_patience, start_points

STORAGE_ATTR = "storage_s"  # study attribute: the parent's time writing trials [s]
WAIT_ATTR = "parent_wait_s"  # study attribute: the parent's time waiting for a result [s]
#: a user attribute the batch-synchronous loop of before stored on each trial
_LEGACY_ATTRS = ("constraints", "batch")


def run_pipelined(
    spec: Study,
    stored,
    total: int,
    executor,
    bar=None,
    interrupted: Callable[[], bool] = lambda: False,
    runner: TrialRunner | None = None,
) -> None:
    """Run the study ``stored`` (an Optuna study in its storage) to ``total`` told trials
    (see the module docstring); ``executor`` scores them with ``runner`` (default: a
    :class:`~fuzzyservo.tuning.trial.TrialRunner` of ``spec``). ``interrupted``: whether a
    Ctrl-C came; the loop then stops with KeyboardInterrupt, the told trials written."""
    from fuzzyservo.executor import stream
    from fuzzyservo.tuning.batch_write import BatchWriter
    from fuzzyservo.tuning.integrity import fingerprint
    from fuzzyservo.tuning.study_trials import finished_states

    told = stored.get_trials(deepcopy=False, states=finished_states())
    if len(told) >= total:
        return  # done already (or asked for fewer trials than it holds)
    ahead = spec.batch_size
    runner = runner or TrialRunner(spec, json.dumps(fingerprint(spec), sort_keys=True))
    memory, flight = _replayed(spec, told, total, ahead)  # the bar counts them already
    if spec.patience and spec.objective.n_values == 1 and out_of_patience(memory, spec.patience):
        return  # it had stopped for want of progress: nothing more to ask
    writer = BatchWriter(stored)
    written = writer.n_trials()
    storage_s = stored.user_attrs.get(STORAGE_ATTR, 0.0)  # the parent's writes, resumed too
    unwritten: list = []
    t0 = time.perf_counter()

    def write() -> None:
        nonlocal written, storage_s
        if not unwritten:
            return
        if writer.n_trials() != written:
            from fuzzyservo.errors import ConfigError

            raise ConfigError(
                f"study {spec.name!r}: another process writes to its storage; a pipelined run "
                "owns its study: run every process sharing one with --async"
            )
        started = time.perf_counter()
        writer.write(unwritten, (STORAGE_ATTR, storage_s))  # one transaction: all or none
        storage_s += time.perf_counter() - started
        written += len(unwritten)
        unwritten.clear()

    def asked() -> Iterator[tuple]:
        while len(memory.get_trials(deepcopy=False)) < total:
            if interrupted():  # a Ctrl-C whose KeyboardInterrupt something swallowed
                raise KeyboardInterrupt
            yield _ask(memory, spec)

    order: deque = deque()  # the trials in flight, in the order their results come

    asking = 0.0  # the asks' seconds so far

    def submit(item: tuple):
        nonlocal asking
        trial, task, sample_s = item
        order.append((trial, sample_s))
        asking += sample_s
        return executor.submit(runner, task)

    waited = stored.user_attrs.get(WAIT_ATTR, 0.0)
    results = stream(submit, chain(flight, asked()), ahead)
    try:
        while True:
            came, asked_before = time.perf_counter(), asking
            result = next(results, None)
            if result is None:
                break
            trial, sample_s = order.popleft()
            # the time the workers kept this process waiting (less the ask it drew)
            waited += max(time.perf_counter() - came - (asking - asked_before), 0.0)
            if interrupted():
                raise KeyboardInterrupt
            result.user_attrs.setdefault("work", {})["sample_s"] = sample_s
            _tell(memory, trial, spec, result)
            unwritten.append(memory.get_trials(deepcopy=False)[trial.number])
            if bar is not None:
                bar.update(1)
                postfix(bar, memory)
            if len(unwritten) >= ahead:
                write()
            if (
                spec.patience
                and spec.objective.n_values == 1
                and out_of_patience(memory, spec.patience)
            ):
                break
            if spec.timeout_s is not None and time.perf_counter() - t0 > spec.timeout_s:
                break
        write()
    except KeyboardInterrupt:
        write()  # what was told is kept; the trials in flight are asked again on resume
        raise
    finally:
        results.close()
    if written:
        stored.set_user_attr(STORAGE_ATTR, storage_s)
        stored.set_user_attr(WAIT_ATTR, waited)


def _memory(spec: Study):
    """A fresh in-memory study with the study's sampler, seeded per trial."""
    import optuna

    return optuna.create_study(
        directions=["minimize"] * spec.objective.n_values,
        sampler=per_trial_seeded(make_sampler(spec, spec.seed), spec.seed),
    )


def _ask(memory, spec: Study) -> tuple:
    """Ask the next trial: (the Optuna trial, its task, the seconds the ask took)."""
    started = time.perf_counter()
    bound = best_feasible_value(memory) if prunes(spec) else None
    trial = memory.ask()
    task = Task(trial.number, suggest(trial, spec), bound)
    return trial, task, time.perf_counter() - started


def _replayed(spec: Study, told: list, total: int, ahead: int) -> tuple:
    """The in-memory study with the stored trials ``told`` replayed (see the module
    docstring), and the trials asked but not told (in flight when the run stopped)."""
    memory = _memory(spec)
    for point in start_points(spec):
        memory.enqueue_trial(point)
    if not told:
        return memory, []
    flight: deque = deque()
    for _ in range(min(ahead, total)):
        flight.append(_ask(memory, spec))
    for old in told:
        trial, task, _ = flight.popleft()
        if task.params != old.params:  # stored another way: take the rest as it is
            memory = _memory(spec)
            memory.add_trials(told)
            for point in start_points(spec)[len(told) :]:
                memory.enqueue_trial(point)
            return memory, []
        _tell(memory, trial, spec, _result_of(old))
        if len(memory.get_trials(deepcopy=False)) < total:
            flight.append(_ask(memory, spec))
    return memory, list(flight)


def _result_of(trial) -> TrialResult:
    """A stored trial's result, as :func:`~fuzzyservo.tuning.trial.score` returned it."""
    from optuna.trial import TrialState

    attrs = {k: v for k, v in trial.user_attrs.items() if k not in _LEGACY_ATTRS}
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


def _tell(study, trial, spec: Study, result: TrialResult) -> None:
    from optuna.trial import TrialState

    record(trial, spec, result)
    if result.pruned_at is not None:
        study.tell(trial, state=TrialState.PRUNED)
    else:
        study.tell(trial, list(result.values))
