"""Distributed and interrupted studies: several processes on one PostgreSQL storage, resume
after SIGKILL or Ctrl-C on the default SQLite storage, and same seed -> same result.

The PostgreSQL tests need ``FUZZYSERVO_TEST_POSTGRES_URL`` (``.ci/run`` starts a server with
``.ci/postgres.sh`` and exports it); without a reachable server they skip.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
import uuid
from collections import Counter
from pathlib import Path

import pytest
import yaml
from support import DATA

STUDY = DATA / "studies" / "dinca_flc.yaml"
TUNE = [sys.executable, "-m", "fuzzyservo", "tune"]
URL_ENV = "FUZZYSERVO_TEST_POSTGRES_URL"
RUN_TIMEOUT_S = 120


# --------------------------------------------------------------------------- helpers
def postgres_url() -> str:
    """The test server's URL as a user would give it to ``--storage``, or skip."""
    url = os.environ.get(URL_ENV, "").strip()
    if not url:
        pytest.skip(f"no PostgreSQL server reachable at ${URL_ENV} (unset); .ci/run starts one")
    try:
        _connect(_libpq(url)).close()
    except Exception as exc:  # no driver, OperationalError: the same answer
        why = " ".join(str(exc).split())
        pytest.skip(f"no PostgreSQL server reachable at {url} ({why}); .ci/run starts one")
    return url


def _driver() -> str:
    """The PostgreSQL driver installed: psycopg2 (the project's), else psycopg 3."""
    import importlib.util

    return "psycopg2" if importlib.util.find_spec("psycopg2") else "psycopg"


def _connect(dsn: str):
    if _driver() == "psycopg2":
        import psycopg2

        return psycopg2.connect(dsn, connect_timeout=3)
    import psycopg

    return psycopg.connect(dsn, connect_timeout=3)


def _libpq(url: str) -> str:
    """``postgresql+psycopg2://...`` (SQLAlchemy) -> ``postgresql://...`` (libpq)."""
    scheme, rest = url.split("://", 1)
    return f"{scheme.split('+')[0]}://{rest}"


def _sqlalchemy(url: str) -> str:
    """The URL this module reads the storage with, its driver named: SQLAlchemy >= 2.1 maps a
    bare ``postgresql://`` to psycopg 3, which need not be installed."""
    if url.startswith(("postgresql://", "postgres://")):
        return f"postgresql+{_driver()}://" + url.split("://", 1)[1]
    return url


def study_copy(tmp_path: Path, tag: str) -> tuple[Path, str]:
    """studies/dinca_flc.yaml under a unique name in tmp_path, its files given as absolute paths."""
    from fuzzyservo.io.paths import find_file

    data = yaml.safe_load(STUDY.read_text(encoding="utf-8"))
    name = f"test_{tag}_{uuid.uuid4().hex[:10]}"
    data["name"] = name
    for key, folder, default in (("rig", "rigs", None), ("controller", "studies/controllers", None),
                                 ("baseline", "studies/controllers", "p_k10")):  # fmt: skip
        found = find_file(data.get(key, default), folder, key, relative_to=STUDY)
        data[key] = str(Path(found).resolve())
    data.pop("storage", None)
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path, name


def _child_env() -> dict[str, str]:
    env = dict(os.environ)
    env.setdefault("MPLBACKEND", "Agg")
    env["PYTHONUNBUFFERED"] = "1"
    return env


def _default_sigint() -> None:
    # a child of a shell that ignores SIGINT (a background job) would inherit SIG_IGN and
    # Python would then never raise KeyboardInterrupt: restore the default before exec
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def start_tune(study: Path, out: Path, trials: int, *extra: str) -> subprocess.Popen:
    cmd = [*TUNE, str(study), "--trials", str(trials), "--out", str(out), *extra]
    return subprocess.Popen(
        cmd,
        cwd=out.parent,
        env=_child_env(),
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        preexec_fn=_default_sigint,
    )


def finish(proc: subprocess.Popen, timeout: float = RUN_TIMEOUT_S) -> tuple[int, str]:
    try:
        output, _ = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        output, _ = proc.communicate()
        pytest.fail(f"{proc.args} did not finish in {timeout} s; output:\n{output}")
    return proc.returncode, output


