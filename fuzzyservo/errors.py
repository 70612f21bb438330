"""Errors raised at the edges (files, command line); never inside a simulation loop.

Every message says what is wrong, where (file and key), the value, and the fix, on one line.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterable, Iterator
from types import ModuleType

#: characters of a value (or a key path) an error message shows before it is cut
EXCERPT = 60


def excerpt(value: object, limit: int = EXCERPT) -> str:
    """``repr(value)`` for an error message, cut to ``limit`` characters.

    A value from a user's file may be megabytes long (or a YAML alias bomb that stands for
    billions of items); a message shows its start, '…' and its full size, e.g.
    ``'aaaaaaaa…' (10,000 characters)`` or ``[[1, 2], [1, 2], [1, …] (5,000 items)``. Only
    about ``limit`` characters of the repr are ever built, whatever the value.
    """
    pieces, length = [], 0
    for piece in _repr_pieces(value, limit, 0):
        pieces.append(piece)
        length += len(piece)
        if length > limit:
            return f"{''.join(pieces)[: limit - 1]}… ({_size(value)})"
    return "".join(pieces)


_BRACKETS = {list: ("[", "]"), tuple: ("(", ")"), set: ("{", "}"), frozenset: ("frozenset({", "})")}


def _repr_pieces(value: object, limit: int, depth: int) -> Iterator[str]:
    """``repr(value)`` in pieces, lazily: the caller stops once it has enough."""
    if depth > limit:  # a value nested deeper than a message shows (or a cycle)
        yield "…"
    elif type(value) in (list, tuple, set, frozenset, dict) and not value:
        yield repr(value)
    elif type(value) in _BRACKETS:
        opening, closing = _BRACKETS[type(value)]
        yield opening
        for k, item in enumerate(value):
            yield ", " if k else ""
            yield from _repr_pieces(item, limit, depth + 1)
        yield "," if type(value) is tuple and len(value) == 1 else ""
        yield closing
    elif type(value) is dict:
        yield "{"
        for k, (key, item) in enumerate(value.items()):
            yield ", " if k else ""
            yield from _repr_pieces(key, limit, depth + 1)
            yield ": "
            yield from _repr_pieces(item, limit, depth + 1)
        yield "}"
    elif isinstance(value, str | bytes):
        yield repr(value[: limit + 1])[: -1 if len(value) > limit else None]
    else:
        try:
            yield repr(value)
        except ValueError:  # an int of more than 4,300 digits has no repr
            yield "<a whole number too long to write>"


def _size(value: object) -> str:
    """The full size of a value whose repr was cut, in words."""
    if isinstance(value, str):
        return f"{len(value):,} characters"
    if isinstance(value, bytes):
        return f"{len(value):,} bytes"
    if isinstance(value, list | tuple | set | frozenset | dict):
        return f"{len(value):,} item{'' if len(value) == 1 else 's'}"
    try:
        return f"{len(repr(value)):,} characters"
    except ValueError:
        return f"{value.bit_length():,} bits" if isinstance(value, int) else "cut"


class FuzzyservoError(Exception):
    """Base class of the errors the command line turns into one line and exit status 2."""

    def as_option(self) -> str:
        """The line the command line prints (a :class:`ConfigError` about a Python
        argument names its option instead)."""
        return str(self)


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
    argument:
        The Python argument the value came from, e.g. ``effects``: the message starts with
        its name (the command line shows the option it maps to, ``--effects``, instead).
    """

    def __init__(
        self,
        message: str,
        *,
        file: str | None = None,
        key: str | None = None,
        argument: str | None = None,
    ):
        self.file = file
        self.key = key
        self.argument = argument
        self.detail = message
        # a key path is the file's own text: an unknown key may be megabytes long
        shown = key if key is None or len(key) <= 2 * EXCERPT else f"{key[: 2 * EXCERPT - 1]}…"
        where = ": ".join(part for part in (file, shown, argument) if part)
        super().__init__(f"{where}: {message}" if where else message)

    def as_option(self) -> str:
        """This error as the command line prints it: the Python argument named as its
        option (``sample_time_s`` as ``--sample-time``: dashes for underscores, no unit
        suffix); an error about a file or key as it is."""
        if not self.argument or self.file or self.key:
            return str(self)
        return f"--{self.argument.removesuffix('_s').replace('_', '-')}: {self.detail}"


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
