"""MATLAB ``.fis`` and IEC 61131-7 FCL files ⇄ fuzzy systems and controllers.

The text is parsed and written by :mod:`fuzzyservo.controllers.fuzzy.fis` and
:mod:`fuzzyservo.controllers.fuzzy.fcl` (pure, text ⇄ objects); this module only reads
and writes the files. A ``.fis`` file is read as UTF-8, else latin-1 (older MATLAB wrote
the platform's encoding, often cp1252); so is an FCL file.
"""

from __future__ import annotations

from pathlib import Path

from fuzzyservo.atomic import write_text
from fuzzyservo.controllers.fuzzy.controller import FuzzyController
from fuzzyservo.controllers.fuzzy.fcl import (
    fcl_text,
    parse_fcl,
    parse_fcl_controller,
    parse_fcl_law,
)
from fuzzyservo.controllers.fuzzy.fis import fis_text, parse_fis_controller, parse_fis_law
from fuzzyservo.controllers.fuzzy.system import FuzzySystem
from fuzzyservo.errors import ConfigError

__all__ = [
    "controller_from_fcl", "controller_from_fis", "read_fcl", "read_fcl_law", "read_fis",
    "read_fis_law", "read_text", "write_fcl", "write_fis",
]  # fmt: skip


def read_text(path: str | Path) -> str:
    """A text file as UTF-8 (a byte-order mark dropped), else latin-1; a missing or
    unreadable file is a :class:`ConfigError` naming it and the fix."""
    p = Path(path)
    if not p.is_file():
        raise ConfigError(
            f"file not found (looked in {p.resolve().parent}); check the path", file=str(path)
        )
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise ConfigError(
            f"cannot read the file ({exc.strerror or exc}); check its permissions", file=str(path)
        ) from None
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError:
        return data.decode("latin-1")


def read_fis(path: str | Path, points: int = 201) -> FuzzySystem:
    """Read a MATLAB ``.fis`` file into a :class:`FuzzySystem` (universes of ``points``
    samples unless its ``% fuzzyservo:`` line says otherwise). Raises
    :class:`ConfigError` naming the file, the section and line, and the fix."""
    return parse_fis_law(read_text(path), str(path), points)[0]


def read_fis_law(path: str | Path) -> tuple[FuzzySystem, dict[str, str]]:
    """The system of a ``.fis`` file and the control law its ``% fuzzyservo:`` line
    gives (:func:`~fuzzyservo.controllers.fuzzy.fis.parse_fis_law`)."""
    return parse_fis_law(read_text(path), str(path))


def controller_from_fis(path: str | Path) -> FuzzyController:
    """A controller from a ``.fis`` file, named after its stem
    (:func:`~fuzzyservo.controllers.fuzzy.fis.parse_fis_controller`)."""
    return parse_fis_controller(read_text(path), str(path))


def write_fis(system: FuzzySystem, path: str | Path, law: str = "") -> Path:
    """Write ``system`` (and the control law ``law``,
    :func:`~fuzzyservo.controllers.fuzzy.fis.law_text`) as a MATLAB ``.fis`` file
    (UTF-8); returns the path."""
    return write_text(path, fis_text(system, law))


def read_fcl(path: str | Path, points: int = 201) -> FuzzySystem:
    """Read an FCL file; :class:`ConfigError` naming the file, line and fix when it is bad."""
    return parse_fcl(read_text(path), str(path), points)


def read_fcl_law(path: str | Path) -> tuple[FuzzySystem, dict[str, str]]:
    """The system of an FCL file and the control law its ``(* fuzzyservo: … *)`` comment
    gives (empty when it gives none)."""
    return parse_fcl_law(read_text(path), str(path))


def controller_from_fcl(path: str | Path) -> FuzzyController:
    """A controller from an FCL file, named after its stem
    (:func:`~fuzzyservo.controllers.fuzzy.fcl.parse_fcl_controller`)."""
    return parse_fcl_controller(read_text(path), str(path))


def write_fcl(system: FuzzySystem, path: str | Path, law: str = "") -> Path:
    """Write ``system`` (and the control law ``law``) as FCL (UTF-8); returns the path."""
    return write_text(path, fcl_text(system, law))
