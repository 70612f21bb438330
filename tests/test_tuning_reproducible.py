"""Pipelined studies (issue 26 items 1 and 2, issue 57): the same seeded study gives the same
trials, hence the same best, with one worker, two local worker processes and a real Dask
cluster (a ``dask scheduler`` and two ``dask worker`` processes started here), after a
Dask worker is killed mid-batch, and after the parent is killed (kill -9) and resumed;
and ``calibrate --cluster`` gives the numbers it gives in one process.

The studies are cut down (one short scenario, few trials, few samples): what is checked is
where and in which order trials run, not the objective.
"""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from support import DATA
from test_study_integrity import cheap_copy
from test_tuning_distributed import (
    complete_now,
    finish,
    snapshot,
    sqlite_url,
    start_tune,
    study_copy,
)

from fuzzyservo.cli import main
from fuzzyservo.io.studies import load_study
from fuzzyservo.tuning.runner import run_study
from fuzzyservo.tuning.storage import open_study

pytest.importorskip("distributed", reason="the cluster extra (dask[distributed]) is not installed")

TRIALS = 12  # three times BATCH
BATCH = 4
DASK = Path(sys.executable).with_name("dask")  # the command the cluster extra installs


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _env() -> dict[str, str]:
    env = dict(os.environ)
    root = str(Path(__file__).resolve().parents[1])  # the checkout under test
    env["PYTHONPATH"] = os.pathsep.join(p for p in (root, env.get("PYTHONPATH")) if p)
    env["PYTHONUNBUFFERED"] = "1"
    return env


class LocalCluster:
    """A Dask scheduler and ``workers`` worker processes (one thread each, no nanny: a
    killed worker stays dead), started as separate processes like on separate machines."""

    def __init__(self, tmp_path: Path, workers: int = 2):
        self.address = f"tcp://127.0.0.1:{_free_port()}"
        self.logs = tmp_path
        self.scheduler = self._start("scheduler", "--host", "127.0.0.1",
                                     "--port", self.address.rsplit(":", 1)[1])  # fmt: skip
        self.workers: list[subprocess.Popen] = []
        for _ in range(workers):
            self.add_worker()

    def add_worker(self) -> subprocess.Popen:
        """One more worker process; returns once the scheduler counts it."""
        from distributed import Client

        n = len(self.workers)
        self.workers.append(self._start(f"worker{n}", self.address, "--nthreads", "1",
                                        "--no-nanny", "--memory-limit", "0", "--name", f"w{n}"))  # fmt: skip
        with Client(self.address, timeout=60) as client:
            client.wait_for_workers(len([w for w in self.workers if w.poll() is None]), timeout=120)
        return self.workers[-1]

    def _start(self, what: str, *args: str) -> subprocess.Popen:
        command = "scheduler" if what == "scheduler" else "worker"
        log = open(self.logs / f"dask_{what}.log", "w")  # closed with the process
        return subprocess.Popen(
            [str(DASK), command, *args, "--no-dashboard"],
            env=_env(), stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
        )  # fmt: skip

    def close(self) -> None:
        for proc in [*self.workers, self.scheduler]:
            if proc.poll() is None:
                proc.kill()
            proc.wait(timeout=30)


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    c = LocalCluster(tmp_path_factory.mktemp("dask"))
    yield c
    c.close()


def _run(spec, out: Path, **how):
    how.setdefault("batch_size", BATCH)
    outcome = run_study(spec, out, trials=TRIALS, progress=False, **how)
    return outcome, snapshot(outcome.storage_url, spec.name)


def test_same_trials_with_one_two_workers_and_a_dask_cluster(tmp_path, cluster):
    study, _ = cheap_copy(tmp_path, "repro")
    spec = load_study(study)
    one, trials_one = _run(spec, tmp_path / "w1")
    for tag, how in (("w2", {"workers": 2}), ("dask", {"cluster": cluster.address})):
        other, trials = _run(spec, tmp_path / tag, **how)
        assert trials == trials_one, f"{tag}: other trials than with one worker"
        assert other.best_params == one.best_params
        assert other.best.values == one.best.values
    assert len(trials_one) == TRIALS