def run_tune(study: Path, out: Path, trials: int, *extra: str) -> str:
    code, output = finish(start_tune(study, out, trials, *extra))
    assert code == 0, f"fuzzyservo tune exited {code}:\n{output}"
    return output


def load(url: str, name: str):
    import optuna

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    return optuna.load_study(study_name=name, storage=_sqlalchemy(url))


def trials_of(url: str, name: str):
    return load(url, name).get_trials(deepcopy=False)


def _param_key(trial) -> tuple:
    return tuple(sorted(trial.params.items()))


def check_storage(url: str, name: str, target: int, extra: int) -> dict[str, int]:
    """The invariants of a study run by several processes; returns counts per state."""
    from optuna.trial import TrialState

    trials = trials_of(url, name)
    states = Counter(t.state.name for t in trials)
    complete = states["COMPLETE"]
    assert target <= complete <= target + extra, (
        f"{complete} COMPLETE trials for {target}: {states}"
    )
    numbers = [t.number for t in trials]
    assert len(set(numbers)) == len(numbers), f"trial numbers repeat: {sorted(numbers)}"
    assert sorted(numbers) == list(range(len(trials))), (
        f"trial numbers have gaps: {sorted(numbers)}"
    )
    running = [t.number for t in trials if t.state == TrialState.RUNNING]
    assert not running, f"trials left RUNNING: {running}"
    seen: dict[tuple, int] = {}
    dups = []
    for t in trials:
        if t.params:
            key = _param_key(t)
            if key in seen:
                dups.append((seen[key], t.number))
            seen[key] = t.number
    assert not dups, (
        f"{len(dups)} pairs of trials with identical parameters {dups}: the processes' "
        "samplers draw the same sequence (same seed in every process)"
    )
    return dict(states)


def max_concurrency(url: str, name: str) -> int:
    """How many trials ran at once at some moment (a lower bound on the processes at work)."""
    events = []
    for t in trials_of(url, name):
        if t.datetime_start and t.datetime_complete:
            events += [(t.datetime_start, 1), (t.datetime_complete, -1)]
    level = peak = 0
    for _, step in sorted(events):
        level += step
        peak = max(peak, level)
    return peak


def delete(url: str, name: str) -> None:
    import optuna

    try:
        optuna.delete_study(study_name=name, storage=_sqlalchemy(url))
    except KeyError:
        pass


def sqlite_url(out: Path, name: str) -> str:
    return f"sqlite:///{(out / f'{name}.db').resolve()}"


def complete_now(db: Path, name: str) -> int:
    """COMPLETE trials in a SQLite storage that another process is writing, read-only (no
    schema creation racing the writer); 0 while the study does not exist yet."""
    import sqlite3

    if not db.is_file():
        return 0
    try:
        con = sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=5)
        try:
            row = con.execute(
                "SELECT count(*) FROM trials JOIN studies USING (study_id) "
                "WHERE studies.study_name = ? AND trials.state = 'COMPLETE'",
                (name,),
            ).fetchone()
        finally:
            con.close()
    except sqlite3.Error:  # tables not created yet, or locked for longer than the timeout
        return 0
    return int(row[0])


def wait_for_complete(proc: subprocess.Popen, db: Path, name: str, n: int) -> int:
    deadline = time.monotonic() + RUN_TIMEOUT_S
    while time.monotonic() < deadline:
        done = complete_now(db, name)
        if done >= n:
            return done
        if proc.poll() is not None:
            output = proc.stdout.read() if proc.stdout else ""
            pytest.fail(
                f"fuzzyservo tune ended (exit {proc.returncode}) before {n} trials:\n{output}"
            )
        time.sleep(0.02)
    proc.kill()
    pytest.fail(f"no {n} complete trials in {db} after {RUN_TIMEOUT_S} s")


def snapshot(url: str, name: str) -> dict[int, tuple[dict, list[float]]]:
    from optuna.trial import TrialState

    return {
        t.number: (dict(t.params), list(t.values))
        for t in trials_of(url, name)
        if t.state == TrialState.COMPLETE
    }


def best_params_of(summary_file: Path) -> dict[str, float]:
    summary = json.loads(summary_file.read_text(encoding="utf-8"))
    best = summary.get("best", {})
    params = best.get("params") if isinstance(best, dict) else None
    if params is None:
        params = summary.get("best_params")
    assert isinstance(params, dict) and params, f"no best params in {summary_file}: {list(summary)}"
    return params


