"""Critically lapped four-way servo-valve: the flow into one load port, a pure map.

Used by the seed-001 plants (``ahc_cylinder``, ``ahc_motor``). No integration here:
the spool lag is a state of the plant that owns the valve.
"""

from __future__ import annotations

from fuzzyservo._jit import njit
from fuzzyservo.components.orifice import signed_sqrt_flow


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