def _small_robust(tmp_path: Path) -> Path:
    """dinca_robust on 3 samples and the `steps` scenario."""
    study, _ = study_copy(tmp_path, "robust")
    data = yaml.safe_load(study.read_text())
    source = yaml.safe_load((DATA / "studies" / "dinca_robust.yaml").read_text())
    source.update({k: data[k] for k in ("name", "rig", "controller", "baseline")})
    source["scenarios"] = ["steps"]
    source["uncertainty"]["samples"] = 3
    source.pop("workers", None)
    study.write_text(yaml.safe_dump(source, sort_keys=False))
    return study


def test_robust_study_same_best_with_workers_and_a_cluster(tmp_path, cluster):
    spec = load_study(_small_robust(tmp_path))
    one, trials_one = _run(spec, tmp_path / "w1")
    for tag, how in (("w2", {"workers": 2}), ("dask", {"cluster": cluster.address})):
        other, trials = _run(spec, tmp_path / tag, **how)
        assert trials == trials_one, f"{tag}: other trials than with one worker"
        assert other.best_params == one.best_params
        assert other.trials_pruned == one.trials_pruned
        assert other.selection == one.selection  # the top trials on fresh samples too


@pytest.mark.slow
def test_a_killed_dask_worker_loses_no_trial(tmp_path, cluster):
    study, name = cheap_copy(tmp_path, "killw")
    doomed = cluster.add_worker()  # a third worker, killed below
    out = tmp_path / "dask"
    total = 16
    proc = start_tune(study, out, total, "--cluster", cluster.address, "--batch-size", str(BATCH))
    deadline = time.monotonic() + 180
    while complete_now(out / f"{name}.db", name) < BATCH and time.monotonic() < deadline:
        assert proc.poll() is None, proc.stdout.read()
        time.sleep(0.05)
    doomed.send_signal(signal.SIGKILL)  # mid-run: its running task is lost
    code, output = finish(proc, timeout=240)
    assert code == 0, output
    got = snapshot(sqlite_url(out, name), name)
    assert len(got) == total
    local = run_study(load_study(study), tmp_path / "local", trials=total, progress=False,
                      batch_size=BATCH)  # fmt: skip
    assert got == snapshot(local.storage_url, name)


@pytest.mark.slow
def test_parent_killed_and_resumed_ends_like_an_uninterrupted_run(tmp_path):
    study, name = cheap_copy(tmp_path, "killp")
    total = 16
    spec = load_study(study)
    outcome = run_study(spec, tmp_path / "whole", trials=total, progress=False, batch_size=BATCH)
    whole = snapshot(outcome.storage_url, name)
    out = tmp_path / "out"
    proc = start_tune(study, out, total, "--workers", "2", "--batch-size", str(BATCH))
    deadline = time.monotonic() + 180
    while complete_now(out / f"{name}.db", name) < BATCH and time.monotonic() < deadline:
        assert proc.poll() is None, proc.stdout.read()
        time.sleep(0.02)
    proc.send_signal(signal.SIGKILL)
    finish(proc, timeout=30)
    assert len(snapshot(sqlite_url(out, name), name)) < total
    code, output = finish(start_tune(study, out, total, "--batch-size", str(BATCH)))
    assert code == 0, output
    assert snapshot(sqlite_url(out, name), name) == whole


def test_a_batch_killed_while_being_written_is_completed_on_resume(tmp_path):
    """A kill between two trials of one write: the resume asks the stored trials again
    (the same numbers), tells their stored results, and scores only the rest."""
    study, name = cheap_copy(tmp_path, "partial")
    spec = load_study(study)
    outcome, _ = _run(spec, tmp_path / "whole")
    import optuna

    trials = optuna.load_study(study_name=name, storage=outcome.storage_url).get_trials()
    url = sqlite_url(tmp_path, name)
    open_study(spec, url).add_trials(trials[: BATCH + 3])  # a whole batch and 3 of the next
    _run(spec, tmp_path)
    assert snapshot(url, name) == snapshot(outcome.storage_url, name)


