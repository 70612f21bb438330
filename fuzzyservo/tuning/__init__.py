"""Tuning studies: a typed study, the trial objective, and the Optuna runner (the only optuna user).

A study is a :class:`~fuzzyservo.tuning.spec.Study`, built in Python or read from a study
file by :func:`fuzzyservo.io.studies.load_study`; :func:`tune` runs or resumes it and
:func:`fuzzyservo.workflows.write_study_report` writes its report.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from fuzzyservo.rig import Rig
    from fuzzyservo.tuning.outcome import StudyOutcome
    from fuzzyservo.tuning.spec import Study

#: the shipped study the README's first command runs: `tune`'s default, the one the
#: designer opens first, and the uncertainty `robustness` samples by default
MAIN_STUDY = "dinca_robust"


def tune(
    study: Study,
    out_dir: str | Path | None = None,
    *,
    trials: int | None = None,
    workers: int = 1,
    rig: Rig | None = None,
    storage: str | None = None,
    progress: bool = True,
    cluster: str | None = None,
    batch_size: int | None = None,
    asynchronous: bool = False,
) -> StudyOutcome:
    """Run (or resume: finished trials are kept, only the rest run) a :class:`Study`.

    The Optuna storage is ``storage`` (an SQLAlchemy URL: ``sqlite:///path.db``,
    ``postgresql://…``), else the study's ``storage``, else SQLite in ``out_dir`` (default
    ``out/<study name>``); ``rig`` tunes on another rig than the study's own. Write the
    report with :func:`fuzzyservo.workflows.write_study_report`.

    Trials are asked ``batch_size`` at a time (default: the study's) and scored by
    ``workers`` local processes or on the Dask ``cluster`` (``tcp://HOST:PORT``): the
    same result either way. ``asynchronous``: Optuna's own loop in each worker on the
    shared storage instead (several commands or machines on one study; not reproducible).
    """
    from fuzzyservo.tuning.runner import run_study

    out = Path(out_dir) if out_dir is not None else Path("out") / study.name
    return run_study(
        study, out, trials=trials, storage=storage, workers=workers, progress=progress, rig=rig,
        cluster=cluster, batch_size=batch_size, asynchronous=asynchronous,
    )  # fmt: skip


__all__ = ["tune"]
