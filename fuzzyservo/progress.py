"""Progress of a long run on stderr: a tqdm bar on a terminal, one plain line per step
otherwise (logs, CI). The library reports progress through callbacks; this draws it."""

from __future__ import annotations

import sys
import time
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
    """One line on stderr before a long silent compile (the first run after an install or
    a change of the compiled kernels)."""
    from fuzzyservo._jit import cache_is_cold

    if cache_is_cold():
        print(
            "compiling the simulation kernels (first run only, after an install or a change; "
            "about a minute, cached afterwards)",
            file=sys.stderr,
            flush=True,
        )
