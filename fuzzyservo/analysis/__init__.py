"""Loop analysis on the nonlinear model: stability margins and frequency response,
measured by simulation (no linearisation)."""

from fuzzyservo.analysis.frequency import FrequencyResponse, frequency_response
from fuzzyservo.analysis.margins import Margins, delay_margin, gain_margin, margins, oscillation

__all__ = [
    "FrequencyResponse",
    "Margins",
    "delay_margin",
    "frequency_response",
    "gain_margin",
    "margins",
    "oscillation",
]
