"""Where a study is stored and opening it there: the storage URL (``--storage``, the study
file's, else SQLite in the output folder), the Optuna RDB storage (SQLite tuned for many
small commits, PostgreSQL through psycopg2), one-line errors for a storage that cannot be
opened or used, :func:`open_study`, which creates or loads the study (retrying while
another process creates it), checks its definition and gives it its sampler, and
:func:`read_trials`, which reads a stored study's best trials without changing it."""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

from fuzzyservo.errors import ConfigError, require
from fuzzyservo.tuning.integrity import check_definition, per_trial_seeded
from fuzzyservo.tuning.samplers import make_sampler
from fuzzyservo.tuning.spec import Study
from fuzzyservo.tuning.study_trials import trial_counts

HEARTBEAT_S = 5
GRACE_S = 15


def storage_url(spec: Study, out_dir: Path, override: str | None = None) -> str:
    """``--storage`` wins, then the study file's ``storage``, then SQLite in the output folder."""
    if override:
        return override
    if spec.storage:
        return spec.storage
    return f"sqlite:///{(out_dir / f'{spec.name}.db').resolve()}"


def driver_url(url: str) -> str:
    """``postgresql://`` names the psycopg2 driver we ship (SQLAlchemy 2.1 would pick psycopg 3)."""
    for prefix in ("postgresql://", "postgres://"):
        if url.startswith(prefix):
            return "postgresql+psycopg2://" + url[len(prefix) :]
    return url


def _storage(url: str):
    import optuna

    if url.startswith("sqlite"):
        # several local workers share the file: wait for the lock rather than fail
        kwargs = {"connect_args": {"timeout": 60}}
    else:
        require("psycopg2", "postgres", "a PostgreSQL storage")
        kwargs = {"pool_pre_ping": True}
    storage = optuna.storages.RDBStorage(
        driver_url(url), engine_kwargs=kwargs, heartbeat_interval=HEARTBEAT_S, grace_period=GRACE_S
    )
    if url.startswith("sqlite"):
        _fast_sqlite(storage.engine)
    return storage


def _fast_sqlite(engine) -> None:
    """Write-ahead log and no fsync per commit: a trial makes some 30 small commits, each
    about 10 ms with the default rollback journal (a third of a robust trial's own time).
    A power cut may lose the last trials, never corrupt the file; a killed process loses
    nothing."""
    from sqlalchemy import event

    def pragmas(dbapi_connection, record) -> None:
        cursor = dbapi_connection.cursor()
        cursor.execute("PRAGMA journal_mode=WAL")
        cursor.execute("PRAGMA synchronous=NORMAL")
        cursor.close()

    event.listen(engine, "connect", pragmas)
    engine.dispose()  # connections opened while creating the tables get the pragmas too


def storage_error(url: str, exc: BaseException) -> ConfigError:
    """One line for a storage that cannot be opened or used (``exc``: what the database
    driver, SQLAlchemy or Optuna raised): a SQLite file that is no database or a damaged
    one, or a server or URL that does not answer; each with its fix."""
    import sqlite3

    cause = exc
    while cause.__cause__ is not None:  # Optuna's StorageInternalError wraps SQLAlchemy's
        cause = cause.__cause__
    cause = getattr(cause, "orig", None) or cause  # SQLAlchemy's wraps the driver's
    reason = (str(cause).strip().splitlines() or [type(cause).__name__])[0]
    garbled = isinstance(cause, sqlite3.DatabaseError) and not isinstance(
        cause, sqlite3.OperationalError
    )
    if garbled:
        return ConfigError(
            f"storage {url}: not an Optuna study database, or a damaged one ({reason}); move "
            "the file away (the study then starts afresh) or give another --storage"
        )
    return ConfigError(
        f"storage {url}: cannot open or use it ({reason}); check that the server runs and the URL "
        "(--storage or the study's storage key), or leave it out for SQLite in the output folder"
    )


def storage_faults() -> tuple[type[BaseException], ...]:
    """What a storage raises when its database is damaged or gone while in use."""
    import optuna
    from sqlalchemy.exc import SQLAlchemyError

    return (optuna.exceptions.StorageInternalError, SQLAlchemyError)


