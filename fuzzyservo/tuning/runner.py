"""Running a study on Optuna: samplers, storage, resume, batches, workers, progress.

The module that drives optuna (with :mod:`~fuzzyservo.tuning.integrity` and
:mod:`~fuzzyservo.tuning.warmstart`, which read its objects). Two ways to run a study:

* **Batch-synchronous** (the default, :func:`run_batches`): this process owns the sampler
  and the storage; it asks ``batch_size`` trials, an executor (:mod:`fuzzyservo.executor`:
  this process, ``--workers N`` local processes, or a Dask ``--cluster``) scores them,
  and it tells them in trial-number order. The same seeded study gives the same trials,
  hence the same best, with any number of workers, run twice, or killed (kill -9) and
  resumed. The batch size is the trade-off: the sampler learns from a batch only once it
  is told (a larger batch learns less often, keeps more workers busy and prunes against an
  older bound); the result depends on it, never on the workers.
* **Asynchronous** (``--async``): every worker process runs Optuna's own loop on the
  shared storage, which several ``tune`` commands, on several machines, may share
  (PostgreSQL). Not reproducible: the trials depend on which worker finished first.

Trials are stored as they are told (in the first mode a batch at a time, in one
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
import json
import math
import multiprocessing as mp
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fuzzyservo.display import trial_counts_text
from fuzzyservo.errors import ConfigError, require
from fuzzyservo.rig import Rig
from fuzzyservo.tuning.evaluation import Evaluation
from fuzzyservo.tuning.integrity import check_definition, die_with_parent, per_trial_seeded
from fuzzyservo.tuning.objective import Evaluator
from fuzzyservo.tuning.spec import Study
from fuzzyservo.tuning.trial import TrialResult, score
from fuzzyservo.tuning.warmstart import (
    enqueue,
    is_feasible,
    out_of_patience,
    patience_callback,
    start_points,
    stored_violations,
)

HEARTBEAT_S = 5
GRACE_S = 15


@dataclass
class StudyOutcome:
    """What a finished (or stopped) study produced."""

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
    #: robust studies: the top trials scored again on fresh samples (tuning/noise.py), the
    #: winner first; each {number, value, standard_error, fresh_value, fresh_standard_error,
    #: fresh_feasible}
    selection: list[dict[str, Any]] = field(default_factory=list)
    best_number: int | None = None
    samples_skipped: int = 0  # sampled plants the robust trials never ran (decided before)
    sampler_time_s: float = 0.0  # the sampler's time (asking the trials)
    trials_asked: int = 0  # every trial the sampler proposed (any state)
    trials_failed: int = 0  # FAIL: an error or a killed worker (not counted)
    build_time_s: float = 0.0  # in the trials: building controllers
    storage_time_s: float = 0.0  # batch mode: the parent writing the batches


def storage_url(spec: Study, out_dir: Path, override: str | None = None) -> str:
    """``--storage`` wins, then the study file's ``storage``, then SQLite in the output folder."""
    if override:
        return override
    if spec.storage:
        return spec.storage
    return f"sqlite:///{(out_dir / f'{spec.name}.db').resolve()}"


def driver_url(url: str) -> str:
    """``postgresql://`` names the psycopg2 driver we ship (SQLAlchemy 2.1 would pick psycopg 3)."""
    for prefix in ("postgresql://", "postgres://"):
        if url.startswith(prefix):
            return "postgresql+psycopg2://" + url[len(prefix) :]
    return url


def _storage(url: str):
    import optuna

    if url.startswith("sqlite"):
        # several local workers share the file: wait for the lock rather than fail
        kwargs = {"connect_args": {"timeout": 60}}
    else:
        require("psycopg2", "postgres", "a PostgreSQL storage")
        kwargs = {"pool_pre_ping": True}
    storage = optuna.storages.RDBStorage(
        driver_url(url), engine_kwargs=kwargs, heartbeat_interval=HEARTBEAT_S, grace_period=GRACE_S
    )
    if url.startswith("sqlite"):
        _fast_sqlite(storage.engine)
    return storage


def _fast_sqlite(engine) -> None:
    """Write-ahead log and no fsync per commit: a trial makes some 30 small commits, each
    about 10 ms with the default rollback journal (a third of a robust trial's own time).
    A power cut may lose the last trials, never corrupt the file; a killed process loses
    nothing."""
    from sqlalchemy import event

    def pragmas(dbapi_connection, _record) -> None:
        cursor = dbapi_connection.cursor()
        cursor.execute("PRAGMA journal_mode=WAL")
        cursor.execute("PRAGMA synchronous=NORMAL")
        cursor.close()

    event.listen(engine, "connect", pragmas)
    engine.dispose()  # connections opened while creating the tables get the pragmas too