# --------------------------------------------------------------------------- PostgreSQL
def test_two_processes_share_one_postgres_study(tmp_path):
    url = postgres_url()
    study, name = study_copy(tmp_path, "twoproc")
    target = 24
    try:
        procs = [start_tune(study, tmp_path / f"out{i}", target, "--storage", url, "--async")
                 for i in (0, 1)]  # fmt: skip
        results = [finish(p) for p in procs]
        for i, (code, output) in enumerate(results):
            assert code == 0, f"process {i} exited {code}:\n{output}"
        states = check_storage(url, name, target, extra=2)
        peak = max_concurrency(url, name)
        print(f"\n{name}: {states}; at most {peak} trials ran at once")
        for i in (0, 1):
            assert (tmp_path / f"out{i}" / "summary.json").is_file()
    finally:
        delete(url, name)


def test_run_study_with_two_workers_on_postgres(tmp_path):
    url = postgres_url()
    from fuzzyservo.io.studies import load_study
    from fuzzyservo.tuning.runner import run_study

    study, name = study_copy(tmp_path, "workers")
    target = 24
    try:
        outcome = run_study(
            load_study(study), tmp_path / "out", trials=target, storage=url, workers=2,
            progress=False,
        )  # fmt: skip
        assert target <= outcome.trials_complete <= target + 2
        states = check_storage(url, name, target, extra=2)
        print(f"\n{name}: {states}; at most {max_concurrency(url, name)} trials ran at once")
    finally:
        delete(url, name)


# --------------------------------------------------------------------------- resume (SQLite)
def _interrupt_and_resume(tmp_path: Path, sig: signal.Signals, tag: str) -> None:
    study, name = study_copy(tmp_path, tag)
    out = tmp_path / "out"
    target, stop_after = 40, 5
    db = out / f"{name}.db"
    url = sqlite_url(out, name)

    proc = start_tune(study, out, target)
    wait_for_complete(proc, db, name, stop_after)
    proc.send_signal(sig)
    code, output = finish(proc, timeout=30)  # Ctrl-C must not hang
    if sig == signal.SIGINT:
        assert code == 130, f"Ctrl-C: exit {code}, expected 130:\n{output}"
        assert "resume" in output, output
    else:
        assert code == -signal.SIGKILL, f"exit {code} after SIGKILL:\n{output}"
    before = snapshot(url, name)
    assert stop_after <= len(before) < target, f"{len(before)} trials complete when stopped"
    if sig == signal.SIGINT:  # an interrupted trial is failed, not left RUNNING
        states = Counter(t.state.name for t in trials_of(url, name))
        assert "RUNNING" not in states, f"Ctrl-C left a RUNNING trial: {states}"

    run_tune(study, out, target)
    assert (out / "summary.json").is_file(), f"no summary.json in {out}: {os.listdir(out)}"
    after = snapshot(url, name)
    assert len(after) >= target
    for number, (params, values) in before.items():
        assert after.get(number) == (params, values), f"trial {number} changed on resume"
    keys = Counter(_param_key(t) for t in trials_of(url, name) if t.params)
    dups = {k: n for k, n in keys.items() if n > 1}
    assert not dups, (
        f"{len(dups)} parameter sets drawn twice after the resume: the resumed sampler "
        "restarts the seed's sequence"
    )


@pytest.mark.slow
def test_resume_after_sigkill_keeps_completed_trials(tmp_path):
    _interrupt_and_resume(tmp_path, signal.SIGKILL, "kill")


@pytest.mark.slow
def test_resume_after_ctrl_c(tmp_path):
    _interrupt_and_resume(tmp_path, signal.SIGINT, "sigint")


# --------------------------------------------------------------------------- reproducibility
@pytest.mark.slow
def test_same_seed_one_worker_gives_same_best(tmp_path):
    study, _ = study_copy(tmp_path, "seed")
    trials = 15
    best = []
    for folder in ("a", "b"):
        out = tmp_path / folder
        run_tune(study, out, trials)
        best.append(best_params_of(out / "summary.json"))
    assert best[0] == best[1]
