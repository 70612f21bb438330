"""Packed vectors declared by name: a controller's parameters ``cp`` and state ``cs``.

The compiled loop hands every controller two float64 vectors. Each controller declares
their slots once, in order, with :func:`layout`; the index of a slot is derived from
that order and never written by hand. A layout is a namedtuple of ints, which numba
reads as compile-time constants, so a kernel writes ``cp[PI_PARAMS.kp]`` at no cost;
:func:`pack` builds a vector by slot name, and code generation (:mod:`fuzzyservo.codegen`)
reads the same declaration for its constants and its state struct.
"""

from __future__ import annotations

from collections import namedtuple
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["Slot", "layout", "pack", "slots"]


@dataclass(frozen=True)
class Slot:
    """One slot of a packed vector: its name, what it holds (with its unit), and whether
    it is a 0/1 flag (generated code declares those as an integer or a BOOL)."""

    name: str
    doc: str = ""
    flag: bool = False


def layout(typename: str, *declared: str | Slot) -> Any:
    """The layout of the slots ``declared`` in order: a namedtuple whose field ``name``
    is that slot's index (``len(layout)`` is the vector's size); :func:`slots` gives
    the declarations back."""
    items = tuple(s if isinstance(s, Slot) else Slot(s) for s in declared)
    names = [s.name for s in items]
    if len(set(names)) != len(names):
        raise ValueError(f"layout {typename}: a slot is declared twice in {names}")
    cls = namedtuple(typename, names)  # type: ignore[misc]
    cls.slots = items
    return cls(*range(len(items)))


def slots(layout: Any) -> tuple[Slot, ...]:
    """The declarations of ``layout``'s slots, in order."""
    return type(layout).slots


def pack(layout: Any, **values: float) -> np.ndarray:
    """A float64 vector laid out by ``layout``, every slot given by name."""
    names = type(layout)._fields
    missing = [n for n in names if n not in values]
    unknown = [n for n in values if n not in names]
    if missing or unknown:
        raise ValueError(
            f"{type(layout).__name__}: slots {names} must each be given once, but "
            f"{missing} are missing and {unknown} are not slots"
        )
    return np.array([float(values[n]) for n in names])
