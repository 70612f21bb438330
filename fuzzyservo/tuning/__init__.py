"""Tuning studies: a study spec, the trial objective, and the Optuna runner (the only optuna user)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from fuzzyservo.rig import Rig
    from fuzzyservo.tuning.runner import Outcome
    from fuzzyservo.tuning.spec import StudySpec

#: the shipped study the README's first command runs: `tune`'s default, the one the
#: designer opens first, and the uncertainty `robustness` samples by default
MAIN_STUDY = "dinca_robust"


def tune(
    study: StudySpec | str | Path,
    out_dir: str | Path | None = None,
    *,
    trials: int | None = None,
    workers: int = 1,
    rig: Rig | None = None,
    progress: bool = True,
) -> Outcome:
    """Run (or resume) a study: a :class:`StudySpec` built in code or a study file.

    Results and the Optuna storage go to ``out_dir`` (default ``out/<study name>``);
    ``rig`` tunes on a rig built in code instead of the study's rig file (one worker).
    Write the report with :func:`fuzzyservo.tuning.report.write_outputs`.
    """
    from fuzzyservo.tuning.runner import run_study

    if not hasattr(study, "parameters"):
        from fuzzyservo.io.studies import load_study

        study = load_study(study)
    out = Path(out_dir) if out_dir is not None else Path("out") / study.name
    return run_study(study, out, trials=trials, workers=workers, progress=progress, rig=rig)


__all__ = ["tune"]
