"""Plant families: pure right-hand sides of named states with frozen, unit-named parameters.

:data:`PLANTS` maps the ``plant.type`` a rig file names to its :class:`PlantModel`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from fuzzyservo.plants import cylinder, motor
from fuzzyservo.plants.kernels import KIND_CYLINDER, KIND_MOTOR


@dataclass(frozen=True)
class PlantModel:
    """Everything the simulator and the file reader need to know about a plant family."""

    type_name: str
    kind: int
    params_cls: type
    states: tuple[str, ...]
    signals: tuple[str, ...]
    signal_units: dict[str, str]
    input: tuple[str, str]
    load: tuple[str, str]
    initial_keys: dict[str, tuple[str, str]]
    initial_state: Callable[..., np.ndarray]
    state_scale: Callable[[Any], np.ndarray]
    typical_state: Callable[[Any], np.ndarray]
    description: str


PLANTS: dict[str, PlantModel] = {
    "open_centre_cylinder": PlantModel(
        type_name="open_centre_cylinder",
        kind=KIND_CYLINDER,
        params_cls=cylinder.CylinderParams,
        states=cylinder.STATES,
        signals=cylinder.SIGNALS,
        signal_units=cylinder.SIGNAL_UNITS,
        input=cylinder.INPUT,
        load=cylinder.LOAD,
        initial_keys=cylinder.INITIAL_KEYS,
        initial_state=cylinder.initial_state,
        state_scale=cylinder.state_scale,
        typical_state=cylinder.typical_state,
        description="open-centre servo-valve + asymmetric cylinder (seed 002)",
    ),
    "servo_motor": PlantModel(
        type_name="servo_motor",
        kind=KIND_MOTOR,
        params_cls=motor.MotorParams,
        states=motor.STATES,
        signals=motor.SIGNALS,
        signal_units=motor.SIGNAL_UNITS,
        input=motor.INPUT,
        load=motor.LOAD,
        initial_keys=motor.INITIAL_KEYS,
        initial_state=motor.initial_state,
        state_scale=motor.state_scale,
        typical_state=motor.typical_state,
        description="servo-valve + axial-piston motor, velocity loop (seed 000)",
    ),
}

__all__ = ["PLANTS", "PlantModel"]
