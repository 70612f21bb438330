"""Dispatch from a controller's ``kind`` code to its compiled step kernel.

One place lists every controller kind the compiled loop knows (codes in :mod:`.kinds`);
a new controller adds its kernel here. The Python face (``Controller.step``) calls each
class's own ``kernel``, so nothing imports this module back.
"""

from __future__ import annotations

import numpy as np

from fuzzyservo._jit import njit
from fuzzyservo.controllers.classical import open_loop_step, p_step, pi_step, pidf_step
from fuzzyservo.controllers.fuzzy.controller import fuzzy_step
from fuzzyservo.controllers.kinds import KIND_FUZZY, KIND_OPEN_LOOP, KIND_P, KIND_PI, KIND_PIDF


@njit(cache=True)
def controller_step(kind: int, cp: np.ndarray, cs: np.ndarray, r: float, y: float) -> float:
    """Command for reference ``r`` and measurement ``y``; updates the state ``cs`` in place."""
    if kind == KIND_P:
        return p_step(cp, cs, r, y)
    if kind == KIND_PI:
        return pi_step(cp, cs, r, y)
    if kind == KIND_FUZZY:
        return fuzzy_step(cp, cs, r, y)
    if kind == KIND_PIDF:
        return pidf_step(cp, cs, r, y)
    if kind == KIND_OPEN_LOOP:
        return open_loop_step(cp, cs, r, y)
    return np.nan
