"""The controller kind codes the compiled loop dispatches on, defined once.

Each controller class takes its ``kind`` from here and :mod:`.kernels` maps each code
to its step kernel; a code used twice is refused when this module is imported.
"""

from __future__ import annotations

KINDS: dict[str, int] = {"open_loop": 0, "P": 1, "PI": 2, "fuzzy": 3, "PIDF": 4, "fmu": 5}

if len(set(KINDS.values())) != len(KINDS):
    raise ValueError(f"controller kind codes must be unique, got {KINDS}")

KIND_OPEN_LOOP = KINDS["open_loop"]
KIND_P = KINDS["P"]
KIND_PI = KINDS["PI"]
KIND_FUZZY = KINDS["fuzzy"]
KIND_PIDF = KINDS["PIDF"]
#: an FMU: no compiled kernel, run sample by sample (simulation.closed_loop.simulate_stepped)
KIND_FMU = KINDS["fmu"]
