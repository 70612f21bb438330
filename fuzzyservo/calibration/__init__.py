"""Calibration against measured data: replay, residual analysis, effect candidates."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from fuzzyservo.calibration.search import Outcome
    from fuzzyservo.controllers.base import Controller
    from fuzzyservo.io.measured import Measured
    from fuzzyservo.rig import Rig


def calibrate(
    rig: Rig,
    data: Measured | str | Path,
    controller: Controller | None = None,
    *,
    effects: Sequence[str] | None = None,
    max_effects: int = 2,
) -> Outcome:
    """Fit ``rig`` to measured ``data`` (a :class:`Measured` or a data file): its unknowns
    (``fit: [lower, upper]``), then up to ``max_effects`` effects of the library.

    With a ``controller`` the data's reference drives the closed loop; without, its
    recorded valve input drives the plant. Write the report and the calibrated rig
    file with :func:`fuzzyservo.calibration.report.write_outputs`.
    """
    from fuzzyservo.calibration.replay import make_replay
    from fuzzyservo.calibration.search import calibrate as search

    if not hasattr(data, "signals"):
        from fuzzyservo.io.measured import read_rig_data

        data = read_rig_data(data, rig.measured)
    replay = make_replay(rig, data, controller)
    return search(replay, rig, effects=effects, max_effects=max_effects)


__all__ = ["calibrate"]
