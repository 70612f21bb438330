"""The sensor's analogue-to-digital converter: the quantisation a reading passes through.

One kernel shared by the compiled loop (:mod:`fuzzyservo.simulation._loop`, the ADC stage)
and the rig's sensor model (:meth:`fuzzyservo.rig.LinearSensor.measure`).
"""

from __future__ import annotations

import numpy as np

from fuzzyservo._jit import njit


@njit(cache=True)
def adc(v: float | np.ndarray, lo: float, hi: float, step: float) -> float | np.ndarray:
    """An ADC of step ``step`` over ``lo .. hi``: the nearest of the 2^bits codes
    ``lo + c·step`` (c = 0 .. 2^bits − 1); readings outside the range clip to its ends.
    ``step`` 0 passes ``v`` through."""
    if step <= 0.0:
        return v + 0.0
    code = np.floor((v - lo) / step + 0.5)
    top = np.floor((hi - lo) / step + 0.5) - 1.0
    return lo + np.minimum(np.maximum(code, 0.0), top) * step


__all__ = ["adc"]
