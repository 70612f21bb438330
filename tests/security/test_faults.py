"""Faults of the disk and the database on the command line: each one line, nothing half-written.

A folder that cannot be written, a full disk, a folder where a file is wanted, a name too
long, a damaged study database and a port out of range each end in exit status 2 and one
line on stderr (``fuzzyservo: error: ...``; an argparse error for ``--port``), never a
traceback; an output is written whole or not at all (:mod:`fuzzyservo.atomic`), so a
write that fails halfway leaves no truncated file and no temporary.
"""

from __future__ import annotations

import errno
import io
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from fuzzyservo.cli import main

LONG = "x" * 5000
CHEAP = ("compare", "dinca_cylinder", "p_k10", "--scenario", "steps", "--duration", "0.5")


def run(argv: list[str], capsys) -> tuple[int, str, str]:
    """``fuzzyservo argv`` in this process: exit status, stdout, stderr."""
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def one_line(err: str, start: str = "fuzzyservo: error:") -> str:
    """The single stderr line, checked: it starts with ``start``, no traceback."""
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith(start), err
    assert "Traceback" not in err
    return lines[0]


def leftovers(folder: Path) -> list[str]:
    """Temporaries of :func:`fuzzyservo.atomic.atomic_write` left in ``folder``."""
    return sorted(p.name for p in folder.iterdir() if p.name.endswith(".tmp"))


# --------------------------------------------------------------------------- output folders
def test_an_out_folder_below_a_file_is_refused_before_the_run(tmp_path, capsys):
    """A path through a regular file cannot be written by anyone (root included)."""
    (tmp_path / "taken").write_text("a file\n")
    code, out, err = run([*CHEAP, "--out", str(tmp_path / "taken" / "out")], capsys)
    line = one_line(err)
    assert code == 2 and "--out" in line and "not a directory" in line
    assert out == ""  # refused before the run: no table printed


def test_a_read_only_out_folder_is_refused_before_the_run(tmp_path, capsys):
    folder = tmp_path / "read_only"
    folder.mkdir()
    folder.chmod(0o555)
    try:
        try:  # root writes into a 0o555 folder: then there is nothing to refuse
            (folder / "probe").write_text("")
        except PermissionError:
            pass
        else:
            pytest.skip("running as root: a 0o555 folder is writable (the path-below-a-file case covers root)")  # fmt: skip
        code, _, err = run(["show", "flc2_reshaped", "--out", str(folder)], capsys)
        line = one_line(err)
        assert code == 2 and "permission denied" in line and str(folder) in line
        assert list(folder.iterdir()) == []
    finally:
        folder.chmod(0o755)


def test_json_on_a_full_device_is_one_line_and_leaves_no_temporary(tmp_path, capsys):
    """``/dev/full`` answers every write with ENOSPC: the JSON fails after the run; the
    plots and signals written before it are whole, and no temporary is left anywhere."""
    if not Path("/dev/full").exists():
        pytest.skip("no /dev/full on this system")
    dev_before = set(os.listdir("/dev"))
    out = tmp_path / "out"
    code, _, err = run([*CHEAP, "--out", str(out), "--json", "/dev/full"], capsys)
    line = one_line(err)
    assert code == 2 and "/dev/full" in line and "no space left on device" in line
    assert Path("/dev/full").is_char_device()  # written in place, never replaced
    assert set(os.listdir("/dev")) <= dev_before
    assert leftovers(out) == [] and {p.suffix for p in out.iterdir()} == {".png", ".csv"}


def test_a_full_disk_halfway_through_a_png_leaves_the_earlier_file_and_no_temporary(
    tmp_path, capsys, monkeypatch
):
    """ENOSPC after 8 kB of the first figure: that figure keeps its earlier content, no
    other figure is written and no temporary stays."""
    import fuzzyservo.atomic

    out = tmp_path / "out"
    out.mkdir()
    earlier = out / "flc2_reshaped_overview.png"
    earlier.write_bytes(b"the figure of an earlier run")
    real_fdopen, written = os.fdopen, []

    class FullDisk(io.RawIOBase):
        """The temporary's file object: takes 8 kB, then the disk is full."""

        def __init__(self, fd: int, mode: str, **_):
            self.file = real_fdopen(fd, mode)

        def writable(self) -> bool:
            return True

        def fileno(self) -> int:  # no descriptor: the image writer goes through write()
            raise io.UnsupportedOperation("fileno")

        def write(self, data) -> int:
            if sum(written) + len(data) > 8192:
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            written.append(len(data))
            return self.file.write(data)

        def close(self) -> None:
            self.file.close()
            super().close()

    monkeypatch.setattr(fuzzyservo.atomic.os, "fdopen", FullDisk)
    code, _, err = run(["show", "flc2_reshaped", "--out", str(out)], capsys)
    monkeypatch.undo()
    line = one_line(err)
    assert code == 2 and "flc2_reshaped_overview.png" in line
    assert "no space left on device" in line
    assert sum(written) > 0  # the fault came halfway, not before the first byte
    assert [p.name for p in out.iterdir()] == [earlier.name]
    assert earlier.read_bytes() == b"the figure of an earlier run"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="RLIMIT_FSIZE semantics")
