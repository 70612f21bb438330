"""Shared fixtures: the project's own rig and controller files (see ``support.py``).

Every test runs in its own temporary folder, so a command's default output folder
(``out/``) lands there; and the session fails if the checkout holds a file it did not
hold before (``git status --ignored``, caches aside): tests write only where they say.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
from support import controller_named, rig_named

ROOT = Path(__file__).resolve().parents[1]
# what tools leave in any checkout: not output of ours
_CACHES = (
    "__pycache__",
    ".pytest_cache",
    ".hypothesis",
    ".ruff_cache",
    ".grimp_cache",
    ".egg-info",
    ".venv",
)


def _checkout_files() -> set[str] | None:
    """Untracked and ignored paths of the checkout (None outside a git checkout)."""
    try:
        done = subprocess.run(
            ["git", "status", "--porcelain", "--ignored", "--untracked-files=all"],
            cwd=ROOT, capture_output=True, text=True, check=True, timeout=60,
        )  # fmt: skip
    except (OSError, subprocess.SubprocessError):
        return None
    paths = {line[3:] for line in done.stdout.splitlines()}
    return {p for p in paths if not any(c in p for c in _CACHES)}


# what each process of the run compiled (numba's kernels, C builds): (what, seconds)
_COMPILED: list[tuple[str, float]] = []


def pytest_sessionstart(session: pytest.Session) -> None:
    from fuzzyservo._jit import watch_compiles

    watch_compiles(lambda what: None, lambda what, seconds: _COMPILED.append((what, seconds)))
    if not hasattr(session.config, "workerinput"):  # the controller, under xdist too
        session.config._files_before = _checkout_files()  # type: ignore[attr-defined]
        session.config._compiled = {"controller": _COMPILED}  # type: ignore[attr-defined]


def pytest_testnodedown(node, error) -> None:
    """A worker's compiles, for the summary (xdist sends its ``workeroutput``)."""
    compiled = getattr(node.config, "_compiled", None)
    if compiled is not None:
        compiled[node.gateway.id] = node.workeroutput.get("compiled", [])


def pytest_terminal_summary(terminalreporter, exitstatus, config) -> None:
    """One line per process: how many top-level compiles it made and their seconds (a
    compile is counted where it ran; a process that found it in the cache counts none)."""
    compiled = getattr(config, "_compiled", None)
    if not compiled:
        return
    parts = [
        f"{name} {len(items)} in {sum(s for _, s in items):.0f} s"
        for name, items in sorted(compiled.items())
    ]
    terminalreporter.write_line("compiles (steps, seconds) by process: " + "; ".join(parts))
    every = [what for items in compiled.values() for what in {w for w, _ in items}]
    twice = sorted({w for w in every if every.count(w) > 1})
    if twice:
        terminalreporter.write_line(f"compiled by more than one process: {twice[:5]}")


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    workeroutput = getattr(session.config, "workeroutput", None)
    if workeroutput is not None:  # an xdist worker: its compiles to the controller
        workeroutput["compiled"] = list(_COMPILED)
    before = getattr(session.config, "_files_before", None)
    after = _checkout_files() if before is not None else None
    if after is None:
        return
    new = sorted(after - before)
    if new:
        print(f"\nthe tests wrote into the checkout (write under tmp_path): {new[:10]}")
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


@pytest.fixture(autouse=True)
def _in_tmp_path(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A command's default output folder (``out``) goes under this test's tmp_path."""
    monkeypatch.chdir(tmp_path)


@pytest.fixture(scope="session")
def dinca():
    return rig_named("dinca_cylinder")


@pytest.fixture(scope="session")
def ehs160():
    return rig_named("ehs160_motor")


@pytest.fixture(scope="session")
def p_k10():
    return controller_named("p_k10")


@pytest.fixture(scope="session")
def p_kb0105():
    return controller_named("p_kb0105")


@pytest.fixture(scope="session")
def open_loop():
    return controller_named("open_loop")


@pytest.fixture(scope="session")
def flc1():
    return controller_named("flc1_translated")


@pytest.fixture(scope="session")
def flc2():
    return controller_named("flc2_reshaped")
