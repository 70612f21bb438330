"""Where parallel work runs: in this process, in local worker processes, or on a Dask cluster.

One concept for every parallel job of the workbench (a tuning study's batch of trials,
a Monte Carlo's samples, a calibration's candidates): an :class:`Executor` maps a
picklable function over a list of picklable items and returns the results **in the
order of the items**, whichever worker computed which. The callers decide everything
that makes the numbers (what to compute, in which order to use the results); the
executor only decides where, so 1 worker, N local processes or a cluster give the
same numbers.

* :class:`Inline`: one after the other in this process (``--workers 1``);
* :class:`LocalProcesses`: a pool of ``spawn`` processes that end with this one
  (``--workers N``);
* :class:`DaskCluster`: the workers of a Dask distributed scheduler (``--cluster
  tcp://HOST:8786``; ``dask scheduler`` on one machine, ``dask worker tcp://HOST:8786``
  on each of the others, every one with fuzzyservo importable). A worker that dies
  mid-batch has its tasks re-run by the scheduler on another worker; no result is lost.

Stdlib only at import; ``distributed`` is imported when a cluster is asked for (the
``cluster`` extra: ``pip install 'fuzzyservo[cluster]'``).
"""

from __future__ import annotations

import os
import signal
import sys
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Sequence
from typing import Any, Protocol

from fuzzyservo.errors import ConfigError, WorkerError, require


class Pending(Protocol):
    """A submitted task: :meth:`result` waits for it (and raises what the task raised)."""

    def result(self) -> Any: ...

    def cancel(self) -> None: ...


class Executor(Protocol):
    """Maps a function over items, results in the items' order; ``on_done(k)`` as item
    ``k`` finishes (in any order: for progress only). :meth:`submit` starts one task
    (:func:`stream` keeps a fixed number of them in flight)."""

    #: how many tasks run at once at most (a hint for progress and batching)
    workers: int

    def map(self, fn: Callable[[Any], Any], items: Sequence[Any],
            on_done: Callable[[int], object] | None = None) -> list[Any]: ...  # fmt: skip

    def submit(self, fn: Callable[[Any], Any], item: Any) -> Pending: ...

    def close(self) -> None: ...


def stream(submit: Callable[[Any], Pending], items: Iterable[Any], ahead: int) -> Iterator[Any]:
    """The results of ``submit(item)`` (an executor's :meth:`~Executor.submit` of one
    task) in the items' order, with ``ahead`` tasks in flight.

    The items are drawn lazily and at fixed moments: ``ahead`` of them first, then one
    more each time the caller comes back for the next result. A caller that learns from
    each result before drawing the next item (a sampler told a trial before it asks the
    next) therefore sees the same history at every draw on any executor, with any
    number of workers, while the workers are never left without a task. Leaving the
    loop early cancels the tasks still in flight."""
    source = iter(items)
    flight: deque[Pending] = deque()

    def draw() -> None:
        for item in source:
            flight.append(submit(item))
            return

    try:
        for _ in range(ahead):
            draw()
        while flight:
            result = flight[0].result()
            flight.popleft()
            yield result
            draw()
    finally:
        for pending in flight:
            pending.cancel()


class Inline:
    """Everything in this process, one item after the other."""

    workers = 1

    def map(self, fn: Callable[[Any], Any], items: Sequence[Any],
            on_done: Callable[[int], object] | None = None) -> list[Any]:  # fmt: skip
        out = []
        for k, item in enumerate(items):
            out.append(fn(item))
            if on_done is not None:
                on_done(k)
        return out

    def submit(self, fn: Callable[[Any], Any], item: Any) -> Pending:
        return _Later(fn, item)

    def close(self) -> None:
        pass

    def describe(self) -> str:
        return "1 worker (this process)"


class _Later:
    """An inline task: run when its result is asked for."""

    def __init__(self, fn: Callable[[Any], Any], item: Any):
        self.fn, self.item = fn, item

    def result(self) -> Any:
        return self.fn(self.item)

    def cancel(self) -> None:
        pass


