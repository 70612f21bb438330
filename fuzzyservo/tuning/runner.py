"""Running a study on Optuna: the run loop, worker processes, Ctrl-C.

:func:`run_study` opens (or resumes) the study in its storage
(:mod:`~fuzzyservo.tuning.storage`, sampler: :mod:`~fuzzyservo.tuning.samplers`), runs it
and reads back its outcome (:mod:`~fuzzyservo.tuning.outcome`); a trial's numbers and
result pass through :mod:`~fuzzyservo.tuning.study_trials`, progress is drawn by
:mod:`~fuzzyservo.tuning.trial_bar` (:mod:`~fuzzyservo.tuning.integrity` and
:mod:`~fuzzyservo.tuning.warmstart` read the study's objects too). Two ways to run a study:

* **Pipelined** (the default, :func:`~fuzzyservo.tuning.pipeline.run_pipelined`):
  this process owns the sampler and the storage; ``batch_size`` trials are in flight at
  every moment, scored by an executor (:mod:`fuzzyservo.executor`: this process,
  ``--workers N`` local processes, or a Dask ``--cluster``), and each told trial lets the
  next one be asked. Trial ``n`` is sampled knowing exactly the trials up to
  ``n - batch_size``, so the same seeded study gives the same trials, hence the same
  best, with any number of workers, run twice, or killed (kill -9) and resumed; and the
  workers never wait for the sampler, the storage or a batch's slowest trial. The batch
  size is the trade-off: a larger one keeps more workers busy and searches less informed
  (and prunes against an older bound); the result depends on it, never on the workers.
* **Asynchronous** (``--async``): every worker process runs Optuna's own loop on the
  shared storage, which several ``tune`` commands, on several machines, may share
  (PostgreSQL). Not reproducible: the trials depend on which worker finished first.

Trials are stored as they are told (in the first mode ``batch_size`` at a time, in one
transaction), so a study stopped at any moment (Ctrl-C, a killed process) resumes with
the same command and loses no told trial. The count towards ``trials`` is the number of COMPLETE trials (and
PRUNED ones: robust trials stopped once their worst sample so far is worse than the
best feasible trial, which is exact: the worst can only grow); a simulation that
diverges or hits an end stop is a COMPLETE trial with the study's penalty as its value
and its reason in ``user_attrs``. In the asynchronous mode, trials left RUNNING by a
killed process are failed by the storage heartbeat and do not count.
"""

from __future__ import annotations

import contextlib
import dataclasses
import multiprocessing as mp
import sys
import time
from pathlib import Path
from typing import Any

from fuzzyservo.display import trial_counts_text
from fuzzyservo.rig import Rig
from fuzzyservo.tuning.integrity import die_with_parent
from fuzzyservo.tuning.objective import Evaluator, build_evaluator
from fuzzyservo.tuning.outcome import StudyOutcome, collect
from fuzzyservo.tuning.pipeline import run_pipelined
from fuzzyservo.tuning.spec import Study
from fuzzyservo.tuning.storage import open_study, storage_error, storage_faults, storage_url
from fuzzyservo.tuning.study_trials import (
    best_feasible_value,
    count_complete,
    finished_states,
    prunes,
    record,
    suggest,
    trial_counts,
)
from fuzzyservo.tuning.trial import TrialRunner, score, warm_kernels
from fuzzyservo.tuning.trial_bar import postfix, refresh, trial_bar
from fuzzyservo.tuning.warmstart import enqueue, patience_callback


def _objective(spec: Study, evaluator: Evaluator):
    """The asynchronous mode's objective: the pruning bound is read at the trial's start."""

    def objective(trial) -> float | tuple[float, ...]:
        params = suggest(trial, spec)
        bound = best_feasible_value(trial.study) if prunes(spec) else None
        result = score(spec, evaluator, params, bound)
        record(trial, spec, result)
        if result.pruned_at is not None:
            import optuna

            raise optuna.TrialPruned(result.user_attrs.get("message", ""))
        return result.values if len(result.values) > 1 else result.values[0]

    return objective