def test_a_study_stored_with_another_batch_size_goes_on_from_its_trials(tmp_path):
    """A study stored another way (here with batch_size 2) proposes other numbers when
    asked again with batch_size 4: its stored trials are kept as they are, the study goes
    on from them, and doing so twice gives the same trials."""
    study, name = cheap_copy(tmp_path, "adopted")
    spec = load_study(study)
    runs = []
    for tag in ("a", "b"):
        out = tmp_path / tag
        run_study(spec, out, trials=TRIALS - BATCH, progress=False, batch_size=2)
        before = snapshot(sqlite_url(out, name), name)
        _run(spec, out)
        after = snapshot(sqlite_url(out, name), name)
        assert {k: after[k] for k in before} == before and len(after) == TRIALS
        runs.append(after)
    assert runs[0] == runs[1]
    run_study(spec, tmp_path / "a", trials=BATCH, progress=False)  # holds more: runs none
    assert snapshot(sqlite_url(tmp_path / "a", name), name) == runs[0]


def test_a_resumed_study_counts_each_trial_once(tmp_path):
    """The progress count of a resumed run starts at the stored trials and ends at the
    total: the stored trials the resume asks again are not counted a second time."""
    from fuzzyservo.executor import Inline
    from fuzzyservo.tuning.pipeline import run_pipelined
    from fuzzyservo.tuning.trial_bar import trial_bar

    study, name = cheap_copy(tmp_path, "counted")
    spec = load_study(study)
    run_study(spec, tmp_path, trials=BATCH + 2, progress=False, batch_size=BATCH)
    stored = open_study(spec, sqlite_url(tmp_path, name))
    bar = trial_bar(TRIALS, BATCH + 2, name, False)
    run_pipelined(dataclasses.replace(spec, batch_size=BATCH), stored, TRIALS, Inline(), bar)
    assert bar.n == TRIALS == len(snapshot(sqlite_url(tmp_path, name), name))


def test_cluster_without_dask_names_the_extra(tmp_path, capsys, monkeypatch):
    study, _ = cheap_copy(tmp_path, "nodask")
    monkeypatch.setitem(sys.modules, "distributed", None)  # as if not installed
    code = main(["tune", str(study), "--trials", "2", "--out", str(tmp_path / "o"),
                 "--cluster", "tcp://127.0.0.1:9"])  # fmt: skip
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert "fuzzyservo[cluster]" in err and "\n" not in err, err


def test_robustness_gives_the_same_numbers_on_workers_and_a_cluster(tmp_path, cluster, dinca,
                                                                    flc2, p_k10):  # fmt: skip
    from fuzzyservo.tuning.uncertainty.montecarlo import CHUNK, plan

    study = load_study(DATA / "studies" / "dinca_robust.yaml")
    setup = plan(dinca, [flc2, p_k10], study, samples=CHUNK + 4, scenarios=["steps"])

    def numbers(**how) -> str:  # NaN (an undefined metric) equals itself in JSON
        return json.dumps(setup.run(**how).rows(), default=str)

    here = numbers()
    assert numbers(workers=2) == here
    assert numbers(cluster=cluster.address) == here


def _untimed(found):
    """A summary without its wall times and output paths."""
    if isinstance(found, dict):
        return {k: _untimed(v) for k, v in found.items() if k not in ("seconds", "calibrated_rig")}
    if isinstance(found, list):
        return [_untimed(v) for v in found]
    return found


@pytest.mark.slow
def test_calibrate_gives_the_same_result_on_a_cluster(tmp_path, cluster):
    """``calibrate --cluster`` screens the candidates on the Dask workers: the same
    effects, values and fits as in this process."""
    from test_calibration import DINCA_EFFECTS, dinca_csv, old_loop

    data = dinca_csv(tmp_path / "d.csv", {"coulomb_friction": DINCA_EFFECTS["coulomb_friction"]})
    rig = str(old_loop(tmp_path))

    def summary(tag: str, *how: str) -> dict:
        out = tmp_path / tag
        code = main(["calibrate", rig, str(data), "--controller", "p_k10", "--effects",
                     "coulomb_friction,internal_leakage", "--max-effects", "1",
                     "--out", str(out / "o"), "--json", str(out / "s.json"), *how])  # fmt: skip
        assert code == 0
        return _untimed(json.loads((out / "s.json").read_text()))

    here = summary("here")
    assert [e["name"] for e in here["effects_added"]] == ["coulomb_friction"]
    assert summary("dask", "--cluster", cluster.address) == here
