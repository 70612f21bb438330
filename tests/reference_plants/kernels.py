"""Maps only the seeds' hand-written plants use (they left the package with them).

``circle_area`` (cylinder geometry), ``four_way_flows`` (seed 003's critically lapped
valve) and the seed-001 servo-valve's ``port_flow``/``supply_flow``/``return_flow``
(the flow into one load port: the spool lag is a state of the plant that owns the
valve).
"""

from __future__ import annotations

import math
from typing import Any

from fuzzyservo._jit import njit
from fuzzyservo.components.effects import LIBRARY
from fuzzyservo.components.orifice import signed_sqrt_flow

_QUARTER_PI = math.pi / 4.0


@njit(cache=True, inline="always")
def circle_area(diameter: float) -> float:
    """Area of a circle ``π·d²/4`` [m²] for a diameter ``d`` [m] (piston or rod)."""
    return _QUARTER_PI * diameter * diameter


@njit(cache=True, inline="always")
def four_way_flows(
    k: float, ps: float, pa: float, pb: float, pt: float, p_lam: float
) -> tuple[float, float, float, float]:
    """Metering-edge flows of a critically lapped 4-way valve [m³/s].

    ``k`` [m³/(s·√Pa)] is the signed opening: k > 0 opens P→A and B→T, k < 0 opens
    P→B and A→T; each edge is the regularised orifice law of
    :func:`~fuzzyservo.components.orifice.signed_sqrt_flow`. Returns
    (q_PA, q_BT, q_PB, q_AT), each positive in the direction of its name.
    """
    kp = max(k, 0.0)
    kn = max(-k, 0.0)
    return (
        signed_sqrt_flow(kp, ps - pa, p_lam),
        signed_sqrt_flow(kp, pb - pt, p_lam),
        signed_sqrt_flow(kn, ps - pb, p_lam),
        signed_sqrt_flow(kn, pa - pt, p_lam),
    )


@njit(cache=True, inline="always")
def port_flow(
    opening: float,
    coeff: float,
    leak: float,
    p_supply: float,
    p_tank: float,
    p_port: float,
    p_lam: float,
) -> float:
    """Flow into a load port [m³/s] of a critically lapped 4-way valve (seed 001 eq. 3-4).

    ``opening`` is the spool position as a fraction of full opening (−1..1), signed so
    that a positive opening connects the port to supply, a negative one to tank (port B
    of the valve is called with ``−opening``). ``coeff`` K [m³/(s·sqrt(Pa))] is the
    fully open land, ``q = K·|opening|·sqrt(Δp)`` with the regularised orifice law.
    ``leak`` K_l [m³/(s·Pa)] is the laminar clearance leakage of the two lands at the
    port, supply → port and port → tank, which seed 001 eq. 3-4 write as
    ``−K_l·(p0 − pa)`` and ``−K_l·pb``; it sets the null pressures of a closed valve at
    (p_supply + p_tank)/2.
    """
    q = leak * (p_supply - p_port) - leak * (p_port - p_tank)
    if opening > 0.0:
        q += signed_sqrt_flow(coeff * opening, p_supply - p_port, p_lam)
    elif opening < 0.0:
        q -= signed_sqrt_flow(-coeff * opening, p_port - p_tank, p_lam)
    return q


@njit(cache=True, inline="always")
def supply_flow(
    opening: float,
    coeff: float,
    leak: float,
    p_supply: float,
    p_port: float,
    p_lam: float,
) -> float:
    """Flow drawn from supply by one port's supply land [m³/s] (``opening`` as in :func:`port_flow`)."""
    q = leak * (p_supply - p_port)
    if opening > 0.0:
        q += signed_sqrt_flow(coeff * opening, p_supply - p_port, p_lam)
    return q


@njit(cache=True, inline="always")
def return_flow(
    opening: float, coeff: float, leak: float, p_tank: float, p_port: float, p_lam: float
) -> float:
    """Flow from one port to tank through its tank land [m³/s] (``opening`` as in :func:`port_flow`)."""
    q = leak * (p_port - p_tank)
    if opening < 0.0:
        q += signed_sqrt_flow(-coeff * opening, p_port - p_tank, p_lam)
    return q


# The effect library as the hand-written seed 002 and seed 000 kernels read it
# (external_leakage came later, with the composed actuators).
FIRST_EFFECTS = tuple(name for name in LIBRARY if name != "external_leakage")


def effective_bulk_modulus(params: Any) -> float:
    """The bulk modulus the seed-002 kernel uses [Pa]: the effect's E_eff when set, else
    the oil's (a composition reads the same through ``components.effects.bulk_modulus``)."""
    return params.effective_bulk_modulus_pa or params.bulk_modulus_pa