def storage_error(url: str, exc: BaseException) -> ConfigError:
    """One line for a storage that cannot be opened or used (``exc``: what the database
    driver, SQLAlchemy or Optuna raised): a SQLite file that is no database or a damaged
    one, or a server or URL that does not answer; each with its fix."""
    import sqlite3

    cause = exc
    while cause.__cause__ is not None:  # Optuna's StorageInternalError wraps SQLAlchemy's
        cause = cause.__cause__
    cause = getattr(cause, "orig", None) or cause  # SQLAlchemy's wraps the driver's
    reason = (str(cause).strip().splitlines() or [type(cause).__name__])[0]
    garbled = isinstance(cause, sqlite3.DatabaseError) and not isinstance(
        cause, sqlite3.OperationalError
    )
    if garbled:
        return ConfigError(
            f"storage {url}: not an Optuna study database, or a damaged one ({reason}); move "
            "the file away (the study then starts afresh) or give another --storage"
        )
    return ConfigError(
        f"storage {url}: cannot open or use it ({reason}); check that the server runs and the URL "
        "(--storage or the study's storage key), or leave it out for SQLite in the output folder"
    )


def storage_faults() -> tuple[type[BaseException], ...]:
    """What a storage raises when its database is damaged or gone while in use."""
    import optuna
    from sqlalchemy.exc import SQLAlchemyError

    return (optuna.exceptions.StorageInternalError, SQLAlchemyError)


def _record_constraints(trial, spec: Study, violations: list[float]) -> None:
    """Store violations where the samplers look (``set_constraint``, optuna >= 5) and in user_attrs."""
    trial.set_user_attr("constraints", violations)
    if hasattr(trial, "set_constraint"):
        for c, v in zip(spec.constraints, violations, strict=True):
            trial.set_constraint(str(c), v)


def make_sampler(spec: Study, seed: int | None):
    import optuna

    # optuna >= 5 reads the constraints stored by Trial.set_constraint; older ones need constraints_func
    legacy = {}
    if spec.constraints and not hasattr(optuna.trial.Trial, "set_constraint"):
        legacy = {"constraints_func": stored_violations}
    if spec.sampler == "tpe":
        return optuna.samplers.TPESampler(seed=seed, multivariate=True, **legacy)
    if spec.sampler == "nsga2":
        return optuna.samplers.NSGAIISampler(seed=seed, **legacy)
    if spec.sampler == "cmaes":
        return optuna.samplers.CmaEsSampler(seed=seed, warn_independent_sampling=False)
    if spec.sampler == "qmc":  # scrambled Sobol points: space-filling, learns nothing
        return optuna.samplers.QMCSampler(seed=seed, scramble=True, warn_independent_sampling=False)
    if spec.sampler == "gp":  # Gaussian-process Bayesian optimisation (needs PyTorch)
        require("torch", "gp", "the gp sampler (Optuna's GPSampler runs on PyTorch)")
        return optuna.samplers.GPSampler(seed=seed, **legacy)
    return optuna.samplers.RandomSampler(seed=seed)


def open_study(spec: Study, url: str, worker: int = 0, *, shared: bool = False):
    """Create or load the study, check that it was made by this definition
    (:func:`~fuzzyservo.tuning.integrity.check_definition`: a :class:`ConfigError` naming
    what changed otherwise), and give it a sampler seeded per trial
    (:func:`~fuzzyservo.tuning.integrity.per_trial_seeded`: no two trials, in any process,
    replay one random stream). ``worker`` and ``shared`` are kept for callers; the trial
    number alone decides the seed."""
    import random
    import warnings

    import optuna
    from sqlalchemy.exc import IntegrityError, OperationalError, ProgrammingError, SQLAlchemyError

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    # the storage heartbeat is what fails trials of a killed process; it is marked experimental
    warnings.filterwarnings("ignore", category=optuna.exceptions.ExperimentalWarning)
    # CMA-ES samples without the constraints (docs/samplers.md: it finds feasible bests anyway)
    warnings.filterwarnings("ignore", "Constraints have been set, but CmaEsSampler", UserWarning)
    directions = ["minimize"] * spec.objective.n_values
    for attempt in range(5):
        try:
            storage = _storage(url)
            study = optuna.create_study(
                study_name=spec.name,
                storage=storage,
                directions=directions,
                load_if_exists=True,
            )
            break
        except (
            IntegrityError,
            ProgrammingError,
            OperationalError,
            optuna.exceptions.DuplicatedStudyError,
        ) as exc:
            # two processes creating the tables or the study at once on an empty database
            if attempt == 4:
                raise storage_error(url, exc) from None
            time.sleep(0.2 + random.random())
        except (SQLAlchemyError, ImportError, optuna.exceptions.StorageInternalError) as exc:
            raise storage_error(url, exc) from None  # a driver or URL we cannot use, damage
    check_definition(study, spec, url)
    study.sampler = per_trial_seeded(make_sampler(spec, spec.seed), spec.seed)
    return study


