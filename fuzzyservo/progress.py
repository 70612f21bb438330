"""Progress of a long run on stderr: a tqdm bar on a terminal, one plain line per step
otherwise (logs, CI). The library reports progress through callbacks; this draws it."""

from __future__ import annotations

import sys
import threading
import time
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Protocol


class ProgressBar(Protocol):
    """What the long runs update (a tqdm bar is one)."""

    def set_description(self, desc: str) -> None: ...

    def set_postfix_str(self, text: str) -> None: ...

    def update(self, k: int = 1) -> object: ...

    def close(self) -> None: ...


class Lines:
    """Progress as one plain line per step on stderr, for logs and CI (no terminal)."""

    def __init__(self, total: int, desc: str):
        self.total, self.desc, self.postfix, self.n = total, desc, "", 0
        self._t0 = time.perf_counter()

    def set_description(self, desc: str) -> None:
        self.desc = desc

    def set_postfix_str(self, text: str) -> None:
        self.postfix = text

    def update(self, k: int = 1) -> None:
        self.n += k
        done = f" {self.postfix}" if self.postfix else ""
        print(
            f"{self.desc}: {self.n}/{self.total}{done} ({time.perf_counter() - self._t0:.0f} s)",
            file=sys.stderr,
            flush=True,
        )

    def close(self) -> None:
        pass


def progress_bar(total: int, desc: str) -> ProgressBar:
    """A tqdm bar on a terminal, plain progress lines otherwise."""
    if not sys.stderr.isatty():
        return Lines(total, desc)
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit="step", file=sys.stderr)


def note_compiling() -> None:
    """Before a run that may compile (the first after an install or a change of the compiled
    kernels): say so, then one line per long kernel as it starts, a line every ``TICK_S``
    while it compiles, and its time when done. A duration is promised only from this
    machine's own last compile (scaled up when the first kernels go slower); before that
    the lines say how long it has taken so far. Plain lines on stderr, on a terminal or not."""
    from fuzzyservo._jit import (
        TYPICAL_COMPILE_S,
        cache_is_cold,
        measured_compile_seconds,
        watch_compiles,
    )

    global _watching
    if _watching or not cache_is_cold():
        return
    _watching = True
    measured = measured_compile_seconds()
    known = set(measured) == set(TYPICAL_COMPILE_S)
    if known:
        took = f"about {sum(measured.values()):.0f} s, as the last time on this machine"
    else:
        took = "a few minutes on a small machine"
    print(
        f"compiling the simulation kernels: {len(TYPICAL_COMPILE_S)} long ones, {took} "
        "(first run only, after an install or a change; cached afterwards)",
        file=sys.stderr,
        flush=True,
    )
    watch = _KernelLines(measured if known else dict.fromkeys(TYPICAL_COMPILE_S, None))
    watch_compiles(watch.start, watch.end)


TICK_S = 10.0
_watching = False  # one watch per process, however many commands it runs


class _KernelLines:
    """The lines of :func:`note_compiling`: ``estimates`` names the long kernels with this
    machine's last compile times (scaled up by slow kernels done so far), or None where
    there is none, and then no duration is promised."""

    def __init__(self, estimates: dict[str, float | None]):
        self.estimates, self.scale = estimates, 1.0
        self.took: dict[str, float] = {}
        self._stop: threading.Event | None = None

    def _say(self, text: str) -> None:
        print(text, file=sys.stderr, flush=True)

    def _expected(self, name: str) -> float | None:
        value = self.estimates[name]
        return None if value is None else value * self.scale

    def start(self, name: str) -> None:
        if name not in self.estimates:
            return
        expected = self._expected(name)
        which = (
            f"kernel {len(self.took) + 1}/{len(self.estimates)} {name}"
            if name not in self.took
            else f"{name} again (other argument types)"
        )
        if expected is None:
            self._say(f"compiling {which}")
        else:
            later = [k for k in self.estimates if k not in self.took and k != name]
            left = expected + sum(self._expected(k) or 0.0 for k in later)
            self._say(f"compiling {which}: about {expected:.0f} s ({left:.0f} s left in all)")
        self._stop = threading.Event()
        t0 = time.perf_counter()

        def tick(stop: threading.Event = self._stop) -> None:
            while not stop.wait(TICK_S):
                took = time.perf_counter() - t0
                if expected is None:
                    of = "so far"
                elif took < expected:
                    of = f"of about {expected:.0f} s"
                else:
                    of = "(a busy machine takes longer)"
                self._say(f"  {name}: {took:.0f} s {of}")

        threading.Thread(target=tick, daemon=True).start()

    def end(self, name: str, seconds: float) -> None:
        if name not in self.estimates:
            return
        if self._stop is not None:
            self._stop.set()
        self.took[name] = seconds
        # only ever up: a short kernel's time is mostly fixed costs, so a fast first kernel
        # says little about the long one, while a slow one means a slow (or busy) machine
        expected = [self.estimates[k] for k in self.took]
        if None not in expected:
            self.scale = max(1.0, sum(self.took.values()) / sum(expected))
        self._say(f"compiled {name} in {seconds:.0f} s")


@contextmanager
def warnings_as_lines() -> Iterator[None]:
    """Inside the block, a :class:`~fuzzyservo.errors.FileWarning` (a file read with a
    repair, e.g. a ``.fis`` MF key read by its place) shows as one ``fuzzyservo: warning:``
    line on stderr; other warnings as Python shows them."""
    from fuzzyservo.errors import FileWarning

    def show(message, category, filename, lineno, file=None, line=None) -> None:
        if issubclass(category, FileWarning):
            print(f"fuzzyservo: warning: {message}", file=sys.stderr)
        else:
            text = warnings.formatwarning(message, category, filename, lineno, line)
            print(text, end="", file=sys.stderr if file is None else file)

    with warnings.catch_warnings():
        warnings.showwarning = show
        yield
