"""The closed loop: a controller at its sample time against a plant, and the result."""

from fuzzyservo.simulation._loop import ROS34PW2, Tableau
from fuzzyservo.simulation.binding import BoundLoop, bind
from fuzzyservo.simulation.closed_loop import DEFAULT_TOL, Resets, simulate
from fuzzyservo.simulation.result import SimResult

__all__ = [
    "DEFAULT_TOL",
    "ROS34PW2",
    "BoundLoop",
    "Resets",
    "SimResult",
    "Tableau",
    "bind",
    "simulate",
]
