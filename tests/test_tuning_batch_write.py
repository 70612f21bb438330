"""A batch written in one transaction (fuzzyservo/tuning/batch_write.py) reads back from
Optuna exactly as the same trials written by Optuna's own ``Study.add_trials``: the
reference is Optuna itself, on the same SQLite file, for every kind of value the
encoder handles (±inf values, NaN and infinite intermediate values, integer, log and
categorical parameters, nested attributes, two objectives)."""

from __future__ import annotations

import math
import os
import uuid

import optuna
import pytest
from optuna.distributions import CategoricalDistribution, FloatDistribution, IntDistribution
from optuna.trial import TrialState, create_trial

from fuzzyservo.tuning.batch_write import BatchWriter
from fuzzyservo.tuning.storage import _storage


def _trials(objectives: int) -> list:
    dists = {"gain": FloatDistribution(0.1, 10.0, log=True), "terms": IntDistribution(3, 9),
             "form": CategoricalDistribution(["p", "pd", None]), "x": FloatDistribution(-1, 1)}  # fmt: skip
    values = [0.5, math.inf, -math.inf, 1e300, 0.0]
    out = []
    for k, v in enumerate(values):
        out.append(create_trial(
            state=TrialState.PRUNED if k == 3 and objectives == 1 else TrialState.COMPLETE,
            values=None if k == 3 and objectives == 1 else [v, -v][:objectives],
            params={"gain": 0.3 + k, "terms": 3 + k, "form": ["p", "pd", None][k % 3],
                    "x": -0.25 * k},
            distributions=dists,
            user_attrs={"status": "ok", "metrics": {"iae": 0.1 * k, "rise_time_s": None},
                        "sample_values": [1.0, None, 2.5], "batch": [k - k % 4, 4]},
            system_attrs={"constraints": [0.1 * k, -1.0]},
            intermediate_values={2: 1.5, 5: math.nan, 7: math.inf} if k == 3 else {},
        ))  # fmt: skip
    return out


def _read(url: str, name: str) -> list[dict]:
    study = optuna.load_study(study_name=name, storage=_storage(url))
    rows = []
    for t in study.get_trials():
        row = dict(vars(t))
        del row["_trial_id"]
        row["intermediate_values"] = {k: repr(v) for k, v in t.intermediate_values.items()}
        rows.append(row)
    return rows


def _url(backend: str, tmp_path) -> str:
    if backend == "sqlite":
        return f"sqlite:///{tmp_path / 'w.db'}"
    url = os.environ.get("FUZZYSERVO_TEST_POSTGRES_URL")
    if not url:
        pytest.skip("no PostgreSQL server: set FUZZYSERVO_TEST_POSTGRES_URL (.ci/run does)")
    pytest.importorskip("psycopg2", reason="the [postgres] extra is not installed")
    return url


@pytest.mark.parametrize("backend", ["sqlite", "postgresql"])
@pytest.mark.parametrize("objectives", [1, 2])
def test_one_transaction_reads_back_like_optunas_add_trials(tmp_path, objectives, backend):
    url = _url(backend, tmp_path)
    ours_name, theirs_name = (f"{who}-{uuid.uuid4().hex}" for who in ("ours", "theirs"))
    directions = ["minimize"] * objectives
    ours = optuna.create_study(study_name=ours_name, storage=_storage(url), directions=directions)
    theirs = optuna.create_study(
        study_name=theirs_name, storage=_storage(url), directions=directions
    )
    trials = _trials(objectives)
    writer = BatchWriter(ours)
    assert writer.direct, "the storage's schema is not one batch_write.SCHEMAS names"
    writer.write(trials[:2], ("storage_s", 0.25))
    writer.write(trials[2:], ("storage_s", 0.5))
    theirs.add_trials(trials)
    assert _read(url, ours_name) == _read(url, theirs_name)
    assert optuna.load_study(study_name=ours_name, storage=_storage(url)).user_attrs == {
        "storage_s": 0.5
    }


def test_other_storages_go_through_add_trials():
    study = optuna.create_study()  # in memory: no RDB schema to write
    writer = BatchWriter(study)
    assert not writer.direct
    writer.write(_trials(1)[:2], ("storage_s", 1.0))
    assert [t.params["terms"] for t in study.get_trials()] == [3, 4]
    assert study.user_attrs == {"storage_s": 1.0}
