"""A cold start you can follow: every compile is one line, naming what it compiled and how
long that took, and no time is promised before it is known (issue 56, item 6)."""

from __future__ import annotations

import numba

from fuzzyservo._jit import compile_step, watch_compiles
from fuzzyservo.progress import _CompileLines


def test_each_top_level_compile_is_reported_once_by_what_it_is() -> None:
    @numba.njit
    def helper(x):
        return 2.0 * x

    @numba.njit
    def closed_loop(x):  # named as the loop: reported as the loop
        return helper(x) + 1.0

    started, ended = [], []
    stop = watch_compiles(started.append, lambda what, s: ended.append((what, s)))
    try:
        assert closed_loop(1.0) == 3.0
        closed_loop(2.0)  # compiled already: no event
    finally:
        stop()
    assert started == ["the closed loop (once per install)"], "its callee is part of it"
    assert [what for what, _ in ended] == started and ended[0][1] > 0


def test_a_step_reports_its_compiles_as_one_and_nothing_when_nothing_compiled() -> None:
    @numba.njit
    def first(x):
        return x + 1.0

    @numba.njit
    def second(x):
        return x * 3.0

    started, ended = [], []
    stop = watch_compiles(started.append, lambda what, s: ended.append((what, s)))
    try:
        with compile_step("the plant's kernels (two)"):
            first(1.0)
            second(1.0)
        with compile_step("the plant's kernels (again)"):
            first(2.0)  # compiled: no line
    finally:
        stop()
    assert started == ["the plant's kernels (two)"]
    assert [what for what, _ in ended] == started


def test_one_line_per_compile_after_one_that_says_why(capsys) -> None:
    lines = _CompileLines()
    lines.start("the plant's kernels (x)")
    lines.end("the plant's kernels (x)", 2.04)
    lines.start("the closed loop (once per install)")
    lines.end("the closed loop (once per install)", 7.3)
    err = capsys.readouterr().err.splitlines()
    assert err == [
        "compiling for this machine (the first run, or a new plant or kernel; cached afterwards):",
        "  compiled the plant's kernels (x) in 2.0 s",
        "  compiled the closed loop (once per install) in 7.3 s",
    ]
    assert not any("about" in line or "minutes" in line for line in err)  # no promise
