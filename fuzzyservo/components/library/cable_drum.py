"""A mass hanging from a cable wound on a drum on the motor shaft (seed 001's AHC stand).

The drum of radius r turns with the shaft; the mass m adds m·r² to the inertia and its
weight a torque m·g·r opposing +θ when turning forward winds the cable in and lifts it
(``winding`` +1, the default), or pulling +θ when turning forward pays the cable out
(``winding`` −1, seed 001's convention: positive drum angle pays out). The cable is
taken stiff and always taut.
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
            Param(
                "winding",
                "1",
                "+1: turning forward winds the cable in (lifts); −1: it pays the cable out",
                default=1.0,
                minimum=-1.0,
                maximum=1.0,
            ),
        ),
        signals=(Signal("t_drum", "N*m", "L.t", "the weight's torque on the shaft"),),
        code={
            "mass": "mass += P.mass * P.drum_radius * P.drum_radius",
            "load": "L.t = P.winding * P.mass * P.acceleration * P.drum_radius\nf_load += L.t",
        },
        check=lambda v: (
            None
            if v["winding"] in (1.0, -1.0)
            else f"winding: must be +1 (forward lifts) or -1 (forward pays out), got "
            f"{v['winding']}; give one of the two"
        ),
        actuators=("motor",),
    ),
)
