"""Physical validity of a finished run: no chamber pressure below the oil's vapour pressure.

No plant models cavitation (gas release, vapour cavities): its pressure law p = E·(ρ/ρ0 − 1)
happily goes below vacuum. Every plant states pressures against the atmosphere (gauge;
the tank or return line at 0 bar), so absolute zero is −1.013 bar. Mineral oil's vapour
pressure is well below 1 kPa absolute at working temperatures, so the floor is taken as
absolute zero: below it the model describes a liquid under tension, which real oil never
sustains. Such a run completes but reports ``cavitation``, never ``ok``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from fuzzyservo.components.air import ATMOSPHERE_PA, EntrainedAir

# Gauge pressure at which the oil would boil away (0 Pa absolute: its vapour pressure,
# < 1 kPa absolute, is within the rounding of the atmosphere).
VAPOUR_PRESSURE_PA = -ATMOSPHERE_PA
STATUS_CAVITATION = "cavitation"


def lowest_pressure(
    t: np.ndarray, signals: Mapping[str, np.ndarray], pressures: Sequence[str]
) -> tuple[str, float, float]:
    """The lowest gauge pressure [Pa] among ``pressures``: (name, value, time); ("", inf,
    0) when none has a finite sample."""
    worst, name, at = np.inf, "", 0.0
    for p_name in pressures:
        values = np.asarray(signals[p_name], dtype=np.float64)
        finite = np.isfinite(values)
        if not finite.any():
            continue
        k = int(np.argmin(np.where(finite, values, np.inf)))
        if values[k] < worst:
            worst, name, at = float(values[k]), p_name, float(t[k])
    return name, float(worst), at


def pressure_violation(
    t: np.ndarray, signals: Mapping[str, np.ndarray], pressures: Sequence[str]
) -> str:
    """Why the run is unphysical, or "" when every pressure stays above the vapour pressure.

    ``pressures`` names the gauge chamber pressures [Pa] among ``signals``; the message
    names the lowest one, its value and the time it is reached.
    """
    name, worst, at = lowest_pressure(t, signals, pressures)
    if worst >= VAPOUR_PRESSURE_PA:
        return ""
    first = np.flatnonzero(np.asarray(signals[name]) < VAPOUR_PRESSURE_PA)[0]
    return (
        f"{name} fell below the oil's vapour pressure ({VAPOUR_PRESSURE_PA / 1e5:.2f} bar gauge, "
        f"0 Pa absolute) at t = {float(t[first]):.3f} s, down to {worst / 1e5:.4g} bar at "
        f"t = {at:.3f} s; the model has no cavitation, so the run is unphysical from there"
    )


def air_note(p_gauge_pa: float, oil_modulus_pa: float, air: EntrainedAir | None = None) -> str:
    """What entrained air does at a chamber's lowest pressure: the free-air share and the
    mixture's bulk modulus against the oil's (components/air.py), which the plants'
    constant-E chamber law leaves out."""
    air = air or EntrainedAir()
    p_abs = p_gauge_pa + ATMOSPHERE_PA
    if p_abs <= air.vapour_pressure_pa:
        return (
            f"below the vapour pressure ({air.vapour_pressure_pa / 1e5:.2g} bar absolute): "
            "the oil would cavitate, no liquid model holds there"
        )
    e_mix = air.bulk_modulus(p_abs, oil_modulus_pa)
    return (
        f"with {100 * air.air_fraction:.2g} % air at 1 atm, {100 * air.free_air_ratio(p_abs):.2g} % "
        f"free air there and a mixture modulus of {e_mix / 1e6:.3g} MPa, "
        f"{100 * e_mix / oil_modulus_pa:.2g} % of the oil's {oil_modulus_pa / 1e9:.3g} GPa"
    )
