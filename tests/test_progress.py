"""A cold start you can follow: the kernels numba compiles are reported one by one, with an
estimate that this machine's own compile times replace (issue 30, item 5)."""

from __future__ import annotations

import numba
import pytest

from fuzzyservo._jit import TYPICAL_COMPILE_S, compile_estimates, watch_compiles
from fuzzyservo.progress import _KernelLines


@pytest.fixture
def cache_in_tmp(tmp_path, monkeypatch):
    """numba's cache folder (and so the compile-time file) under tmp_path, as a user's
    ``NUMBA_CACHE_DIR`` would put it."""
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(numba.config, "CACHE_DIR", str(tmp_path))
    return tmp_path


def test_each_top_level_compile_is_reported_and_its_time_kept(cache_in_tmp):
    @numba.njit
    def helper(x):
        return 2.0 * x

    @numba.njit
    def closed_loop(x):  # named as the long kernel, so its time is kept
        return helper(x) + 1.0

    assert compile_estimates() == TYPICAL_COMPILE_S  # nothing compiled on this "machine" yet
    started, ended = [], []
    stop = watch_compiles(started.append, lambda name, s: ended.append((name, s)))
    try:
        assert closed_loop(1.0) == 3.0
        closed_loop(2.0)  # compiled already: no event
    finally:
        stop()
    assert started == ["closed_loop"], "the kernel it calls is part of its compile"
    assert [name for name, _ in ended] == ["closed_loop"] and ended[0][1] > 0
    assert compile_estimates()["closed_loop"] == pytest.approx(ended[0][1], abs=0.06)
    assert (cache_in_tmp / "compile_seconds.json").is_file()


def test_lines_per_kernel_with_an_estimate_scaled_by_the_kernels_done(capsys):
    fast = _KernelLines({"plant_signals": 10.0, "closed_loop": 30.0})
    fast.end("plant_signals", 2.0)  # a fast first kernel: the long one's estimate stays
    assert fast.scale == 1.0
    lines = _KernelLines({"plant_signals": 10.0, "closed_loop": 30.0})
    lines.start("plant_signals")
    lines.end("plant_signals", 20.0)  # this machine is twice as slow as the typical one
    lines.start("closed_loop")
    lines.end("closed_loop", 55.0)
    lines.start("term_index")  # short kernels: no line
    lines.end("term_index", 0.1)
    assert capsys.readouterr().err.splitlines() == [
        "compiled plant_signals in 2 s",
        "compiling kernel 1/2 plant_signals: about 10 s (40 s left in all)",
        "compiled plant_signals in 20 s",
        "compiling kernel 2/2 closed_loop: about 60 s (60 s left in all)",
        "compiled closed_loop in 55 s",
    ]


def test_no_duration_is_promised_before_this_machine_has_compiled(capsys):
    """Before the first compile on a machine the lines count the time taken, and promise none."""
    lines = _KernelLines({"plant_signals": None, "closed_loop": None})
    lines.start("plant_signals")
    lines.end("plant_signals", 20.0)
    lines.start("closed_loop")
    lines.end("closed_loop", 95.0)
    assert capsys.readouterr().err.splitlines() == [
        "compiling kernel 1/2 plant_signals",
        "compiled plant_signals in 20 s",
        "compiling kernel 2/2 closed_loop",
        "compiled closed_loop in 95 s",
    ]


def test_the_first_line_states_a_duration_only_from_this_machine(cache_in_tmp, monkeypatch, capsys):
    import json

    import fuzzyservo.progress as progress
    from fuzzyservo import _jit

    monkeypatch.setattr(_jit, "cache_is_cold", lambda: True)
    monkeypatch.setattr(_jit, "watch_compiles", lambda start, end: lambda: None)
    monkeypatch.setattr(progress, "_watching", False)
    progress.note_compiling()
    first = capsys.readouterr().err.splitlines()[0]
    assert "a few minutes on a small machine" in first and "about" not in first, first
    (cache_in_tmp / "compile_seconds.json").write_text(
        json.dumps({"plant_signals": 3.0, "closed_loop": 100.0, "signal_table": 4.0})
    )
    monkeypatch.setattr(progress, "_watching", False)
    progress.note_compiling()
    first = capsys.readouterr().err.splitlines()[0]
    assert "about 107 s, as the last time on this machine" in first, first
