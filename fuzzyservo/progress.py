"""Progress of a long run on stderr: a tqdm bar on a terminal, one plain line per step
otherwise (logs, CI). The library reports progress through callbacks; this draws it."""

from __future__ import annotations

import sys
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
    """From here on, every compile this process makes is one line on stderr, when it ends:
    what it compiled and how long that took (a first run, a new rig or a changed kernel;
    cached afterwards). A line before the first says why. No time is promised: none is known
    before it is taken. Plain lines, on a terminal or not."""
    from fuzzyservo._jit import watch_compiles

    global _watching
    if _watching:
        return
    _watching = True
    lines = _CompileLines()
    watch_compiles(lines.start, lines.end)


_watching = False  # one watch per process, however many commands it runs


class _CompileLines:
    """The lines of :func:`note_compiling`."""

    def __init__(self) -> None:
        self.first = True

    def start(self, what: str) -> None:
        if self.first:
            self.first = False
            print(
                "compiling for this machine (the first run, or a new plant or kernel; "
                "cached afterwards):",
                file=sys.stderr,
                flush=True,
            )

    def end(self, what: str, seconds: float) -> None:
        print(f"  compiled {what} in {seconds:.1f} s", file=sys.stderr, flush=True)


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
