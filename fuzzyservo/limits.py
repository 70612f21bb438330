"""Sizes refused before any work starts, each a stated limit in one place.

A closed-loop run keeps every controller sample of every signal in memory, so its
length is bounded, and so is a measured record's (it is replayed as a run); a sample
period below a microsecond is no controller or logger (and a subnormal one overflows the
step count). A fuzzy variable's universe samples, an exported lookup table and a YAML
file's nesting and aliases are bounded too: each would otherwise let a few bytes of input
ask for gigabytes; a port is 0-65535. Each check returns the problem as text (``None`` when fine); the
caller names the file, key or option.
"""

from __future__ import annotations

import math

from fuzzyservo.errors import excerpt

#: controller samples a run may hold (about 16 signals of 8 bytes: 256 MB per run)
MAX_SAMPLES = 2_000_000
#: shortest sample period accepted from a rig file, a data file or the command line [s]
MIN_SAMPLE_PERIOD_S = 1e-6
#: samples (rows of a CSV, elements of a .mat vector) a measured record may hold: a replay
#: runs the record, so it holds no more than a run
MAX_RECORD_SAMPLES = MAX_SAMPLES
#: universe samples of a fuzzy variable (``points``): a two-input controller's coverage
#: check visits points² input pairs when it is built (5,000: 8 s, 250 MB)
MAX_POINTS = 5_000
#: output samples of the exact semantics (``sample_points``): each evaluation visits them
#: once per rule (a reference evaluation may use 20,001)
MAX_SAMPLE_POINTS = 100_000
#: plants sampled from a study's ``uncertainty:`` (its ``samples``, ``robustness --samples``,
#: ``tune --check-samples``): every draw is held in memory and every trial runs them all
MAX_PLANT_SAMPLES = 100_000
#: entries of an exported lookup table (``--lut N``: N per input, N² for two inputs)
MAX_LUT_ENTRIES = 65_536
#: nesting of a YAML file (a rig nests about 6 levels deep)
MAX_YAML_DEPTH = 100
#: nodes a YAML file may expand to through its aliases (``*name``): this many times the
#: nodes written in it, ...
YAML_ALIAS_FACTOR = 10
#: ... and at least this many (a short file that repeats a block by alias)
YAML_ALIAS_FLOOR = 10_000


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


def points_problem(points: object, default: int = 201, most: int = MAX_POINTS) -> str | None:
    """Why ``points`` (a number, or the text of a ``.fis``/FCL setting) is no usable number
    of universe samples (``default`` when not given; ``most``: ``MAX_SAMPLE_POINTS`` for
    output samples), or ``None``."""
    value = points
    if isinstance(points, str):  # text: digits only (a 5,000-digit one is no int to parse)
        value = int(points) if points.isascii() and points.isdigit() and len(points) <= 18 else None
    if (
        isinstance(value, int | float)
        and not isinstance(value, bool)
        and math.isfinite(value)
        and value == int(value)
        and 3 <= value <= most
    ):
        return None
    if isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value):
        shown = _count(int(value)) if value == int(value) else f"{value:g}"
    else:
        shown = excerpt(points)
    return f"must be a whole number from 3 to {most:,}, got {shown}; {default} is the default"


def lut_problem(n: int, inputs: int) -> str | None:
    """Why a lookup table of ``n`` points per input over ``inputs`` inputs is refused, or ``None``."""
    most = round(MAX_LUT_ENTRIES ** (1 / inputs))
    if 2 <= n <= most:
        return None
    if n < 2:
        return f"needs at least 2 points per input, got {_count(n)}"
    return (
        f"{_count(n)} points per input make a table of more than the {MAX_LUT_ENTRIES:,} "
        f"entries allowed; give at most {most:,} for {inputs} input(s)"
    )


def plant_samples_problem(samples: int) -> str | None:
    """Why drawing ``samples`` plants is refused (too many), or ``None``."""
    if samples <= MAX_PLANT_SAMPLES:
        return None
    return (
        f"{_count(samples)} sampled plants are more than the {MAX_PLANT_SAMPLES:,} a run draws (each "
        "held in memory, each trial runs them all); give fewer"
    )


def record_problem(samples: int) -> str | None:
    """Why a measured record of ``samples`` samples is too long, or ``None``."""
    if samples <= MAX_RECORD_SAMPLES:
        return None
    return (
        f"more than the {MAX_RECORD_SAMPLES:,} samples a record may hold (a replay runs it in "
        "memory); split the file into shorter records or downsample it"
    )


def _count(n: int) -> str:
    """A whole number for a message: with thousands separators, or its length when absurd."""
    return f"{n:,}" if abs(n) < 10**18 else f"a {len(str(abs(n)))}-digit number"
