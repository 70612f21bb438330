"""Every command in the README and the documentation runs (issue 31).

Shell blocks (```bash, ```sh, ```shell, ```console) of ``README.md`` and ``docs/**/*.md``:
every line that starts with ``fuzzyservo`` (after a ``$ `` prompt in a console block;
a line ending in ``\\`` continues on the next) is run as written by ``bash`` with
``fuzzyservo`` meaning ``python -m fuzzyservo`` of the package under test, and must exit 0.
Other lines of a block (``pip install``, ``cd``, output) are not run. A block is one
session: its lines run in order in one fresh folder holding copies of the checkout's
``rigs/``, ``studies/`` and ``examples/`` and an empty ``docs/`` (as in a fresh clone),
so a line may use what an earlier line of the same block wrote; a block never sees
another block's files. ``fuzzyservo designer`` (a web server) is never run.

Markers (HTML comments, invisible on the rendered page):

- ``<!-- not run: REASON -->`` on the line(s) right before a block's opening fence: the
  block is not run (data a user downloads, a cluster, a database, a machine of theirs);
  REASON is required. It works for Python blocks too.
- ``# not run: REASON`` as a shell comment at the end of one line: that line is not run.
- ``<!-- slow -->`` before a block marks it slow (``-m "not slow"`` leaves it out);
  blocks running ``tune``, ``robustness``, ``calibrate``, ``reproduce``, ``fit-valve``
  or ``bench`` are slow anyway. Keep doc commands small (``--trials 8``, ``--samples 8``,
  short ``--duration``): the slow ones run in the full suite too.

Python blocks (```python) run with Sybil, one test per page, its blocks in order in
one namespace, in the same kind of fresh folder.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

import fuzzyservo

ROOT = Path(__file__).resolve().parents[1]
PAGES = sorted(
    [p for p in [ROOT / "README.md"] if p.is_file()] + sorted((ROOT / "docs").rglob("*.md"))
)
SHELLS = {"bash", "sh", "shell", "console"}
NEVER = {"designer"}  # starts a web server and waits
SLOW = {"tune", "robustness", "calibrate", "reproduce", "fit-valve", "bench"}
FENCE = re.compile(r"^\s*(`{3,}|~{3,})\s*([\w+-]*)")
NOT_RUN = re.compile(r"<!--\s*not run:\s*(\S.*?)\s*-->")
SLOW_MARK = re.compile(r"<!--\s*slow\s*-->")
LINE_NOT_RUN = re.compile(r"#\s*not run:\s*\S")
TIMEOUT_S = 900


@dataclass(frozen=True)
class Block:
    page: Path
    line: int  # of the opening fence, 1-based
    lang: str
    lines: tuple[tuple[int, str], ...]  # (line number, text) inside the fence
    not_run: str | None
    slow: bool

    @property
    def where(self) -> str:
        return f"{_name(self.page)}:{self.line}"


def _name(page: Path) -> str:
    """``page`` as the tests name it: relative to the checkout (else its file name)."""
    return page.relative_to(ROOT).as_posix() if page.is_relative_to(ROOT) else page.name


def blocks(page: Path) -> list[Block]:
    """The fenced code blocks of ``page`` with the markers before them."""
    text = page.read_text(encoding="utf-8").splitlines()
    found: list[Block] = []
    i = 0
    while i < len(text):
        m = FENCE.match(text[i])
        if not m:
            i += 1
            continue
        fence, lang, start = m.group(1), m.group(2).lower(), i
        before = []  # the comment lines right above the fence (blank lines between allowed)
        j = i - 1
        while j >= 0 and (not text[j].strip() or text[j].lstrip().startswith("<!--")):
            before.append(text[j])
            j -= 1
        i += 1
        body = []
        while i < len(text) and not text[i].strip().startswith(fence[0] * len(fence)):
            body.append((i + 1, text[i]))
            i += 1
        i += 1
        reason = next((r.group(1) for b in before if (r := NOT_RUN.search(b))), None)
        found.append(
            Block(
                page, start + 1, lang, tuple(body), reason, any(SLOW_MARK.search(b) for b in before)
            )
        )
    return found


def commands(block: Block) -> list[tuple[int, str]]:
    """(line number, command text) of the block's ``fuzzyservo`` lines, in order."""
    out: list[tuple[int, str]] = []
    pending: tuple[int, str] | None = None
    for number, raw in block.lines:
        line = raw.strip()
        if pending is not None:
            line = pending[1] + " " + line
            number = pending[0]
            pending = None
        elif line.startswith("$ "):
            line = line[2:].lstrip()
        elif block.lang == "console":
            continue  # output
        if line.endswith("\\"):
            pending = (number, line[:-1].rstrip())
            continue
        if LINE_NOT_RUN.search(line):
            continue
        try:
            words = shlex.split(line, comments=True)
        except ValueError:
            words = line.split()
        if words[:1] == ["fuzzyservo"] and not set(words[1:2]) & NEVER:
            out.append((number, line))
    return out


def _subcommand(command: str) -> str:
    words = shlex.split(command, comments=True)
    return words[1] if len(words) > 1 else ""


def _cases() -> list:
    cases = []
    for page in PAGES:
        for block in blocks(page):
            if block.lang not in SHELLS:
                continue
            lines = commands(block)
            if not lines:
                continue
            marks = []
            if block.slow or any(_subcommand(c) in SLOW for _, c in lines):
                marks.append(pytest.mark.slow)
            if block.not_run:
                marks.append(pytest.mark.skip(reason=f"not run: {block.not_run}"))
            cases.append(pytest.param(block, lines, id=block.where, marks=marks))
    return cases


