"""A mass hanging from a cable wound on a drum on the motor shaft (seed 001's AHC stand).

The drum of radius r turns with the shaft; the mass m adds m·r² to the inertia and its
weight a torque m·g·r opposing +θ (turning forward lifts it). The cable is taken stiff
and always taut.
"""

from __future__ import annotations

from fuzzyservo.components._declare import Component, Param, Signal

COMPONENTS = (
    Component(
        type="cable_drum",
        role="load",
        doc="mass m on a cable wound on a drum of radius r: inertia m·r², torque m·g·r",
        source="seed 001 §2 (5 kg load on the compensating motor's cable drum)",
        params=(
            Param("mass", "kg", "the hanging mass m", positive=True),
            Param("drum_radius", "m", "the drum's radius r", positive=True),
            Param("acceleration", "m/s^2", "g", default=9.80665, positive=True),
        ),
        signals=(Signal("t_drum", "N*m", "L.t", "the weight's torque on the shaft"),),
        code={
            "mass": "mass += P.mass * P.drum_radius * P.drum_radius",
            "load": "L.t = P.mass * P.acceleration * P.drum_radius\nf_load += L.t",
        },
        actuators=("motor",),
    ),
)