def _optimize(spec: Study, study, total: int, extra_callbacks: list) -> None:
    """``study.optimize`` until ``total`` complete trials; Ctrl-C finishes the running trial
    and stops (a second Ctrl-C stops at once), then raises KeyboardInterrupt."""
    import signal

    from optuna.study import MaxTrialsCallback

    if count_complete(study) >= total:
        return
    if spec.patience and spec.objective.n_values == 1:
        extra_callbacks = [*extra_callbacks, patience_callback(spec.patience)]
    evaluator = build_evaluator(spec)
    interrupted = False

    def on_sigint(signum, frame) -> None:
        nonlocal interrupted
        if interrupted:
            raise KeyboardInterrupt
        interrupted = True
        study.stop()

    previous = signal.signal(signal.SIGINT, on_sigint)
    try:
        study.optimize(
            _objective(spec, evaluator),
            timeout=spec.timeout_s,
            callbacks=[MaxTrialsCallback(total, states=finished_states()), *extra_callbacks],
            gc_after_trial=False,
        )
    finally:
        signal.signal(signal.SIGINT, previous)
    if interrupted:
        raise KeyboardInterrupt


def _worker(spec: Study, url: str, total: int, worker: int, shared: bool, parent: int = 0) -> None:
    """A local worker process: optimise until the study holds ``total`` complete trials;
    it ends when its parent ``parent`` does (:func:`~fuzzyservo.tuning.integrity.die_with_parent`)."""
    if parent:
        die_with_parent(parent)
    try:
        _optimize(spec, open_study(spec, url, worker, shared=shared), total, [])
    except KeyboardInterrupt:
        pass


def run_study(
    spec: Study,
    out_dir: Path,
    *,
    trials: int | None = None,
    storage: str | None = None,
    workers: int = 1,
    progress: bool = True,
    rig: Rig | None = None,
    cluster: str | None = None,
    batch_size: int | None = None,
    asynchronous: bool = False,
) -> StudyOutcome:
    """Run (or resume) the study until it holds ``trials`` complete trials; return the outcome.

    Pipelined (the default; :func:`run_pipelined`): the same seeded study gives the
    same trials, hence the same best, with any ``workers`` (local processes) or on the Dask
    ``cluster`` (``tcp://HOST:PORT``), run twice, or interrupted and resumed.
    ``asynchronous``: every worker runs Optuna's own loop on the shared storage (several
    ``tune`` commands, on several machines, may share one study): not reproducible.

    ``rig``: tune on this rig instead of the study's own (the same as
    ``dataclasses.replace(spec, rig=rig)``)."""
    if rig is not None:
        spec = dataclasses.replace(spec, rig=rig)
    if batch_size is not None:
        spec = dataclasses.replace(spec, batch_size=batch_size)
    out_dir.mkdir(parents=True, exist_ok=True)
    url = storage_url(spec, out_dir, storage)
    # a storage named by the user may be shared with other processes or machines
    shared = bool(storage or spec.storage)
    total = trials or spec.trials
    if cluster and asynchronous:
        from fuzzyservo.errors import ConfigError

        raise ConfigError("--cluster runs pipelined; leave out --async (or --cluster)")
    executor = None
    if not asynchronous:  # a cluster that cannot be used fails before anything starts
        from fuzzyservo.executor import make_executor

        executor = make_executor(workers, cluster)
    try:
        return _run(spec, url, total, executor, workers, shared, progress)
    except storage_faults() as exc:  # damaged while in use (open_study names what it meets)
        raise storage_error(url, exc) from None
    finally:
        if executor is not None:
            executor.close()


