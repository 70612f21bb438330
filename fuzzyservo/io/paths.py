"""Finding the project's files: a path as given, or a bare name under ``rigs/``, ``studies/`` …

Bare names are looked up in the working folder first (a user's own ``rigs/``), then in
the shipped rigs, controllers and studies: the checkout's top-level ``rigs/`` and
``studies/``, which a wheel or a non-editable install carries as package data
(``fuzzyservo/data/rigs``, ``fuzzyservo/data/studies``: the ``package-dir`` mapping in
pyproject.toml), so an installed package finds them from any folder.
"""

from __future__ import annotations

import errno
import os
import re
import stat
import tempfile
from pathlib import Path

from fuzzyservo.atomic import NAME_MAX_BYTES, file_error, shown_path
from fuzzyservo.errors import ConfigError, did_you_mean, excerpt

_PACKAGE = Path(__file__).resolve().parent.parent


def package_data() -> Path:
    """``fuzzyservo/data``: the files only the package reads (the seed reproduction spec)
    and, once installed, the shipped ``rigs/`` and ``studies/``."""
    return _PACKAGE / "data"


def data_root() -> Path:
    """The folder holding the shipped ``rigs/`` and ``studies/``: ``fuzzyservo/data`` in an
    installed package, else the checkout's top level (a source tree, an editable install,
    ``PYTHONPATH=<checkout>``), where they are kept as the one copy."""
    installed = package_data()
    return installed if (installed / "rigs").is_dir() else _PACKAGE.parent


def search_dirs() -> list[Path]:
    """Where bare names are looked up: the working folder, then the shipped files."""
    return [Path.cwd(), data_root()]


def find_file(name: str, folder: str, what: str, *, relative_to: Path | None = None) -> Path:
    """``name`` as a path (also relative to ``relative_to``'s folder), or a bare name
    looked up as ``<folder>/<name>.yaml`` in :func:`search_dirs`.

    Raises :class:`ConfigError` listing the known names when nothing matches.
    """
    given = Path(name)
    candidates = [given] if relative_to is None else [relative_to.parent / given, given]
    for candidate in candidates:
        try:
            if candidate.is_file():
                return candidate
        except OSError as exc:  # a name too long, a loop of links
            raise file_error(name, exc, "read") from None
    if given.suffix in (".yaml", ".yml", ".fis") or "/" in name:
        raise ConfigError(f"{what} file not found; check the path", file=name)
    for base in search_dirs():
        candidate = base / folder / f"{name}.yaml"
        if candidate.is_file():
            return candidate
    known = sorted({p.stem for base in search_dirs() for p in (base / folder).glob("*.yaml")})
    raise ConfigError(
        f"no {what} named {excerpt(name)}; {did_you_mean(name, known)}known: {', '.join(known) or 'none'}",
        file=name,
    )


def shipped_or_path(name: str | Path, folder: str, what: str) -> str | Path:
    """``name`` unchanged when it is a path; a bare name that is not a file here (no
    suffix, no folder) is a shipped file's name, found by :func:`find_file`."""
    text = str(name)
    if Path(text).suffix or "/" in text or "\\" in text or Path(text).is_file():
        return name
    return find_file(text, folder, what)


_UNSAFE = re.compile(r"[/\\:\x00-\x1f]")


def name_problem(name: str) -> str | None:
    """Why ``name`` (of a rig, controller, study or scenario) cannot be part of a file
    name, or ``None``. Names become output file names, so they hold no path."""
    if not name.strip():
        return "is empty; give a short name such as my_rig"
    if _UNSAFE.search(name) or name.startswith("."):
        return (
            f"{excerpt(name)} is not a plain name: it becomes part of output file names, so it may "
            "not hold '/', '\\', ':', control characters or start with '.'; "
            "use letters, digits, '_' and '-' (e.g. my_rig)"
        )
    if len(name) > 100:
        return f"is {len(name)} characters long; give at most 100"
    return None


def _creatable(path: Path) -> None:
    """Raise the :class:`OSError` that creating ``path`` (absent: a file or a folder, with
    its missing parents) would meet: a name too long, a file in the way, no permission or
    a read-only file system in the nearest folder that exists. Writes nothing."""
    if any(len(os.fsencode(part)) > NAME_MAX_BYTES for part in path.parts):
        raise OSError(errno.ENAMETOOLONG, os.strerror(errno.ENAMETOOLONG))
    ancestor = path
    while True:
        try:
            info = os.stat(ancestor)
            break
        except FileNotFoundError:
            if ancestor == ancestor.parent:
                raise
            ancestor = ancestor.parent
    if not stat.S_ISDIR(info.st_mode):
        raise NotADirectoryError(errno.ENOTDIR, os.strerror(errno.ENOTDIR))
    if not os.access(ancestor, os.W_OK | os.X_OK):
        read_only = hasattr(os, "statvfs") and os.statvfs(ancestor).f_flag & os.ST_RDONLY
        code = errno.EROFS if read_only else errno.EACCES
        raise OSError(code, os.strerror(code))


def output_dir(path: str | None, option: str = "--out") -> Path | None:
    """The output folder ``path`` given to ``option``, checked before any work starts:
    refused (one line) when a file of that name is in the way, when a file or folder
    cannot be made in it (a probe file is created and removed), or when it cannot be made."""
    if path is None:
        return None
    out = Path(path)
    try:
        if out.is_dir():
            with tempfile.TemporaryFile(dir=out):  # a probe, gone when closed
                pass
        elif out.exists():
            raise ConfigError(
                f"{option} {shown_path(out)}: is a file, not a folder; name a folder (new or "
                "existing)"
            )
        else:
            _creatable(out)
    except OSError as exc:
        raise file_error(out, exc, option=option) from None
    return out


def output_file(path: str | None, option: str, example: str = "out.json") -> str | None:
    """An output file ``path`` given to ``option``, checked before any work starts: refused
    (one line) when it names a folder (the message suggests ``example`` in it) or when it
    could not be written there."""
    if path is None:
        return None
    p = Path(path)
    try:
        if p.is_dir():
            raise ConfigError(
                f"{option} {shown_path(p)}: is a folder; give a file name such as "
                f"{shown_path(p / example)}"
            )
        if p.exists():
            if not os.access(p, os.W_OK):
                raise PermissionError(errno.EACCES, os.strerror(errno.EACCES))
        else:
            _creatable(p)
    except OSError as exc:
        raise file_error(p, exc, option=option) from None
    return path
