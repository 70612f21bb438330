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
    }
    if default is None:
        return dataclasses.field(metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


def fields_by_key(cls: type) -> dict[str, dataclasses.Field]:
    """Map file keys to the dataclass fields declared with :func:`quantity`."""
    return {f.metadata["key"]: f for f in dataclasses.fields(cls) if "key" in f.metadata}


def check(params: Any) -> None:
    """Validate every quantity of a parameter set; raise ``ValueError`` on the first bad one."""
    for f in dataclasses.fields(params):
        meta = f.metadata
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


def pack(params: Any) -> np.ndarray:
    """Pack the quantities of a parameter set, in field order, into a float64 vector.

    Compiled kernels index this vector with the ``P_*`` constants their module defines.
    """
    return np.array(
        [float(getattr(params, f.name)) for f in dataclasses.fields(params) if "key" in f.metadata],
        dtype=np.float64,
    )


def index_of(cls: type, name: str) -> int:
    """Position of field ``name`` in :func:`pack`'s vector (for ``P_*`` constants)."""
    names = [f.name for f in dataclasses.fields(cls) if "key" in f.metadata]
    return names.index(name)
