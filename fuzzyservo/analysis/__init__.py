"""Loop analysis on the nonlinear model: stability margins and frequency response,
measured by simulation (no linearisation)."""

from fuzzyservo.analysis.margins import Margins, delay_margin, gain_margin, margins, oscillation

__all__ = ["Margins", "delay_margin", "gain_margin", "margins", "oscillation"]
