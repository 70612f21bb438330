"""Measured data checked against the rig before a replay: the mistakes that read as
numbers but are not the rig's (a unit one decade off, a time base in ms under an ``s``
header, a stuck sensor, a missing output).

Each check raises :class:`~fuzzyservo.errors.DataError` with one line naming the file,
the column, what is implausible and the fix; none of them fits or simulates anything.
"""

from __future__ import annotations

import numpy as np

from fuzzyservo.errors import DataError
from fuzzyservo.measured import Measured
from fuzzyservo.rig import Rig

#: the data's sample period may lie within these factors of the rig's controller period
PERIOD_RATIO = (1e-3, 50.0)
#: a position may pass the stroke ends by this fraction of the stroke (sensor offset, noise)
STROKE_MARGIN = 0.1


def check_against_rig(rig: Rig, data: Measured, compared: dict[str, str]) -> None:
    """Raise :class:`DataError` when ``data`` cannot be a record of ``rig``.

    ``compared`` maps the data's channels to the model signals they are compared with.
    """
    source = data.source
    if "y" not in data.signals and rig.output not in data.signals:
        found = ", ".join(data.columns.values()) or ", ".join(data.signals)
        raise DataError(
            f"{source}: no y column (found {found}): the replay compares the rig's output "
            f"{rig.output!r} with it; add it as y_<unit> (or {rig.output}_<unit>) or map one "
            "under the rig file's measured: columns"
        )
    _check_time_base(rig, data)
    for channel in compared:
        _check_not_stuck(data, channel)
    stroke = getattr(rig.params, "stroke_limits_m", None)
    if stroke is not None and compared.get("y") == "y":
        _check_range(data, "y", *stroke, "the rig's stroke")
    supply = rig.scales().pressure  # the supply above the tank [Pa]; NaN when unknown
    if np.isfinite(supply):
        for channel, signal in compared.items():
            if data.units.get(channel) == "Pa" and signal != "y":
                _check_pressure(data, channel, supply)


def _column(data: Measured, signal: str) -> str:
    return data.columns.get(signal, f"column {signal!r}")


def _check_time_base(rig: Rig, data: Measured) -> None:
    ratio = data.sample_period_s / rig.sample_time_s
    lo, hi = PERIOD_RATIO
    if lo <= ratio <= hi:
        return
    hint = "in ms, name it t_ms" if ratio > hi else "in s, name it t_s"
    raise DataError(
        f"{data.source}: {_column(data, 't')}: samples {data.sample_period_s:.4g} s apart, "
        f"{ratio:.3g} times the rig's {rig.sample_time_s:.4g} s controller period; check the "
        f"time unit (if the stamps are {hint}), or give measured: sample_period in the rig file"
    )


def _check_not_stuck(data: Measured, channel: str) -> None:
    values = data.signals[channel]
    if np.ptp(values) == 0.0:
        raise DataError(
            f"{data.source}: {_column(data, channel)}: holds the one value {values[0]:.6g} "
            f"{data.units[channel]} for the whole record, a stuck or unplugged sensor; check "
            "the logging, or delete the column to leave it out of the comparison"
        )


def _check_range(data: Measured, channel: str, lo: float, hi: float, what: str) -> None:
    values = data.signals[channel]
    margin = STROKE_MARGIN * (hi - lo)
    low, high = float(values.min()), float(values.max())
    if lo - margin <= low and high <= hi + margin:
        return
    factor = max(high, -low) / max(abs(hi), abs(lo))
    raise DataError(
        f"{data.source}: {_column(data, channel)}: spans {low:.4g} .. {high:.4g} m but "
        f"{what} is {lo:.4g} .. {hi:.4g} m ({factor:.3g} times its end); check the unit in "
        "the column name (values in mm under a cm header read 10 times too large)"
    )


def _check_pressure(data: Measured, channel: str, supply_pa: float) -> None:
    values = data.signals[channel]
    peak = float(np.abs(values).max())
    if 1e-3 * supply_pa <= peak <= 3.0 * supply_pa:
        return
    raise DataError(
        f"{data.source}: {_column(data, channel)}: peaks at {peak:.4g} Pa against the rig's "
        f"{supply_pa:.4g} Pa ({supply_pa / 1e5:.4g} bar) supply; check the unit in the column "
        "name (bar under a Pa header reads 100 000 times too small)"
    )
