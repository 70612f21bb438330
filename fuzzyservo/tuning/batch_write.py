"""A told batch of trials into an Optuna RDB storage in one transaction.

The pipelined runner (:func:`~fuzzyservo.tuning.pipeline.run_pipelined`) keeps its
study in memory and stores each batch once it is told. Optuna's ``Study.add_trials``
writes a trial in some 45 ORM statements (every parameter and attribute is looked up and
upserted one at a time) and a transaction per trial: 15-30 ms a trial, a third of the
robust study's wall time on 2 cores, while the workers wait. A finished trial needs
none of those look-ups: :class:`BatchWriter` inserts the batch's rows (trial, values,
parameters, attributes, intermediate values, and the study's ``storage_s`` figure) with
SQLAlchemy Core in one transaction, so a batch is stored whole or not at all.

The rows are Optuna's RDB schema, read from the database itself (reflected) and encoded
as Optuna encodes them (states and value types by name, ±inf and NaN as a type with no
value, datetimes as naive UTC, attributes as JSON). Only on a schema version written
here (:data:`SCHEMAS`); on any other, and on a storage that is no RDB, the writer falls
back to ``Study.add_trials``. A test stores the same trials both ways and compares what
Optuna reads back (tests/test_tuning_batch_write.py).
"""

from __future__ import annotations

import datetime
import json
import math
from typing import Any

#: Optuna RDB schema versions whose tables this module writes (Optuna 4.x-5.0)
SCHEMAS = ("v3.2.0.a",)
_TABLES = (
    "trials",
    "trial_values",
    "trial_params",
    "trial_user_attributes",
    "trial_system_attributes",
    "trial_intermediate_values",
    "study_user_attributes",
)


class BatchWriter:
    """Stores finished trials of ``study`` (an Optuna study on any storage) a batch at a
    time, with the study's user attribute ``figure`` (name, value) in the same write."""

    def __init__(self, study):
        from optuna.storages import RDBStorage

        self.study = study
        backend = getattr(study._storage, "_backend", study._storage)  # under Optuna's cache
        self._engine = None
        if isinstance(backend, RDBStorage) and backend.get_current_version() in SCHEMAS:
            import sqlalchemy as sa

            self._engine = backend.engine
            metadata = sa.MetaData()
            metadata.reflect(self._engine, only=list(_TABLES))
            self._tables = metadata.tables

    @property
    def direct(self) -> bool:
        """Whether batches go in one transaction (else through ``Study.add_trials``)."""
        return self._engine is not None

    def n_trials(self) -> int:
        """The study's trials in the storage, by one count (Optuna's cached storage would
        read every trial written since it last looked)."""
        if self._engine is None:
            return self.study._storage.get_n_trials(self.study._study_id)
        with self._engine.connect() as db:
            return self._count(db)

    def _count(self, db) -> int:
        import sqlalchemy as sa

        trials = self._tables["trials"]
        query = sa.select(sa.func.count()).select_from(trials)
        return db.execute(query.where(trials.c.study_id == self.study._study_id)).scalar_one()

    def write(self, trials: list, figure: tuple[str, Any] | None = None) -> None:
        """Store ``trials`` (finished, in number order) after the study's last trial."""
        if self._engine is None:
            self.study.add_trials(trials)
            if figure is not None:
                self.study.set_user_attr(*figure)
            return
        t = self._tables
        study_id = self.study._study_id
        with self._engine.begin() as db:
            number = self._count(db)
            for k, trial in enumerate(trials):
                self._insert(db, trial, study_id, number + k)
            if figure is not None:
                attrs = t["study_user_attributes"]
                key, value = figure
                db.execute(
                    attrs.delete().where(attrs.c.study_id == study_id).where(attrs.c.key == key)
                )
                db.execute(attrs.insert().values(study_id=study_id, key=key,
                                                 value_json=json.dumps(value)))  # fmt: skip

    def _insert(self, db, trial, study_id: int, number: int) -> None:
        from optuna.distributions import distribution_to_json

        if not trial.state.is_finished():
            raise ValueError(f"trial {trial.number}: only finished trials are written, "
                             f"got state {trial.state.name}")  # fmt: skip
        t = self._tables
        row = {"number": number, "study_id": study_id, "state": trial.state.name,
               "datetime_start": _utc(trial.datetime_start),
               "datetime_complete": _utc(trial.datetime_complete)}  # fmt: skip
        trial_id = db.execute(t["trials"].insert().values(**row)).inserted_primary_key[0]
        values = [
            {"trial_id": trial_id, "objective": k, **_value(v, "value", "value_type")}
            for k, v in enumerate(trial.values or ())
        ]
        params = [
            {"trial_id": trial_id, "param_name": name,
             "param_value": trial.distributions[name].to_internal_repr(value),
             "distribution_json": distribution_to_json(trial.distributions[name])}
            for name, value in trial.params.items()
        ]  # fmt: skip
        steps = [
            {"trial_id": trial_id, "step": step,
             **_value(v, "intermediate_value", "intermediate_value_type")}
            for step, v in trial.intermediate_values.items()
        ]  # fmt: skip
        for table, rows in (
            ("trial_values", values),
            ("trial_params", params),
            ("trial_user_attributes", _attrs(trial_id, trial.user_attrs)),
            ("trial_system_attributes", _attrs(trial_id, trial.system_attrs)),
            ("trial_intermediate_values", steps),
        ):
            if rows:
                db.execute(t[table].insert(), rows)


def _utc(moment: datetime.datetime | None) -> datetime.datetime | None:
    """Optuna's RDB stores naive UTC (FrozenTrial holds naive local time)."""
    if moment is None:
        return None
    return moment.astimezone(datetime.UTC).replace(tzinfo=None)


def _value(value: float, column: str, kind: str) -> dict[str, Any]:
    """A float as Optuna's RDB stores it: ±inf and NaN as a type with no number."""
    if math.isnan(value):
        return {column: None, kind: "NAN"}
    if math.isinf(value):
        return {column: None, kind: "INF_POS" if value > 0 else "INF_NEG"}
    return {column: value, kind: "FINITE"}


def _attrs(trial_id: int, attrs: dict[str, Any]) -> list[dict[str, Any]]:
    return [{"trial_id": trial_id, "key": k, "value_json": json.dumps(v)} for k, v in attrs.items()]
