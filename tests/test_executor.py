"""Local worker processes (fuzzyservo/executor.py) that die mid-map: a worker killed with
kill -9 has its tasks run again on a new pool, with the same results; workers that keep
dying end the map with one line naming the signal, and the CLI prints no traceback. A
stream of tasks draws its items at the same moments on any executor."""

from __future__ import annotations

import os
import signal
from pathlib import Path

import pytest

from fuzzyservo.errors import WorkerError
from fuzzyservo.executor import Inline, LocalProcesses, stream


def _square_killing_once(item: tuple[int, str]) -> int:
    """``k * k``; item 2 kills its own worker (kill -9) the first time it runs."""
    k, marker = item
    if k == 2 and marker and not Path(marker).exists():
        Path(marker).touch()
        os.kill(os.getpid(), signal.SIGKILL)
    return k * k


def _always_killed(item: int) -> int:
    os.kill(os.getpid(), signal.SIGKILL)
    return item


def test_a_worker_killed_mid_map_has_its_task_run_again(tmp_path, capsys):
    items = [(k, str(tmp_path / "killed")) for k in range(6)]
    pool = LocalProcesses(2)
    done = []
    try:
        got = pool.map(_square_killing_once, items, done.append)
        assert got == Inline().map(_square_killing_once, [(k, "") for k in range(6)])
        assert sorted(done) == list(range(6))  # each item counted once
        assert pool.map(_square_killing_once, items[:3]) == [0, 1, 4]  # the new pool works on
    finally:
        pool.close()
    assert (tmp_path / "killed").exists()
    err = capsys.readouterr().err
    assert "a worker process died (killed by signal 9 (SIGKILL)" in err, err


def test_workers_that_keep_dying_end_the_map_in_one_line():
    pool = LocalProcesses(1)
    try:
        with pytest.raises(WorkerError) as info:
            pool.map(_always_killed, [1])
    finally:
        pool.close()
    text = str(info.value)
    assert "died 3 times" in text and "SIGKILL" in text and "\n" not in text, text


def _slow_square(k: int) -> int:
    import time

    time.sleep(0.01 * (k % 3))  # finishing out of order on two workers
    return k * k


def _feedback_run(executor, ahead: int) -> tuple[list[int], list[int]]:
    """A caller that learns from each result before drawing the next item (as a sampler
    asks a trial only after telling the one before): each item is the sum of the
    results seen so far; returns the items and, for each draw, how many results it saw."""
    seen: list[int] = []
    drawn: list[int] = []
    items: list[int] = []

    def source():
        for _ in range(9):
            drawn.append(len(seen))
            items.append(sum(seen) % 7)
            yield items[-1]

    for result in stream(lambda k: executor.submit(_slow_square, k), source(), ahead):
        seen.append(result)
    return items, drawn


def test_a_stream_draws_at_the_same_moments_on_any_executor_and_keeps_tasks_in_flight(tmp_path):
    """stream(): the items drawn, hence the results, are the same inline and on two
    worker processes; the first `ahead` items are drawn before any result, then one
    after each result; a worker killed mid-stream has its tasks run again."""
    inline = _feedback_run(Inline(), 3)
    pool = LocalProcesses(2)
    try:
        assert _feedback_run(pool, 3) == inline
        killed = [
            pool.submit(_square_killing_once, (k, str(tmp_path / "killed"))) for k in range(4)
        ]
        assert [p.result() for p in killed] == [0, 1, 4, 9]
    finally:
        pool.close()
    assert inline[1] == [0, 0, 0, 1, 2, 3, 4, 5, 6]
