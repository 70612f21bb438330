"""Errors raised at the edges (files, command line); never inside a simulation loop.

Every message says what is wrong, where (file and key), the value, and the fix, on one line.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterable
from types import ModuleType


class FuzzyservoError(Exception):
    """Base class of the errors the command line turns into one line and exit status 2."""


class ConfigError(FuzzyservoError, ValueError):
    """A rig, controller or study file (or a value in it) that cannot be used.

    Parameters
    ----------
    message:
        What is wrong and how to fix it.
    file:
        The file the value came from, if any.
    key:
        Dotted path of the key inside the file, e.g. ``plant.parameters.bulk_modulus``.
    """

    def __init__(self, message: str, *, file: str | None = None, key: str | None = None):
        self.file = file
        self.key = key
        self.detail = message
        where = ": ".join(part for part in (file, key) if part)
        super().__init__(f"{where}: {message}" if where else message)


class DataError(FuzzyservoError, ValueError):
    """A measured-data file that cannot be used (unknown unit, bad time column, NaN ...)."""


class FileError(FuzzyservoError, OSError):
    """A file or folder that cannot be read or written: permissions, a full disk, a name
    too long, a folder where a file is wanted. Raised by :mod:`fuzzyservo.atomic`, with the
    ``errno`` of the fault; its text is the one-line message alone."""

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""


class WorkerError(FuzzyservoError, RuntimeError):
    """Parallel work that cannot go on: local worker processes that keep dying."""


class FileWarning(UserWarning):
    """A file read the way its own tool reads it, where that differs from what it says (a
    MATLAB ``.fis`` whose ``MF2`` is given twice: the second is read as ``MF3``). The
    command line prints it as one ``fuzzyservo: warning:`` line."""


class MissingExtraError(FuzzyservoError, ImportError):
    """A feature whose optional dependencies (an install extra) are not installed."""


def require(module: str, extra: str, purpose: str) -> ModuleType:
    """Import ``module``, or raise :class:`MissingExtraError` naming the extra to install.

    ``purpose`` says what needs it: ``require("panel", "designer", "the designer")``.
    """
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise MissingExtraError(
            f"{purpose} needs the '{extra}' extra, which is not installed ({exc.name or module} "
            f"missing): pip install 'fuzzyservo[{extra}]' (or -e '.[{extra}]' in a clone)"
        ) from None


def did_you_mean(name: object, known: Iterable[str]) -> str:
    """``"did you mean 'steps'? "`` for the known name closest to a misspelt ``name`` (to
    put before the list of known names in a message), ``""`` when none is close."""
    import difflib

    close = difflib.get_close_matches(str(name), [str(k) for k in known], n=1, cutoff=0.6)
    return f"did you mean {close[0]!r}? " if close else ""