def sandbox(folder: Path) -> Path:
    """A fresh clone's files the docs use: ``rigs/``, ``studies/``, ``examples/``, ``docs/``."""
    for name in ("rigs", "studies", "examples"):
        if (ROOT / name).is_dir():
            shutil.copytree(ROOT / name, folder / name)
    (folder / "docs").mkdir(exist_ok=True)
    return folder


def _shim(folder: Path) -> dict[str, str]:
    """An environment whose ``fuzzyservo`` is ``python -m fuzzyservo`` of this package."""
    bin_dir = folder / ".bin"
    bin_dir.mkdir()
    script = bin_dir / "fuzzyservo"
    script.write_text(f'#!/bin/sh\nexec {shlex.quote(sys.executable)} -m fuzzyservo "$@"\n')
    script.chmod(0o755)
    env = dict(os.environ)
    env["PATH"] = f"{bin_dir}{os.pathsep}{env.get('PATH', '')}"
    package_parent = str(Path(fuzzyservo.__file__).resolve().parents[1])
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [package_parent, env.get("PYTHONPATH")]))
    env["MPLBACKEND"] = "Agg"
    return env


@pytest.mark.parametrize(("block", "lines"), _cases())
def test_every_fuzzyservo_command_of_the_docs_runs(tmp_path: Path, block: Block, lines) -> None:
    work = sandbox(tmp_path / "clone")
    env = _shim(tmp_path)
    for number, command in lines:
        done = subprocess.run(
            ["bash", "-c", command],
            cwd=work,
            env=env,
            capture_output=True,
            text=True,
            timeout=TIMEOUT_S,
            check=False,
        )
        where = f"{_name(block.page)}:{number}"
        assert done.returncode == 0, (
            f"{where}: `{command}` exited {done.returncode}\n{done.stderr[-3000:]}"
        )


def test_the_collector_reads_blocks_markers_and_continuations(tmp_path: Path) -> None:
    page = tmp_path / "page.md"
    page.write_text(
        "Text.\n\n```bash\nfuzzyservo simulate dinca_cylinder p_k10   # a comment\n"
        "pip install x\nfuzzyservo designer\nfuzzyservo tune dinca_flc \\\n  --trials 4\n"
        "fuzzyservo tune dinca_flc --cluster tcp://HOST:8786   # not run: needs a cluster\n```\n\n"
        "<!-- not run: the data is downloaded -->\n```console\n$ fuzzyservo calibrate x y.csv\n"
        "output line\n```\n\n```python\nprint(1)\n```\n",
        encoding="utf-8",
    )
    first, second, third = blocks(page)
    assert (first.lang, first.line, first.not_run) == ("bash", 3, None)
    assert commands(first) == [
        (4, "fuzzyservo simulate dinca_cylinder p_k10   # a comment"),
        (7, "fuzzyservo tune dinca_flc --trials 4"),
    ]
    assert second.not_run == "the data is downloaded"
    assert second.line == 13
    assert commands(second) == [(14, "fuzzyservo calibrate x y.csv")]
    assert third.lang == "python"


def test_a_block_runs_in_a_fresh_clone_and_a_failure_names_its_line(tmp_path: Path) -> None:
    page = tmp_path / "page.md"
    page.write_text(
        "```bash\nfuzzyservo evaluate examples/pd_valve.fis examples/pd_valve_inputs.csv "
        "--out u.csv\nfuzzyservo evaluate examples/pd_valve.fis u.csv\n```\n",
        encoding="utf-8",
    )
    (block,) = blocks(page)
    with pytest.raises(AssertionError, match=r"page\.md:3: `fuzzyservo evaluate .* exited 2"):
        test_every_fuzzyservo_command_of_the_docs_runs(tmp_path, block, commands(block))
    assert (tmp_path / "clone" / "u.csv").is_file()  # the first line ran, in the clone


# --------------------------------------------------------------------------- Python
def _python_pages() -> list:
    pages = []
    for page in PAGES:
        if any(b.lang in ("python", "py") for b in blocks(page)):
            pages.append(pytest.param(page, id=_name(page)))
    return pages


def run_python_blocks(page: Path) -> int:
    """Evaluate the Python blocks of ``page`` in order in one namespace (Sybil), those
    after a not-run marker aside; how many ran. Raises AssertionError naming the line."""
    from sybil import Sybil
    from sybil.parsers.markdown import PythonCodeBlockParser

    skipped = {b.line for b in blocks(page) if b.not_run}
    ran = 0
    for example in Sybil(parsers=[PythonCodeBlockParser()]).parse(page).examples():
        if example.line in skipped:
            continue
        try:
            example.evaluate()
        except Exception as exc:
            raise AssertionError(f"{_name(page)}:{example.line}: {exc!r}") from exc
        ran += 1
    return ran


@pytest.mark.parametrize("page", _python_pages())
def test_every_python_block_of_the_docs_runs(tmp_path: Path, monkeypatch, page: Path) -> None:
    pytest.importorskip("sybil")
    monkeypatch.chdir(sandbox(tmp_path))
    monkeypatch.setenv("MPLBACKEND", "Agg")
    assert run_python_blocks(page) > 0


def test_python_blocks_share_a_namespace_and_honour_the_marker(tmp_path: Path) -> None:
    pytest.importorskip("sybil")
    page = tmp_path / "page.md"
    page.write_text(
        "```python\nx = 2\n```\n\n<!-- not run: a sketch -->\n```python\nraise SystemExit\n```\n\n"
        "```python\nassert x == 2\n```\n\n```python\nassert x == 3\n```\n",
        encoding="utf-8",
    )
    with pytest.raises(AssertionError, match=r"page\.md:14: AssertionError"):
        run_python_blocks(page)
