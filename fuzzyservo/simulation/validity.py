"""Physical validity of a finished run: no chamber pressure below the oil's vapour pressure.

Without the ``entrained_air`` effect a plant's pressure law p = E·(ρ/ρ0 − 1) happily goes
below vacuum. Every plant states pressures against the atmosphere (gauge; the tank or
return line at 0 bar), so absolute zero is −1.013 bar. Mineral oil's vapour pressure is
well below 1 kPa absolute at working temperatures, so the floor is taken as absolute
zero: below it the model describes a liquid under tension, which real oil never
sustains. Such a run completes but reports ``cavitation``, never ``ok``.

With the ``entrained_air`` effect the chambers stiffen with E_mix(p) and stop at the
vapour pressure p_v (components/effects.py, ``chamber_modulus``): a chamber that reaches
the floor (below 2·p_v absolute, where it acts) has cavitated as modelled; the run
reports ``cavitation`` too, with a message saying that the floor held it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

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


def entrained_air(params: Any) -> EntrainedAir | None:
    """The free air of a plant's parameter set when its ``entrained_air`` effect is on
    (fixed parameters left at 0 take the effect's defaults, as the kernel does), else None."""
    alpha = float(getattr(params, "air_fraction", 0.0))
    if alpha <= 0.0:
        return None
    return EntrainedAir(
        air_fraction=alpha,
        polytropic_index=max(float(params.air_polytropic_index), 1.0),
        vapour_pressure_pa=float(params.air_vapour_pressure_pa) or 1.0e3,
    )


def pressure_violation(
    t: np.ndarray,
    signals: Mapping[str, np.ndarray],
    pressures: Sequence[str],
    air: EntrainedAir | None = None,
) -> str:
    """Why the run is unphysical, or "" when every pressure stays above the vapour pressure.

    ``pressures`` names the gauge chamber pressures [Pa] among ``signals``; the message
    names the lowest one, its value and the time it is reached. ``air``: the plant's
    entrained air (:func:`entrained_air`); then reaching its floor (2·p_v absolute) is
    reported, as cavitation the model holds at the vapour pressure.
    """
    name, worst, at = lowest_pressure(t, signals, pressures)
    # the gauge pressure below which the run is reported: with entrained air its floor
    # (2·p_v absolute), without it the vapour pressure itself
    floor = VAPOUR_PRESSURE_PA if air is None else 2.0 * air.vapour_pressure_pa - ATMOSPHERE_PA
    if worst >= floor:
        return ""
    first = float(t[np.flatnonzero(np.asarray(signals[name]) < floor)[0]])
    if air is not None:
        return (
            f"{name} reached the oil's vapour pressure ({air.vapour_pressure_pa / 1e5:.2g} bar "
            f"absolute) at t = {first:.3f} s, down to "
            f"{(worst + ATMOSPHERE_PA) / 1e5:.3g} bar absolute at t = {at:.3f} s: the oil "
            "cavitates there; the entrained_air effect holds the chamber at that floor"
        )
    return (
        f"{name} fell below the oil's vapour pressure ({VAPOUR_PRESSURE_PA / 1e5:.2f} bar gauge, "
        f"0 Pa absolute) at t = {first:.3f} s, down to {worst / 1e5:.4g} bar at "
        f"t = {at:.3f} s; the model has no cavitation, so the run is unphysical from there"
    )


def air_note(p_gauge_pa: float, oil_modulus_pa: float, air: EntrainedAir | None = None) -> str:
    """What entrained air does at a chamber's lowest pressure: the free-air share and the
    mixture's bulk modulus against the oil's (components/air.py). ``air``: the plant's own
    (its ``entrained_air`` effect, which the chambers then integrate with); None: the
    default air, which a constant-E chamber law leaves out."""
    modelled = air is not None
    air = air or EntrainedAir()
    p_abs = p_gauge_pa + ATMOSPHERE_PA
    if p_abs <= air.vapour_pressure_pa:
        return (
            f"below the vapour pressure ({air.vapour_pressure_pa / 1e5:.2g} bar absolute): "
            "the oil would cavitate, no liquid model holds there"
        )
    e_mix = air.bulk_modulus(p_abs, oil_modulus_pa)
    return (
        ("chambers integrate E_mix (entrained_air effect): " if modelled else "")
        + f"with {100 * air.air_fraction:.2g} % air at 1 atm, {100 * air.free_air_ratio(p_abs):.2g} % "
        f"free air there and a mixture modulus of {e_mix / 1e6:.3g} MPa, "
        f"{100 * e_mix / oil_modulus_pa:.2g} % of the oil's {oil_modulus_pa / 1e9:.3g} GPa"
    )
