"""Calibration against measured data: replay, residual analysis, effect candidates."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

from fuzzyservo.calibration.null import DRAWS
from fuzzyservo.calibration.run import Calibration, CalibrationResult, conclude, prepare

if TYPE_CHECKING:
    from fuzzyservo.controllers.base import Controller
    from fuzzyservo.measured import Measured
    from fuzzyservo.rig import Rig


def calibrate(
    rig: Rig,
    data: Measured | Sequence[Measured],
    controller: Controller | None = None,
    *,
    effects: Sequence[str] | None = None,
    max_effects: int = 2,
    per_record: Sequence[str] = (),
    workers: int = 1,
    cluster: str | None = None,
    progress: Callable[[str], object] | None = None,
    bootstrap_draws: int = DRAWS,
    segments: bool = False,
) -> CalibrationResult:
    """Fit ``rig`` to measured ``data`` (a :class:`Measured`; read a data file with
    :func:`fuzzyservo.io.measured.read_rig_data`): its unknowns
    (``fit: [lower, upper]``), then up to ``max_effects`` effects of the library.

    A list of records is calibrated together (calibration/joint.py): effects and unknowns
    shared, the unknowns named in ``per_record`` (rig-file keys) fitted per record.
    ``workers`` > 1 fits each round's candidates in that many processes, ``cluster`` (a
    Dask scheduler, ``tcp://HOST:PORT``) on its workers: the same result either way.

    Each round adds its best candidate only when it passes the held-out test at a
    threshold calibrated on ``bootstrap_draws`` surrogate records of its own residual
    (model error included; calibration/null.py) and matters (its contribution and size
    against the residual level and its detection limit); the result states the
    false-positive rate on the record, negligible effects and candidates not established.

    ``segments``: fit, test and size the effects on segments of the record, each
    restarted from the state the record shows at its start (calibration/segments.py),
    where a whole-record replay is chaotic (friction holding a piston); the overlays
    and fit % still replay the whole record.

    With a ``controller`` the data's reference drives the closed loop; without, its
    recorded valve input drives the plant. Print the result, or write the report and
    the calibrated rig file with :func:`fuzzyservo.io.calibration_report.write_calibration`.
    """
    setup = prepare(rig, data, controller, effects=effects, per_record=per_record,
                    segments=segments)  # fmt: skip
    return setup.run(max_effects=max_effects, workers=workers, cluster=cluster,
                     progress=progress, bootstrap_draws=bootstrap_draws)  # fmt: skip


__all__ = ["Calibration", "CalibrationResult", "calibrate", "conclude", "prepare"]