def test_a_write_the_kernel_stops_halfway_leaves_no_truncated_png(tmp_path):
    """A real fault inside the image writer (which writes to the file descriptor itself):
    a file-size limit of 20 kB, below the 140 kB overview figure; Python ignores
    SIGXFSZ, so the write fails with EFBIG."""
    out = tmp_path / "out"
    script = (
        "import resource, sys\n"
        "import matplotlib.pyplot, fuzzyservo.plots\n"
        "from fuzzyservo.cli import main\n"
        "resource.setrlimit(resource.RLIMIT_FSIZE, (20000, resource.getrlimit(resource.RLIMIT_FSIZE)[1]))\n"
        f"sys.exit(main(['show', 'flc2_reshaped', '--out', {str(out)!r}]))\n"
    )  # fmt: skip
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, cwd=tmp_path, timeout=300
    )
    line = one_line(done.stderr)
    assert done.returncode == 2 and "file too large" in line.lower()
    assert list(out.iterdir()) == []


# --------------------------------------------------------------------------- wrong kinds of path
def test_evaluate_out_naming_a_folder_is_refused_before_evaluating(tmp_path, capsys):
    (tmp_path / "in.csv").write_text("error\n0.1\n")
    code, out, err = run(["evaluate", "flc2_reshaped", "in.csv", "--out", str(tmp_path)], capsys)
    line = one_line(err)
    assert code == 2 and "is a folder" in line and "out.csv" in line and out == ""


@pytest.mark.parametrize(
    "argv",
    [
        [*CHEAP, "--out", f"out/{LONG}"],
        [*CHEAP, "--json", f"{LONG}.json"],
        ["show", LONG],
        ["show", f"{LONG}.yaml"],
    ],
    ids=["--out", "--json", "controller name", "controller file"],
)
def test_a_5000_character_name_is_one_short_line(argv, capsys):
    code, _, err = run(argv, capsys)
    line = one_line(err)
    assert code == 2 and len(line) < 400  # the path is shown shortened
    assert "file name too long" in line or "not found" in line, line


def test_a_5000_character_name_in_a_file_is_one_line(tmp_path, capsys):
    from support import shipped

    text = shipped("flc2_reshaped", "studies/controllers").read_text(encoding="utf-8")
    mine = tmp_path / "mine.yaml"
    mine.write_text(re.sub(r"(?m)^name: .*$", f"name: {LONG}", text), encoding="utf-8")
    code, _, err = run(["show", str(mine), "--out", str(tmp_path / "out")], capsys)
    line = one_line(err)
    assert code == 2 and "characters long; give at most 100" in line and len(line) < 400
    assert not (tmp_path / "out").exists()


# --------------------------------------------------------------------------- study databases
def _tune(storage_args: list[str], out: Path) -> list[str]:
    return ["tune", "dinca_flc", "--trials", "1", "--workers", "1", "--out", str(out),
            *storage_args]  # fmt: skip


def _damage(db: Path) -> None:
    """Overwrite every page of the SQLite file ``db`` after the first."""
    data = bytearray(db.read_bytes())
    data[4096:] = bytes((7 * k + 3) % 256 for k in range(len(data) - 4096))
    db.write_bytes(bytes(data))


def test_a_file_that_is_no_database_given_as_storage_is_one_line(tmp_path, capsys):
    garbled = tmp_path / "garbled.db"
    garbled.write_bytes(bytes(range(256)) * 16)
    code, _, err = run(_tune(["--storage", f"sqlite:///{garbled}"], tmp_path / "out"), capsys)
    line = one_line(err)
    assert code == 2 and str(garbled) in line and "not an Optuna study database" in line
    assert "--storage" in line
    assert garbled.read_bytes() == bytes(range(256)) * 16  # untouched


def test_a_damaged_default_study_database_is_one_line(tmp_path, capsys):
    """A real study database (the default storage, out/<study>/<study>.db) whose pages
    after the first are overwritten: Optuna raises StorageInternalError or SQLAlchemy a
    DatabaseError, depending on where the damage is met."""
    import optuna

    out = tmp_path / "out"
    out.mkdir()
    db = out / "dinca_flc.db"
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.create_study(study_name="dinca_flc", storage=f"sqlite:///{db}")
    study.optimize(lambda t: t.suggest_float("a", 0, 1), n_trials=5)
    _damage(db)
    code, _, err = run(_tune([], out), capsys)
    line = one_line(err)
    assert code == 2 and str(db) in line
    assert "not an Optuna study database, or a damaged one" in line


# --------------------------------------------------------------------------- ports
@pytest.mark.parametrize("port", ["99999", "-1", "65536", "http"])
def test_a_port_out_of_range_is_an_argument_error(port, tmp_path, capsys):
    code, _, err = run(["designer", "--port", port, "--out", str(tmp_path)], capsys)
    line = one_line(err, "fuzzyservo designer: error: argument --port:")
    assert code == 2 and "port" in line


def test_serve_refuses_a_port_out_of_range_before_starting(tmp_path):
    from support import shipped

    from fuzzyservo.designer import serve
    from fuzzyservo.errors import ConfigError

    rig, controller = shipped("dinca_cylinder"), shipped("flc2_reshaped", "studies/controllers")
    for port in (99999, -1, True, 5006.0):
        with pytest.raises(ConfigError, match="1-65535"):
            serve(rig, controller, port=port, out_dir=tmp_path)