def _run(spec: Study, url: str, total: int, executor, workers: int, shared: bool, progress):
    """:func:`run_study` once its storage URL and executor are known."""
    t0, started = time.perf_counter(), time.time()
    runner, warming = None, []
    if executor is not None:
        import json

        from fuzzyservo.executor import Inline
        from fuzzyservo.tuning.integrity import fingerprint

        runner = TrialRunner(spec, json.dumps(fingerprint(spec), sort_keys=True))
        if not isinstance(executor, Inline):  # the workers start (import, load the
            # kernels) while we open; inline, this process warms itself just below
            warming = [executor.submit(runner.warm, k) for k in range(executor.workers)]
    # before the bar (its rate and ETA should not count compiling); on a fresh install
    # one process compiles each kernel, the others wait for it and load it (_jit.first_call)
    warm_kernels(spec)
    study = open_study(spec, url)  # creates it (and its tables) before any worker starts
    done_before = count_complete(study)
    if done_before and progress:
        left = max(total - done_before, 0)
        counts = trial_counts_text(**trial_counts(study))
        print(f"resuming study {spec.name}: {done_before} of {total} trials done "
              f"({counts}), {left} to run ({url})", file=sys.stderr, flush=True)  # fmt: skip
    bar = trial_bar(total, done_before, spec.name, progress)
    try:
        if executor is not None:
            with _interruptible() as interrupted:
                for pending in warming:
                    pending.result()
                run_pipelined(spec, study, total, executor, bar, interrupted, runner)
        else:
            enqueue(study, spec)
            if workers <= 1:
                _run_inline(spec, url, total, bar, shared)
            else:
                _run_processes(spec, url, total, workers, bar, shared)
    finally:
        bar.close()
    wall = time.perf_counter() - t0
    # a pipelined run wrote every trial through this study: read it back without reopening
    return collect(spec, url, wall_s=wall, executor=executor, started=started,
                   study=study if executor is not None else None)  # fmt: skip


@contextlib.contextmanager
def _interruptible():
    """SIGINT (also in a background job started with it ignored) and SIGTERM raise
    KeyboardInterrupt here: the batch is dropped, the workers are ended, the told
    trials stay. Only the main thread may set handlers; elsewhere nothing changes.

    Yields a function telling whether such a signal came: the exception can be lost
    where it is raised (a Ctrl-C during the sampler's first import of scipy.stats,
    about 1 in 12 runs of the background-Ctrl-C test under load, ended nowhere and
    the study ran on), so the batch loop checks it too."""
    import signal
    import threading

    came = threading.Event()
    if threading.current_thread() is not threading.main_thread():
        yield came.is_set
        return

    def on_signal(signum: int, frame: Any) -> None:
        came.set()
        raise KeyboardInterrupt

    previous = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield came.is_set
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def _run_inline(spec: Study, url: str, total: int, bar, shared: bool) -> None:
    study = open_study(spec, url, shared=shared)

    def update(study, trial) -> None:
        if trial.state in finished_states():
            bar.update(1)
            postfix(bar, study)

    _optimize(spec, study, total, [update])


def _run_processes(spec: Study, url: str, total: int, workers: int, bar, shared: bool) -> None:
    import os
    import signal

    ctx = mp.get_context("spawn")
    procs = [
        ctx.Process(target=_worker, args=(spec, url, total, w, shared, os.getpid()))
        for w in range(workers)
    ]
    # SIGINT (also when a background job started with it ignored) and SIGTERM stop the
    # workers and this process alike; a kill -9 of this process ends them by their watch
    previous = {
        sig: signal.signal(sig, signal.default_int_handler)
        for sig in (signal.SIGINT, signal.SIGTERM)
    }
    for p in procs:
        p.start()
    study = open_study(spec, url)
    try:
        while any(p.is_alive() for p in procs):
            time.sleep(1.0)  # each poll reads the storage: no more often than the bar needs
            refresh(bar, study)
        refresh(bar, study)
    except KeyboardInterrupt:
        # the workers finish their running trial and stop (Ctrl-C in a terminal reaches
        # them too; a signal from elsewhere reaches only us, so pass it on)
        for p in procs:
            if p.is_alive() and p.pid:
                os.kill(p.pid, signal.SIGINT)
        for p in procs:
            p.join(timeout=60)
            if p.is_alive():
                p.terminate()
        raise
    finally:
        for p in procs:
            p.join(timeout=10)
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    failed = [p.exitcode for p in procs if p.exitcode not in (0, None)]
    if failed:
        raise RuntimeError(
            f"{len(failed)} worker process(es) failed (exit codes {failed}); see their output above"
        )
