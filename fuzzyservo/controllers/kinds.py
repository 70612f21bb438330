"""The controller kind codes, defined once: what a controller is, for the code that
needs to tell them apart (the compiled loop calls each controller's own step kernel
through its address, simulation/binding.py). A code used twice is refused when this
module is imported.
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
