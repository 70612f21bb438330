"""Entrained air in the oil: the mixture's bulk modulus at a chamber's pressure.

Oil carries undissolved air (typically 0.1-1 % of its volume at atmospheric pressure).
The air follows a polytropic law, so its share of a chamber grows as the pressure falls,
and below a few bar it, not the oil, sets the chamber's stiffness. With the free-air
ratio at absolute pressure p (air volume per liquid volume)

    r(p) = α·(p_atm/p)^(1/n)

the mixture's bulk modulus is the volume-weighted compressibility of liquid and gas

    E_mix(p) = (1 + r) / (1/E_oil + r/(n·p))

(Merritt, *Hydraulic Control Systems*, 1967, §2.5; the "constant entrained air" model of
Simscape's Isothermal Liquid Properties block, α = 0.005 and n = 1 by default; MapleSim's
hydraulic Constant Volume, n = 1.4). E_mix tends to E_oil at high pressure and to n·p as
p → 0, so a chamber integrated with it approaches absolute zero only asymptotically; the
oil's vapour pressure (< 1 kPa absolute for mineral oil) is the floor below which no
liquid model holds (:mod:`fuzzyservo.simulation.validity`). docs/modelling.md,
"Entrained air and cavitation", gives the numbers for the seed rigs.
"""

from __future__ import annotations

from dataclasses import dataclass

from fuzzyservo._jit import njit

ATMOSPHERE_PA = 101_325.0


@njit(cache=True)
def mixture_modulus(
    p_abs: float, oil_modulus_pa: float, air_fraction: float, index: float
) -> float:
    """E_mix(p) = (1 + r)/(1/E_oil + r/(n·p)), r = α·(p_atm/p)^(1/n) [Pa], at ``p_abs``
    [Pa absolute, > 0]: the one formula the chambers' ``entrained_air`` effect and
    :class:`EntrainedAir` share."""
    r = air_fraction * (ATMOSPHERE_PA / p_abs) ** (1.0 / index)
    return (1.0 + r) / (1.0 / oil_modulus_pa + r / (index * p_abs))


@dataclass(frozen=True)
class EntrainedAir:
    """The oil's free air: ``air_fraction`` α [1] (air volume per liquid volume at
    atmospheric pressure), ``polytropic_index`` n [1] (1: isothermal, slow changes;
    1.4: adiabatic, fast ones), ``vapour_pressure_pa`` [Pa absolute] (the floor)."""

    air_fraction: float = 0.005
    polytropic_index: float = 1.0
    vapour_pressure_pa: float = 1.0e3

    def __post_init__(self) -> None:
        if not 0.0 <= self.air_fraction < 1.0:
            raise ValueError(
                f"air_fraction must lie in [0, 1), got {self.air_fraction} (0.001-0.01 is typical)"
            )
        if not 1.0 <= self.polytropic_index <= 1.4:
            raise ValueError(f"polytropic_index must lie in [1, 1.4], got {self.polytropic_index}")
        if not 0.0 < self.vapour_pressure_pa < ATMOSPHERE_PA:
            raise ValueError(
                f"vapour_pressure_pa must lie in (0, {ATMOSPHERE_PA:g}) Pa absolute, "
                f"got {self.vapour_pressure_pa}"
            )

    def free_air_ratio(self, p_abs: float) -> float:
        """r(p) = α·(p_atm/p)^(1/n): air volume per liquid volume at ``p_abs`` [Pa absolute]."""
        p = max(p_abs, self.vapour_pressure_pa)
        return self.air_fraction * (ATMOSPHERE_PA / p) ** (1.0 / self.polytropic_index)

    def bulk_modulus(self, p_abs: float, oil_modulus_pa: float) -> float:
        """E_mix(p) = (1 + r)/(1/E_oil + r/(n·p)) [Pa] at ``p_abs`` [Pa absolute]."""
        p = max(p_abs, self.vapour_pressure_pa)
        return float(mixture_modulus(p, oil_modulus_pa, self.air_fraction, self.polytropic_index))