class LocalProcesses:
    """``workers`` processes on this machine (``spawn``: a fresh interpreter each, which
    imports fuzzyservo like the parent), ended with the parent (:func:`die_with_parent`).

    A worker that dies mid-map (``kill -9``, the out-of-memory killer) breaks the pool:
    the pool is started again and the items without a result are run again, up to
    :data:`RESTARTS` times in one map (an item's result depends on the item alone, so
    nothing changes); then :class:`~fuzzyservo.errors.WorkerError` says so in one line."""

    #: new pools one map may start after its workers died
    RESTARTS = 2

    def __init__(self, workers: int):
        self.workers = workers
        self._procs: dict[int, Any] = {}  # pid -> process of this pool
        self._flight: list[_PoolTask] = []  # submitted tasks not yet awaited
        self._pool = self._start()

    def _start(self):
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor

        return ProcessPoolExecutor(
            max_workers=self.workers,
            mp_context=mp.get_context("spawn"),
            initializer=_pool_worker,
            initargs=(os.getpid(),),
        )

    def map(self, fn: Callable[[Any], Any], items: Sequence[Any],
            on_done: Callable[[int], object] | None = None) -> list[Any]:  # fmt: skip
        from concurrent.futures.process import BrokenProcessPool

        results: dict[int, Any] = {}
        for restarts in range(self.RESTARTS + 1):
            try:
                self._run(fn, items, results, on_done)
                break
            except BrokenProcessPool:
                self._restart(restarts, len(items) - len(results))
        return [results[k] for k in range(len(items))]

    def _restart(self, restarts: int, left: int) -> None:
        """After the pool broke (a worker died): end it, say so, start a new one; the
        ``restarts``-th time (counted from 0) past :data:`RESTARTS` raises WorkerError."""
        codes = self._end_pool()
        # the pool ends a dead worker's siblings with SIGTERM: name the one that died
        term = (-signal.SIGTERM, 128 + signal.SIGTERM)
        codes = [c for c in codes if c not in term] or codes
        died = ", ".join(_exit_text(c) for c in codes) or "ended"
        if restarts == self.RESTARTS:
            raise WorkerError(
                f"local worker processes died {restarts + 1} times in one batch "
                f"(last: {died}); the results told so far are kept: run the command "
                "again to resume, with fewer --workers if memory ran out"
            ) from None
        print(f"fuzzyservo: a worker process died ({died}); {left} task(s) run again "
              "on new workers", file=sys.stderr, flush=True)  # fmt: skip
        self._pool = self._start()

    def submit(self, fn: Callable[[Any], Any], item: Any) -> Pending:
        """One task; when its pool breaks while it is awaited, every task still in flight
        is run again on a new pool (up to :data:`RESTARTS` times for one task)."""
        task = _PoolTask(self, fn, item)
        self._flight.append(task)
        task.future = self._pool.submit(fn, item)
        self._procs.update((getattr(self._pool, "_processes", None) or {}).items())
        return task

    def _await(self, task: _PoolTask) -> Any:
        from concurrent.futures.process import BrokenProcessPool

        restarts = 0
        while True:
            try:
                result = task.future.result()
            except BrokenProcessPool:
                self._restart(restarts, len(self._flight))
                restarts += 1
                for waiting in self._flight:
                    waiting.future = self._pool.submit(waiting.fn, waiting.item)
                continue
            self._flight.remove(task)
            return result

    def _run(self, fn: Callable[[Any], Any], items: Sequence[Any], results: dict[int, Any],
             on_done: Callable[[int], object] | None) -> None:  # fmt: skip
        """Run the items without a result into ``results``; a task's exception (or a
        broken pool) stops here, keeping the results of the tasks that finished."""
        from concurrent.futures import as_completed

        futures = {self._pool.submit(fn, item): k for k, item in enumerate(items)
                   if k not in results}  # fmt: skip
        # the workers, as submitting started them: a broken pool may drop a dead one from
        # its own list before we ask for its exit code
        self._procs.update((getattr(self._pool, "_processes", None) or {}).items())
        try:
            for future in as_completed(futures):
                results[futures[future]] = future.result()
                if on_done is not None:
                    on_done(futures[future])
        finally:
            for future, k in futures.items():
                future.cancel()
                if future.done() and not future.cancelled() and future.exception() is None:
                    results.setdefault(k, future.result())

    def _end_pool(self) -> list[int | None]:
        """Shut the pool down without waiting, end and reap its processes; their exit codes."""
        procs = list({**self._procs, **(getattr(self._pool, "_processes", None) or {})}.values())
        self._procs = {}
        self._pool.shutdown(wait=False, cancel_futures=True)
        for proc in procs:
            if proc.is_alive():
                proc.terminate()
        for proc in procs:
            proc.join(timeout=10)  # reaped: no zombie, their CPU time counted as ours
        # the pool's own thread may reap a dead worker at the same moment (its waitpid
        # wins, ours finds no child): the exit code is then set a moment later
        deadline = time.monotonic() + 2.0
        while any(p.exitcode is None for p in procs) and time.monotonic() < deadline:
            time.sleep(0.01)
        return [proc.exitcode for proc in procs if proc.exitcode]

    def close(self) -> None:
        # a Ctrl-C mid-batch: drop the queued tasks, do not wait for the running ones
        self._end_pool()

    def describe(self) -> str:
        return f"{self.workers} local worker processes"