def build_evaluator(spec: Study) -> Evaluator:
    """The trial evaluator of a study (it scores the baseline first)."""
    return Evaluator(spec)


def _suggest(trial, spec: Study) -> dict[str, float]:
    """The trial's numbers, drawn by the study's sampler."""
    params = {}
    for p in spec.parameters:
        if p.integer:
            params[p.path] = trial.suggest_int(p.path, int(p.low), int(p.high), log=p.log)
        else:
            params[p.path] = trial.suggest_float(p.path, p.low, p.high, log=p.log)
    return params


def _prunes(spec: Study) -> bool:
    """Robust single-objective trials stop once hopeless (tuning/trial.py)."""
    return spec.uncertainty is not None and spec.objective.n_values == 1


def _record(trial, spec: Study, result: TrialResult) -> None:
    """The result's attributes and constraints on the Optuna trial (and, for a pruned
    trial, its last value: TPE ranks a pruned trial by it)."""
    for key, value in result.user_attrs.items():
        trial.set_user_attr(key, value)
    _record_constraints(trial, spec, list(result.constraints))
    if result.pruned_at is not None:
        step, value = result.pruned_at
        trial.report(value, step)


def _objective(spec: Study, evaluator: Evaluator):
    """The asynchronous mode's objective: the pruning bound is read at the trial's start."""

    def objective(trial) -> float | tuple[float, ...]:
        params = _suggest(trial, spec)
        bound = _best_feasible_value(trial.study) if _prunes(spec) else None
        result = score(spec, evaluator, params, bound)
        _record(trial, spec, result)
        if result.pruned_at is not None:
            import optuna

            raise optuna.TrialPruned(result.user_attrs.get("message", ""))
        return result.values if len(result.values) > 1 else result.values[0]

    return objective


def trial_counts(study) -> dict[str, int]:
    """The study's trials: ``asked`` (every state), ``complete``, ``pruned``, ``failed``."""
    from optuna.trial import TrialState

    states = [t.state for t in study.get_trials(deepcopy=False)]
    return {"asked": len(states), "complete": states.count(TrialState.COMPLETE),
            "pruned": states.count(TrialState.PRUNED), "failed": states.count(TrialState.FAIL)}  # fmt: skip


def count_complete(study) -> int:
    """Finished trials: COMPLETE, and PRUNED (a robust trial stopped as hopeless)."""
    return len(study.get_trials(deepcopy=False, states=_finished()))


def _finished() -> tuple:
    """The trial states that count towards a study's ``trials``."""
    from optuna.trial import TrialState

    return (TrialState.COMPLETE, TrialState.PRUNED)


