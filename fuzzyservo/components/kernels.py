"""The compiled maps and effect positions component code may call (``components/library``).

The composed right-hand side (:mod:`fuzzyservo.plants.composed`) imports everything
listed here, so a component's code reads ``signed_sqrt_flow(...)``
without imports of its own; effect parameters it reads as ``E.<field>``.
"""

from __future__ import annotations

import math

from fuzzyservo.components.effects import (
    actuator_friction,
    bristle_rate,
    bulk_modulus,
    chamber_modulus,
    friction_force,
    pump_limited,
)
from fuzzyservo.components.orifice import signed_sqrt_flow
from fuzzyservo.components.valves import metering_edges, nn_forward, polynomial_flow

__all__ = [
    "actuator_friction",
    "bristle_rate",
    "bulk_modulus",
    "chamber_modulus",
    "friction_force",
    "math",
    "metering_edges",
    "nn_forward",
    "polynomial_flow",
    "pump_limited",
    "signed_sqrt_flow",
]
