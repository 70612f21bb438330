"""The closed loop: a controller at its sample time against a plant, and the result."""

from fuzzyservo.simulation.closed_loop import DEFAULT_TOL, simulate
from fuzzyservo.simulation.result import SimResult

__all__ = ["DEFAULT_TOL", "SimResult", "simulate"]