def _best_feasible_value(study) -> float | None:
    from optuna.trial import TrialState

    values = [
        t.value
        for t in study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,))
        if is_feasible(t)
    ]
    return min(values) if values else None


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
            callbacks=[MaxTrialsCallback(total, states=_finished()), *extra_callbacks],
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

    Batch-synchronous (the default; :func:`run_batches`): the same seeded study gives the
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

        raise ConfigError("--cluster runs batches; leave out --async (or --cluster)")
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
    study = open_study(spec, url)  # creates it (and its tables) before any worker starts
    done_before = count_complete(study)
    if done_before and progress:
        left = max(total - done_before, 0)
        counts = trial_counts_text(**trial_counts(study))
        print(f"resuming study {spec.name}: {done_before} of {total} trials done "
              f"({counts}), {left} to run ({url})", file=sys.stderr, flush=True)  # fmt: skip
    t0 = time.perf_counter()
    _warm_kernels(spec)  # before the bar: its rate (and ETA) should not count compiling
    bar = _bar(total, done_before, spec.name, progress)
    try:
        if executor is not None:
            with _interruptible() as interrupted:
                run_batches(spec, study, total, executor, bar, interrupted)
        else:
            enqueue(study, spec)
            if workers <= 1:
                _run_inline(spec, url, total, bar, shared)
            else:
                _run_processes(spec, url, total, workers, bar, shared)
    finally:
        bar.close()
    wall = time.perf_counter() - t0
    # a batch run wrote every trial through this study: read it back without reopening
    return collect(spec, url, wall_s=wall, executor=executor,
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

    told = stored.get_trials(deepcopy=False, states=_finished())
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
        bound = _best_feasible_value(memory) if _prunes(spec) else None
        trials = [memory.ask() for _ in range(size)]
        tasks = [Task(t.number, _suggest(t, spec), bound) for t in trials]
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
            _postfix(bar, memory)
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

    _record(trial, spec, result)
    trial.set_user_attr(BATCH_ATTR, batch)
    if result.pruned_at is not None:
        study.tell(trial, state=TrialState.PRUNED)
    else:
        study.tell(trial, list(result.values))


def _run_inline(spec: Study, url: str, total: int, bar, shared: bool) -> None:
    study = open_study(spec, url, shared=shared)

    def update(study, trial) -> None:
        if trial.state in _finished():
            bar.update(1)
            _postfix(bar, study)

    _optimize(spec, study, total, [update])


def _run_processes(spec: Study, url: str, total: int, workers: int, bar, shared: bool) -> None:
    import os
    import signal

    _warm_kernels(spec)
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
            _refresh(bar, study)
        _refresh(bar, study)
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


def _warm_kernels(spec: Study) -> None:
    """Compile the kernels here, once, before the workers start (else each compiles them)."""
    from fuzzyservo._jit import cache_is_cold

    if not cache_is_cold():
        return
    from fuzzyservo.simulation import simulate

    rig = spec.rig
    simulate(rig, spec.template, spec.scenarios[0], duration_s=10 * rig.sample_time_s)
    if spec.uncertainty is not None:  # its trials run their samples' checks in lock-step
        from fuzzyservo.simulation.closed_loop import simulate_batch
        from fuzzyservo.tuning.robust import sample_rigs

        seeds = [d.noise_seed for d in spec.uncertainty.draws[:2]]
        simulate_batch(sample_rigs(rig, spec)[:2], spec.template, spec.scenarios[0], seeds)


def _refresh(bar, study) -> None:
    n = count_complete(study)
    if n > bar.n:
        bar.update(n - bar.n)
    _postfix(bar, study)


def _postfix(bar, study) -> None:
    best = _best_value(study)
    if best is not None:
        bar.set_postfix_str(f"best {best:.4g}")


def _best_value(study) -> float | None:
    try:
        if len(study.directions) == 1:
            return study.best_value
    except ValueError:
        return None
    return None


class _NoBar:
    n = 0

    def update(self, k: int = 1) -> None:
        self.n += k

    def set_postfix_str(self, text: str) -> None:
        pass

    def close(self) -> None:
        pass


def _bar(total: int, initial: int, name: str, enabled: bool):
    import sys

    if not enabled:
        bar = _NoBar()
        bar.n = initial
        return bar
    from tqdm import tqdm

    return tqdm(
        total=total,
        initial=initial,
        desc=name,
        unit="trial",
        file=sys.stderr,
        dynamic_ncols=True,
        mininterval=0.5,
    )


def _trial_time(trial) -> float:
    """A trial's own time (a batch's trials all start at its ask and end at its tell)."""
    if "trial_time_s" in trial.user_attrs:
        return trial.user_attrs["trial_time_s"]
    if trial.datetime_complete and trial.datetime_start:
        return (trial.datetime_complete - trial.datetime_start).total_seconds()
    return 0.0


def collect(spec: Study, url: str, *, wall_s: float = 0.0, executor=None,
            study=None) -> StudyOutcome:  # fmt: skip
    """Read the study back: best (feasible) trial or Pareto front, history, importances.
    A robust study's best is chosen among its top trials on fresh samples
    (:func:`select_on_fresh_samples`, scored by ``executor``, default this process).
    ``study``: the study at ``url`` already open (default: open it)."""
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
    finished = study.get_trials(deepcopy=False, states=_finished())  # with pruned ones
    sim = sum(t.user_attrs.get("sim_time_s", 0.0) for t in finished)
    worker_time = sum(_trial_time(t) for t in finished)
    counts = trial_counts(study)
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
    )


def _work(trial, key: str) -> float:
    """One figure of a stored trial's ``work`` record (0 for a study stored before it)."""
    return trial.user_attrs.get("work", {}).get(key, 0)


def select_on_fresh_samples(spec: Study, pool: list, executor=None) -> tuple[Any, list[dict]]:
    """The best of the :data:`~fuzzyservo.tuning.noise.TOP` lowest trials of ``pool`` on
    fresh samples (:func:`~fuzzyservo.tuning.noise.fresh_uncertainty`; feasible there
    first, then by value), and every candidate's values with their standard errors."""
    from fuzzyservo.executor import Inline
    from fuzzyservo.tuning.integrity import fingerprint
    from fuzzyservo.tuning.noise import TOP, fresh_uncertainty, standard_error
    from fuzzyservo.tuning.trial import Task, TrialRunner

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
