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

from typing import Any

from fuzzyservo.components.declare import Component, Param, Signal, phase


@phase("mass")
def drum_inertia(P: Any, mass: float) -> float:
    return mass + P.mass * P.drum_radius * P.drum_radius


@phase("t", "f_load")
def hanging_weight(P: Any, f_load: float) -> tuple[float, float]:
    t = P.winding * P.mass * P.acceleration * P.drum_radius
    return t, f_load + t


@phase("t", "payout", "z_load", "f_load")
def platform_weight(P: Any, pos: float, f_ext: float, f_load: float) -> tuple[float, ...]:
    """:func:`hanging_weight`, and where the load hangs on the platform at height f_ext."""
    t = P.winding * P.mass * P.acceleration * P.drum_radius
    payout = -P.winding * P.drum_radius * pos
    z_load = f_ext + P.winding * P.drum_radius * pos
    return t, payout, z_load, f_load + t


def _drum(type_name: str, doc: str, platform: bool) -> Component:
    signals = [Signal("t_drum", "N*m", "t", "the weight's torque on the shaft")]
    if platform:
        signals += [
            Signal("payout", "m", "payout", "cable paid out"),
            Signal(
                "z_load",
                "m",
                "z_load",
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
        code={"mass": drum_inertia, "load": platform_weight if platform else hanging_weight},
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
