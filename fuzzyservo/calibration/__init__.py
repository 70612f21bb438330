"""Calibration against measured data: replay, residual analysis, effect candidates."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from fuzzyservo.calibration.search import Outcome
    from fuzzyservo.controllers.base import Controller
    from fuzzyservo.measured import Measured
    from fuzzyservo.rig import Rig


def calibrate(
    rig: Rig,
    data: Measured | str | Path | Sequence[Measured | str | Path],
    controller: Controller | None = None,
    *,
    effects: Sequence[str] | None = None,
    max_effects: int = 2,
    per_record: Sequence[str] = (),
    workers: int = 1,
) -> Outcome:
    """Fit ``rig`` to measured ``data`` (a :class:`Measured` or a data file): its unknowns
    (``fit: [lower, upper]``), then up to ``max_effects`` effects of the library.

    A list of records is calibrated together (calibration/joint.py): effects and unknowns
    shared, the unknowns named in ``per_record`` (rig-file keys) fitted per record.
    ``workers`` > 1 fits each round's candidates in that many processes.

    With a ``controller`` the data's reference drives the closed loop; without, its
    recorded valve input drives the plant. Write the report and the calibrated rig
    file with :func:`fuzzyservo.calibration.report.write_outputs`.
    """
    from fuzzyservo.calibration.joint import joint_replay, per_record_fields
    from fuzzyservo.calibration.replay import make_replay
    from fuzzyservo.calibration.search import calibrate as search
    from fuzzyservo.io.measured import read_rig_data

    several = isinstance(data, Sequence) and not isinstance(data, str)
    records = [
        d if hasattr(d, "signals") else read_rig_data(d, rig.measured)
        for d in (data if several else [data])
    ]
    replays = [make_replay(rig, d, controller) for d in records]
    fields = per_record_fields(rig, per_record)
    replay = joint_replay(replays, rig, fields) if several or fields else replays[0]
    return search(replay, rig, effects=effects, max_effects=max_effects, workers=workers)


__all__ = ["calibrate"]