def open_study(spec: Study, url: str, worker: int = 0, *, shared: bool = False):
    """Create or load the study, check that it was made by this definition
    (:func:`~fuzzyservo.tuning.integrity.check_definition`: a :class:`ConfigError` naming
    what changed otherwise), and give it a sampler seeded per trial
    (:func:`~fuzzyservo.tuning.integrity.per_trial_seeded`: no two trials, in any process,
    replay one random stream). ``worker`` and ``shared`` are kept for callers; the trial
    number alone decides the seed."""
    import random
    import warnings

    import optuna
    from sqlalchemy.exc import IntegrityError, OperationalError, ProgrammingError, SQLAlchemyError

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    # the storage heartbeat is what fails trials of a killed process; it is marked experimental
    warnings.filterwarnings("ignore", category=optuna.exceptions.ExperimentalWarning)
    # CMA-ES samples without the constraints (docs/samplers.md: it finds feasible bests anyway)
    warnings.filterwarnings("ignore", "Constraints have been set, but CmaEsSampler", UserWarning)
    directions = ["minimize"] * spec.objective.n_values
    for attempt in range(5):
        try:
            storage = _storage(url)
            study = optuna.create_study(
                study_name=spec.name,
                storage=storage,
                directions=directions,
                load_if_exists=True,
            )
            break
        except (
            IntegrityError,
            ProgrammingError,
            OperationalError,
            optuna.exceptions.DuplicatedStudyError,
        ) as exc:
            # two processes creating the tables or the study at once on an empty database
            if attempt == 4:
                raise storage_error(url, exc) from None
            time.sleep(0.2 + random.random())
        except (SQLAlchemyError, ImportError, optuna.exceptions.StorageInternalError) as exc:
            raise storage_error(url, exc) from None  # a driver or URL we cannot use, damage
    check_definition(study, spec, url)
    study.sampler = per_trial_seeded(make_sampler(spec, spec.seed), spec.seed)
    return study


@dataclass(frozen=True)
class StoredTrial:
    """A complete trial of a stored study: number, objective values, parameters, status."""

    number: int
    values: tuple[float, ...]
    params: dict[str, float]
    status: str


@dataclass(frozen=True)
class StoredTrials:
    """A stored study's best complete trials (ok ones first, then by objective), how many
    trials completed, and the trial counts by state (:func:`trial_counts`)."""

    best: tuple[StoredTrial, ...]
    complete: int
    counts: dict[str, int]


def read_trials(
    name: str, url: str, *, sqlite_file: Path | None = None, top: int = 10
) -> StoredTrials:
    """The ``top`` best complete trials of study ``name`` at ``url``; a SQLite database
    ``sqlite_file`` is opened read-only (looking at a study never changes it). A storage
    without that study, or that cannot be opened, is a one-line :class:`ConfigError`."""
    optuna = require("optuna", "tune", "reading a study")
    from optuna.exceptions import OptunaError
    from optuna.trial import TrialState
    from sqlalchemy.exc import SQLAlchemyError

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    if sqlite_file is not None:
        from urllib.parse import quote

        opened = f"sqlite:///file:{quote(str(sqlite_file))}?mode=ro&uri=true"
    else:
        opened = driver_url(url)
    try:
        loaded = optuna.load_study(study_name=name, storage=opened)
    except KeyError:
        raise ConfigError(f"the storage holds no study named {name!r}", file=url) from None
    except (SQLAlchemyError, OptunaError, ValueError, ImportError) as exc:
        first = str(exc).strip().splitlines()[0][:120] if str(exc).strip() else type(exc).__name__
        raise ConfigError(
            f"cannot open the storage ({first}); check that it is a study database "
            "(fuzzyservo tune writes one) and that its server runs",
            file=url,
        ) from None
    trials = loaded.get_trials(deepcopy=False, states=(TrialState.COMPLETE,))
    ranked = sorted(trials, key=lambda t: (t.user_attrs.get("status", "ok") != "ok", t.values[0]))
    best = tuple(
        StoredTrial(t.number, tuple(t.values), dict(t.params), t.user_attrs.get("status", "?"))
        for t in ranked[:top]
    )
    return StoredTrials(best, len(trials), trial_counts(loaded))
