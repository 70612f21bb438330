"""A mass hanging from a cable wound on a drum on the motor shaft (seed 001's AHC stand).

The drum of radius r turns with the shaft; the mass m adds m·r² to the inertia and its
weight a torque m·g·r opposing +θ when turning forward winds the cable in and lifts it
(``winding`` +1, the default), or pulling +θ when turning forward pays the cable out
(``winding`` −1, seed 001's convention: positive drum angle pays out). The cable is
taken stiff and always taut.

``platform_cable_drum`` is the same drum on a heaving platform (seed 001's compensator
on the wave-simulator rod): the scenario's load input is then the platform's height
z_w [m] instead of a torque, and the load hangs at ``z_load = z_w − payout`` with the
payout ``−winding·r·θ``. The rigid cable makes z_w no force on the shaft; the
platform's acceleration is left out of the cable tension (below 2 % of g for the
0.05-0.2 Hz waves of seed 001's heave).
"""

from __future__ import annotations

from fuzzyservo.components.declare import Component, Param, Signal


def _drum(type_name: str, doc: str, platform: bool) -> Component:
    signals = [Signal("t_drum", "N*m", "L.t", "the weight's torque on the shaft")]
    if platform:
        signals += [
            Signal("payout", "m", "-P.winding * P.drum_radius * pos", "cable paid out"),
            Signal(
                "z_load",
                "m",
                "f_ext + P.winding * P.drum_radius * pos",
                "the load's height: the platform's less the payout",
            ),
        ]
    return Component(
        type=type_name,
        role="load",
        doc=doc,
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
        signals=tuple(signals),
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
        load=("z_wave", "m") if platform else None,
    )


COMPONENTS = (
    _drum(
        "cable_drum",
        "mass m on a cable wound on a drum of radius r: inertia m·r², torque m·g·r",
        platform=False,
    ),
    _drum(
        "platform_cable_drum",
        "a cable_drum on a heaving platform: the scenario's load is the platform's height",
        platform=True,
    ),
)