class _PoolTask:
    """A task submitted to :class:`LocalProcesses` (its future changes with the pool)."""

    def __init__(self, owner: LocalProcesses, fn: Callable[[Any], Any], item: Any):
        self.owner, self.fn, self.item = owner, fn, item
        self.future: Any = None

    def result(self) -> Any:
        return self.owner._await(self)

    def cancel(self) -> None:
        self.future.cancel()
        if self in self.owner._flight:
            self.owner._flight.remove(self)


class DaskCluster:
    """The workers of the Dask scheduler at ``address`` (``tcp://HOST:PORT``)."""

    def __init__(self, address: str, timeout_s: float = 30.0):
        require("distributed", "cluster", f"the Dask cluster {address}")
        from distributed import Client

        try:
            self._client = Client(address, timeout=timeout_s, set_as_default=False)
        except (OSError, TimeoutError) as exc:
            reason = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
            raise ConfigError(
                f"{address}: cannot reach the Dask scheduler ({reason}); start "
                "`dask scheduler` there and `dask worker ADDRESS` on the machines that compute",
                argument="cluster",
            ) from None
        self.address = address
        self._client.wait_for_workers(1, timeout=timeout_s)
        self.workers = max(1, sum(self._client.nthreads().values()))

    def map(self, fn: Callable[[Any], Any], items: Sequence[Any],
            on_done: Callable[[int], object] | None = None) -> list[Any]:  # fmt: skip
        from distributed import as_completed

        # pure=False: the same item twice is computed twice, never taken from a cache of
        # another study; a task lost with its worker is re-run by the scheduler
        futures = self._client.map(fn, list(items), pure=False)
        index = {f.key: k for k, f in enumerate(futures)}
        try:
            for future in as_completed(futures, loop=self._client.loop):
                if on_done is not None:
                    on_done(index[future.key])
            return self._client.gather(futures)
        finally:
            self._client.cancel(futures)

    def submit(self, fn: Callable[[Any], Any], item: Any) -> Pending:
        # pure=False, as in map; a task lost with its worker is re-run by the scheduler
        return self._client.submit(fn, item, pure=False)

    def close(self) -> None:
        self._client.close()

    def describe(self) -> str:
        return f"Dask cluster {self.address} ({self.workers} worker thread(s))"


def cluster_problem(address: str) -> str | None:
    """Why ``address`` is no Dask scheduler address, or ``None`` (reachability is found
    out when connecting)."""
    if not address.startswith(("tcp://", "tls://", "inproc://", "ucx://")):
        return (
            f"{address!r} is not a Dask scheduler address; give it as tcp://HOST:PORT "
            "(the address `dask scheduler` prints, port 8786 by default)"
        )
    return None


def make_executor(workers: int = 1, cluster: str | None = None) -> Executor:
    """A Dask cluster when ``cluster`` names a scheduler, else ``workers`` local processes
    (1: this process)."""
    if cluster:
        problem = cluster_problem(cluster)
        if problem:
            raise ConfigError(problem, argument="cluster")
        return DaskCluster(cluster)
    if workers <= 1:
        return Inline()
    return LocalProcesses(workers)


# --------------------------------------------------------------------------- orphans
_PR_SET_PDEATHSIG = 1


def die_with_parent(parent_pid: int, poll_s: float = 1.0) -> None:
    """End this process when ``parent_pid`` ends: SIGTERM from the kernel on Linux
    (``prctl(PR_SET_PDEATHSIG)``), and a daemon thread that checks the parent every
    ``poll_s`` everywhere (and the race where the parent died before the request).
    SIGTERM then stops the process at once."""
    signal.signal(signal.SIGTERM, _exit_now)
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0)
        except (OSError, AttributeError):
            pass
    if os.getppid() != parent_pid:  # died before we asked
        _exit_now(signal.SIGTERM, None)

    def watch() -> None:
        while True:
            time.sleep(poll_s)
            if os.getppid() != parent_pid:
                os.kill(os.getpid(), signal.SIGTERM)
                return

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()


def _pool_worker(parent_pid: int) -> None:
    """A pool process: ends with its parent; Ctrl-C is the parent's to handle (it drops
    the batch and ends the pool), so the worker ignores it."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    die_with_parent(parent_pid)


def _exit_text(code: int | None) -> str:
    """A worker's exit code in words: ``killed by signal 9 (SIGKILL)``, ``exit code 1``."""
    if code is not None and code < 0:
        try:
            return f"killed by signal {-code} ({signal.Signals(-code).name})"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit code {code}"


def _exit_now(signum: int, frame: Any) -> None:
    os._exit(128 + int(signum))


__all__ = ["DaskCluster", "Executor", "Inline", "LocalProcesses", "Pending", "die_with_parent",
           "make_executor", "stream"]  # fmt: skip
