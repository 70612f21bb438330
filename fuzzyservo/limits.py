"""Sizes refused before any work starts: a run's length, the shortest sample period, a port.

A closed-loop run keeps every controller sample of every signal in memory, so its
length is bounded; a sample period below a microsecond is no controller or logger
(and a subnormal one overflows the step count). Each check returns the problem as
text (``None`` when fine); the caller names the file, key or option.
"""

from __future__ import annotations

import math

#: controller samples a run may hold (about 16 signals of 8 bytes: 256 MB per run)
MAX_SAMPLES = 2_000_000
#: shortest sample period accepted from a rig file, a data file or the command line [s]
MIN_SAMPLE_PERIOD_S = 1e-6


def period_problem(period_s: float) -> str | None:
    """Why ``period_s`` is no usable sample period, or ``None``."""
    if not (math.isfinite(period_s) and period_s >= MIN_SAMPLE_PERIOD_S):
        return (
            f"must be at least {MIN_SAMPLE_PERIOD_S:g} s (1 MHz), got {period_s:g} s; "
            "give the period with its unit, e.g. {value: 10, unit: ms}"
        )
    return None


def duration_problem(duration_s: float, sample_time_s: float) -> str | None:
    """Why a run of ``duration_s`` at ``sample_time_s`` cannot be simulated, or ``None``."""
    if not (math.isfinite(duration_s) and duration_s > 0):
        return f"must be a positive number of seconds, got {duration_s:g}"
    samples = duration_s / sample_time_s
    if samples < 1:
        return (
            f"{duration_s:g} s is shorter than one controller sample ({sample_time_s:g} s); "
            f"give at least {sample_time_s:g} s"
        )
    if samples > MAX_SAMPLES:
        return (
            f"{duration_s:g} s is {samples:.3g} controller samples of {sample_time_s:g} s, more "
            f"than the {MAX_SAMPLES:,} a run holds in memory; give at most "
            f"{MAX_SAMPLES * sample_time_s:g} s"
        )
    return None


#: the highest TCP port number (0 asks the system for any free port)
MAX_PORT = 65535


def port_problem(port: int) -> str | None:
    """Why ``port`` is no TCP port a server can listen on, or ``None``."""
    if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= MAX_PORT:
        return f"{port!r} is not a port; give a whole number 1-{MAX_PORT} (0: any free port)"
    return None
