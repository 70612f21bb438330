"""Typed, frozen parameter sets whose fields carry their SI unit and physical bounds.

A field is declared with :func:`quantity`; its name ends with the SI unit
(``bulk_modulus_pa``), its metadata holds the key used in files (``bulk_modulus``),
the SI unit expression and the admissible range. :func:`check` validates a whole
parameter set and raises ``ValueError`` naming the key, the value and the fix.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np


def quantity(
    key: str,
    unit: str,
    *,
    default: float | None = None,
    minimum: float | None = None,
    maximum: float | None = None,
    positive: bool = False,
    nonnegative: bool = False,
    nonzero: bool = False,
    doc: str = "",
    effect: bool = False,
) -> Any:
    """Declare a dataclass field that holds a physical quantity in SI units.

    ``key`` is the name used in rig files, ``unit`` the SI unit expression the field
    is stored in (see :mod:`fuzzyservo.units`).
    """
    meta = {
        "key": key,
        "unit": unit,
        "minimum": minimum,
        "maximum": maximum,
        "positive": positive,
        "nonnegative": nonnegative,
        "nonzero": nonzero,
        "doc": doc,
        "effect": effect,
    }
    if default is None:
        return dataclasses.field(metadata=meta)
    if effect:
        # effect parameters (components/effects.py) are inherited by every plant's
        # parameter set; keyword-only keeps them out of the positional signature
        return dataclasses.field(default=default, metadata=meta, kw_only=True)
    return dataclasses.field(default=default, metadata=meta)


def vector(key: str, length: int, *, fmt: str, doc: str = "") -> Any:
    """Declare a dataclass field holding a fixed-length tuple of floats (e.g. network weights).

    :func:`pack` appends it after the quantities (``length`` zeros when the tuple is
    empty). ``fmt`` names the file format the rig reader loads it from (the file is
    named under ``key`` in the rig file).
    """
    meta = {"vector_key": key, "length": length, "format": fmt, "doc": doc}
    return dataclasses.field(default=(), metadata=meta)


def vectors_by_key(cls: type) -> dict[str, dataclasses.Field]:
    """Map file keys to the dataclass fields declared with :func:`vector`."""
    return {
        f.metadata["vector_key"]: f for f in dataclasses.fields(cls) if "vector_key" in f.metadata
    }


def fields_by_key(cls: type, *, effects: bool = False) -> dict[str, dataclasses.Field]:
    """Map file keys to the dataclass fields declared with :func:`quantity`: the plant's
    own parameters, or with ``effects=True`` the inherited effect parameters."""
    return {
        f.metadata["key"]: f
        for f in dataclasses.fields(cls)
        if "key" in f.metadata and f.metadata.get("effect", False) == effects
    }


def check(params: Any) -> None:
    """Validate every quantity of a parameter set; raise ``ValueError`` on the first bad one."""
    for f in dataclasses.fields(params):
        meta = f.metadata
        if "vector_key" in meta:
            _check_vector(getattr(params, f.name), meta)
            continue
        if "key" not in meta:
            continue
        value = getattr(params, f.name)
        key, unit = meta["key"], meta["unit"]
        if (
            not isinstance(value, int | float)
            or isinstance(value, bool)
            or not math.isfinite(value)
        ):
            raise ValueError(
                f"{key}: must be a finite number in {unit}, got {value!r}; give a number"
            )
        fix = meta["doc"] or "check the value and its unit"
        if meta["positive"] and not value > 0:
            raise ValueError(
                f"{key}: must be > 0 {unit} (physical), got {value!r}; give a positive value"
            )
        if meta["nonnegative"] and value < 0:
            raise ValueError(f"{key}: must be >= 0 {unit} (physical), got {value!r}; {fix}")
        if meta["nonzero"] and value == 0:
            raise ValueError(f"{key}: must not be zero, got {value!r}; {fix}")
        if meta["minimum"] is not None and value < meta["minimum"]:
            raise ValueError(f"{key}: must be >= {meta['minimum']} {unit}, got {value!r}; {fix}")
        if meta["maximum"] is not None and value > meta["maximum"]:
            raise ValueError(f"{key}: must be <= {meta['maximum']} {unit}, got {value!r}; {fix}")


def _check_vector(value: Any, meta: dict) -> None:
    key, length = meta["vector_key"], meta["length"]
    if not isinstance(value, tuple) or len(value) not in (0, length):
        got = len(value) if isinstance(value, tuple) else type(value).__name__
        raise ValueError(
            f"{key}: must be a tuple of {length} floats (or empty), got {got}; "
            f"{meta['doc'] or 'check the file it was read from'}"
        )
    if not all(isinstance(v, float) and math.isfinite(v) for v in value):
        raise ValueError(f"{key}: every entry must be a finite float; check the file")


def pack(params: Any) -> np.ndarray:
    """Pack a parameter set into a float64 vector: the quantities in field order, then
    every :func:`vector` field (its ``length`` entries, zeros when empty).

    Compiled kernels index this vector with the ``P_*`` constants their module defines;
    a vector field starts at :func:`vector_offset`.
    """
    values = [
        float(getattr(params, f.name)) for f in dataclasses.fields(params) if "key" in f.metadata
    ]
    for f in dataclasses.fields(params):
        if "vector_key" in f.metadata:
            entries = getattr(params, f.name)
            values.extend(entries if entries else [0.0] * f.metadata["length"])
    return np.array(values, dtype=np.float64)


def vector_offset(cls: type, name: str) -> int:
    """Position in :func:`pack`'s vector where the :func:`vector` field ``name`` starts."""
    offset = sum(1 for f in dataclasses.fields(cls) if "key" in f.metadata)
    for f in dataclasses.fields(cls):
        if "vector_key" not in f.metadata:
            continue
        if f.name == name:
            return offset
        offset += f.metadata["length"]
    raise ValueError(f"{name}: not a vector field of {cls.__name__}")


def param_index(cls: type) -> Any:
    """A namedtuple of every quantity field's position in :func:`pack`'s vector, by field
    name: compiled kernels read ``p[P.bulk_modulus_pa]`` (numba reads it as a constant)."""
    from collections import namedtuple

    names = [f.name for f in dataclasses.fields(cls) if "key" in f.metadata]
    return namedtuple(f"{cls.__name__}Index", names)(*range(len(names)))


def name_index(names: tuple[str, ...], typename: str = "Signals") -> Any:
    """A namedtuple of each name's position: ``out[S.p1] = p1`` writes a signal table by
    name, generated from the one tuple that declares the names."""
    from collections import namedtuple

    return namedtuple(typename, names)(*range(len(names)))


def index_of(cls: type, name: str) -> int:
    """Position of field ``name`` in :func:`pack`'s vector (for ``P_*`` constants)."""
    names = [f.name for f in dataclasses.fields(cls) if "key" in f.metadata]
    return names.index(name)
