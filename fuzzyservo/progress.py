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
    kernels): say so, then one line per long kernel as it starts, with an estimate from
    this machine's last compile (else a typical one, scaled up when the first kernels
    went slower), a line every ``TICK_S`` while it compiles, and its time when done. Plain lines
    on stderr, on a terminal or not."""
    from fuzzyservo._jit import cache_is_cold, compile_estimates, watch_compiles

    global _watching
    if _watching or not cache_is_cold():
        return
    _watching = True
    estimates = compile_estimates()
    total = sum(estimates.values())
    print(
        f"compiling the simulation kernels: {len(estimates)} long ones, about {total:.0f} s "
        "(first run only, after an install or a change; cached afterwards)",
        file=sys.stderr,
        flush=True,
    )
    watch = _KernelLines(estimates)
    watch_compiles(watch.start, watch.end)


TICK_S = 10.0
_watching = False  # one watch per process, however many commands it runs


class _KernelLines:
    """The lines of :func:`note_compiling` (the estimate is scaled up by slow kernels done so far)."""

    def __init__(self, estimates: dict[str, float]):
        self.estimates, self.scale = estimates, 1.0
        self.took: dict[str, float] = {}
        self._stop: threading.Event | None = None

    def _say(self, text: str) -> None:
        print(text, file=sys.stderr, flush=True)

    def start(self, name: str) -> None:
        if name not in self.estimates:
            return
        expected = self.estimates[name] * self.scale
        later = [k for k in self.estimates if k not in self.took and k != name]
        left = expected + sum(self.estimates[k] * self.scale for k in later)
        which = (
            f"kernel {len(self.took) + 1}/{len(self.estimates)} {name}"
            if name not in self.took
            else f"{name} again (other argument types)"
        )
        self._say(f"compiling {which}: about {expected:.0f} s ({left:.0f} s left in all)")
        self._stop = threading.Event()
        t0 = time.perf_counter()

        def tick(stop: threading.Event = self._stop) -> None:
            while not stop.wait(TICK_S):
                took = time.perf_counter() - t0
                of = (
                    f"of about {expected:.0f} s"
                    if took < expected
                    else "(a busy machine takes longer)"
                )
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
        ratio = sum(self.took.values()) / sum(self.estimates[k] for k in self.took)
        self.scale = max(1.0, ratio)
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
