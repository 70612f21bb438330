"""Orifice laws, regularised near zero pressure drop so that the flow has a finite slope.

Pure compiled maps, no integration.
"""

from __future__ import annotations

import math

from fuzzyservo._jit import njit


@njit(cache=True, inline="always")
def signed_sqrt_flow(coeff: float, dp: float, p_lam: float) -> float:
    """Turbulent orifice flow ``q = K·Δp / (Δp² + p_lam²)^(1/4)`` [m³/s].

    ``coeff`` K in m³/(s·sqrt(Pa)), ``dp`` Δp in Pa, ``p_lam`` in Pa. Equals
    ``K·sign(Δp)·sqrt(|Δp|)`` for ``|Δp| ≫ p_lam`` and is linear (laminar) below,
    so ``dq/dΔp`` is bounded by ``K/sqrt(p_lam)``. Source: docs/modelling.md "Orifice law
    near Δp = 0" (Hopsan's signedSquareL, Simscape's orifice).
    """
    # two square roots are several times faster than a fractional power
    return coeff * dp / math.sqrt(math.sqrt(dp * dp + p_lam * p_lam))
