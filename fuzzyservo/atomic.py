"""Output files, written whole or not at all; a file fault as one line.

Every file fuzzyservo writes (JSON, CSV, figures, reports, exports, generated code, rig
and controller files) goes through :func:`atomic_write`: the content goes to a temporary
name in the target's folder (``.<name>.<random>.tmp``), is flushed to the disk, and only
then renamed onto the target. A full disk, an error halfway or Ctrl-C leaves the earlier
file (or none), never a truncated one, and the temporary is removed. A target that is not
a regular file (``/dev/stdout``, a pipe) is written in place. Study databases are not
written here: SQLite keeps its own journal.

An :class:`OSError` on the way becomes a :class:`~fuzzyservo.errors.FileError` naming the
path, the problem and the fix on one line (:func:`file_error`).
"""

from __future__ import annotations

import contextlib
import errno
import os
import secrets
import stat
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import IO, Any

from fuzzyservo.errors import FileError

__all__ = [
    "NAME_MAX_BYTES",
    "atomic_write",
    "ensure_folder",
    "file_error",
    "shown_path",
    "write_bytes",
    "write_files",
    "write_text",
]

#: a path longer than this is shown as its start, its end and its length
SHOWN_PATH_CHARS = 120
#: the longest folder or file name most file systems take (NAME_MAX), in bytes
NAME_MAX_BYTES = 255

_WRITE_ELSEWHERE = "choose a folder you may write to, or change its permissions"
_FIXES = {
    errno.EACCES: _WRITE_ELSEWHERE,
    errno.EPERM: _WRITE_ELSEWHERE,
    errno.EROFS: "the file system is read-only; write to another folder",
    errno.ENOSPC: "free some space or write to another disk",
    errno.EDQUOT: "free some space (the disk quota is used up) or write to another disk",
    errno.EFBIG: "the file is larger than the file system allows; write to another disk",
    errno.ENAMETOOLONG: (
        f"give a shorter name (at most {NAME_MAX_BYTES} bytes per folder or file name)"
    ),
    errno.EISDIR: "it is a folder; give a file name",
    errno.ENOTDIR: "a part of the path is a file, not a folder; give a path through folders",
    errno.ENOENT: "check that the folder exists",
    errno.EEXIST: "a file of that name is in the way; give another name",
    errno.ELOOP: "the path has a loop of symbolic links; give another path",
    errno.EIO: "the disk reported an input/output error; check it or write elsewhere",
}


def shown_path(path: str | os.PathLike[str]) -> str:
    """``path`` for a message: as given, or its start and end when it is very long."""
    text = os.fspath(path)
    if len(text) <= SHOWN_PATH_CHARS:
        return text
    return f"{text[:60]}...{text[-40:]} ({len(text)} characters)"


def file_error(
    path: str | os.PathLike[str] | None, exc: OSError, action: str = "write", option: str = ""
) -> FileError:
    """One line for ``exc``, raised while trying to ``action`` (read, write, make, use)
    ``path`` (given to the command-line ``option``, if any): the path, the problem (the
    system's words) and the fix."""
    reason = exc.strerror or str(exc) or type(exc).__name__
    reason = reason[:1].lower() + reason[1:]
    fix = _FIXES.get(exc.errno or 0, "check the path and its permissions")
    if path is None:
        return FileError(f"cannot {action} a file ({reason}); {fix}")
    where = f"{option} {shown_path(path)}" if option else shown_path(path)
    error = FileError(f"{where}: cannot {action} it ({reason}); {fix}")
    error.errno, error.strerror = exc.errno, exc.strerror
    return error


def ensure_folder(folder: str | os.PathLike[str]) -> Path:
    """``folder`` and its parents, made when missing; a :class:`FileError` when that fails."""
    out = Path(folder)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except FileExistsError:  # a file (or a dangling link) of that name
        raise file_error(out, OSError(errno.ENOTDIR, "a file is in the way"), "make") from None
    except OSError as exc:
        raise file_error(out, exc, "make") from None
    return out


def _temporary(target: Path, existing: os.stat_result | None) -> tuple[Path, int]:
    """A new, empty, exclusively created file beside ``target`` (with its permissions)."""
    stem = target.name[:64]  # short: the temporary's name must fit where the target's fits
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL
    flags |= getattr(os, "O_CLOEXEC", 0) | getattr(os, "O_BINARY", 0)
    while True:
        tmp = target.with_name(f".{stem}.{secrets.token_hex(4)}.tmp")
        try:
            fd = os.open(tmp, flags, 0o666)  # the umask applies, as to any new file
            break
        except FileExistsError:
            continue
    if existing is not None and hasattr(os, "fchmod"):
        with contextlib.suppress(OSError):  # keep the mode of the file it replaces
            os.fchmod(fd, stat.S_IMODE(existing.st_mode))
    return tmp, fd


@contextlib.contextmanager
def atomic_write(
    path: str | os.PathLike[str],
    mode: str = "w",
    *,
    encoding: str = "utf-8",
    newline: str | None = None,
) -> Iterator[IO[Any]]:
    """A file object (``mode`` ``"w"`` or ``"wb"``) whose content replaces ``path`` in one
    rename once the ``with`` block ends without an error; makes the folder.

    On any error the target is untouched and the temporary removed; an :class:`OSError`
    (also one raised inside the block while writing) becomes a :class:`FileError`.
    """
    if mode not in ("w", "wb"):
        raise ValueError(f"mode must be 'w' or 'wb', got {mode!r}")
    given = path
    target = Path(path)
    text = {} if mode == "wb" else {"encoding": encoding, "newline": newline}
    try:
        if target.is_symlink():  # write through the link, do not replace it by a file
            target = Path(os.path.realpath(target))
        try:
            existing = target.stat()
        except FileNotFoundError:
            existing = None
        if existing is not None and stat.S_ISDIR(existing.st_mode):
            raise IsADirectoryError(errno.EISDIR, os.strerror(errno.EISDIR))
        if existing is not None and not os.access(target, os.W_OK):  # a read-only file stays
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES))
        if existing is not None and not stat.S_ISREG(existing.st_mode):
            in_place = open(target, mode, **text)
        else:
            in_place = None
            ensure_folder(target.parent)
            tmp, fd = _temporary(target, existing)
    except FileError:
        raise
    except OSError as exc:
        raise file_error(given, exc) from None
    if in_place is not None:
        try:
            with in_place as fh:
                yield fh
        except FileError:
            raise
        except OSError as exc:
            raise file_error(given, exc) from None
        return
    try:
        with os.fdopen(fd, mode, **text) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, target)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(exc, OSError) and not isinstance(exc, FileError):
            raise file_error(given, exc) from None
        raise


def write_text(path: str | os.PathLike[str], text: str, *, newline: str | None = None) -> Path:
    """``text`` as UTF-8 into ``path`` through :func:`atomic_write`; returns the path."""
    with atomic_write(path, "w", newline=newline) as fh:
        fh.write(text)
    return Path(path)


def write_bytes(path: str | os.PathLike[str], data: bytes) -> Path:
    """``data`` into ``path`` through :func:`atomic_write`; returns the path."""
    with atomic_write(path, "wb") as fh:
        fh.write(data)
    return Path(path)


def write_files(files: Mapping[str, str], folder: str | os.PathLike[str]) -> list[Path]:
    """Each ``{file name: text}`` into ``folder`` (made), one :func:`write_text` each."""
    out = ensure_folder(folder)
    return [write_text(out / name, text) for name, text in files.items()]
