"""Local worker processes (fuzzyservo/executor.py) that die mid-map: a worker killed with
kill -9 has its tasks run again on a new pool, with the same results; workers that keep
dying end the map with one line naming the signal, and the CLI prints no traceback."""

from __future__ import annotations

import os
import signal
from pathlib import Path

import pytest

from fuzzyservo.errors import WorkerError
from fuzzyservo.executor import Inline, LocalProcesses


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
