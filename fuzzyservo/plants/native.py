"""A composition's kernels compiled by the system's C compiler, in a fraction of a second.

numba takes seconds to compile a composition's right-hand side, signals and end stops;
the C translation of the same equations (:mod:`.c_source`, what an exported plant FMU
carries) compiles in about 0.2 s and gives the same numbers to the bit (no fast-math and
no contraction on either side; ``tests/test_plant_export.py`` holds every shipped rig and
effect to this). :func:`native_kernels` builds it, with an entry point per kernel of the
loop's ABI (:mod:`.abi`), once per composition and machine (:func:`fuzzyservo._jit.build_c`).
It gives None where there is no C compiler, where the translation cannot follow a
component's code, or when ``FUZZYSERVO_KERNELS=numba`` is set: numba compiles them then.
A composition's Jacobian (plants/_jacobian.py: each column re-runs only what its state
reaches) is translated too; without one the loop's forward differences serve, the same
numbers.
"""

from __future__ import annotations

import ctypes
import os
from dataclasses import dataclass

import numpy as np
from numba import types

from fuzzyservo._jit import build_c
from fuzzyservo.plants import PlantModel
from fuzzyservo.plants.abi import END_STOP, JACOBIAN, KERNELS, RHS, SIGNALS, c_prototype
from fuzzyservo.plants.c_source import TranslationError, plant_c_sources

#: the environment variable that picks numba for every plant's kernels ("numba")
KERNELS_VARIABLE = "FUZZYSERVO_KERNELS"
_D = ctypes.POINTER(ctypes.c_double)
#: the slots the C translation provides, and how its own function is called from the entry
_CALLS = {
    RHS: "plant_rhs(x, u, f_ext, p, dx)",
    SIGNALS: "plant_signals(x, u, f_ext, p, out)",
    END_STOP: "(int64_t)(plant_in_end_stop(x, p) != 0.0)",
    JACOBIAN: "plant_jacobian(x, u, f_ext, p, f0, typical, jac, (long)jac_n1, ftmp)",
}


@dataclass(frozen=True)
class NativeKernels:
    """A composition's kernels in a loaded shared library: ``addresses`` of the loop's
    entry points by slot (:mod:`.abi`), and its signals callable from Python."""

    library: ctypes.CDLL
    addresses: dict[int, int]

    def signals(
        self, x: np.ndarray, u: float, f_ext: float, p: np.ndarray, out: np.ndarray
    ) -> None:
        """``plant_signals`` into ``out`` (float64 arrays, contiguous)."""
        self.library.plant_signals(
            np.ascontiguousarray(x, dtype=np.float64).ctypes.data_as(_D), ctypes.c_double(u),
            ctypes.c_double(f_ext), np.ascontiguousarray(p, dtype=np.float64).ctypes.data_as(_D),
            out.ctypes.data_as(_D),
        )  # fmt: skip


def _entry_points(has_jacobian: bool) -> str:
    """The C of the loop's entry points, each calling the translated function."""
    lines = ["#include <stdint.h>", '#include "plant_model.h"', ""]
    for slot, call in _CALLS.items():
        if slot == JACOBIAN and not has_jacobian:
            continue
        prototype = c_prototype(slot, f"fs_entry_{KERNELS[slot][0]}")
        returns = "" if KERNELS[slot][2] == types.void else "return "
        lines += [prototype, "{", f"    {returns}{call};", "}", ""]
    return "\n".join(lines)


def native_kernels(plant: PlantModel) -> NativeKernels | None:
    """The composition ``plant``'s kernels built by the C compiler (module docstring), or
    None where numba compiles them."""
    if os.environ.get(KERNELS_VARIABLE, "").strip().lower() == "numba" or not plant.components:
        return None
    if plant.binding not in _BUILT:
        _BUILT[plant.binding] = _built(plant)
    return _BUILT[plant.binding]


_BUILT: dict[str, NativeKernels | None] = {}  # by binding: the same source, the same library


def _built(plant: PlantModel) -> NativeKernels | None:
    try:
        files = plant_c_sources(plant, end_stop=True)
    except TranslationError:
        return None
    has_jacobian = "void plant_jacobian(" in files["plant_model.h"]
    files["entry_points.c"] = _entry_points(has_jacobian)
    library = build_c(files)
    if library is None:
        return None
    addresses = {
        slot: ctypes.cast(getattr(library, f"fs_entry_{KERNELS[slot][0]}"), ctypes.c_void_p).value
        for slot in _CALLS
        if slot != JACOBIAN or has_jacobian
    }
    library.plant_signals.restype = None
    return NativeKernels(library, addresses)


__all__ = ["KERNELS_VARIABLE", "NativeKernels", "native_kernels"]
