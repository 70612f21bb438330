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


def pytest_sessionstart(session: pytest.Session) -> None:
    if not hasattr(session.config, "workerinput"):  # the controller, under xdist too
        session.config._files_before = _checkout_files()  # type: ignore[attr-defined]


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
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
