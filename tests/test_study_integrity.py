"""Study integrity (issue 13 item 5): an edited definition never mixes into a stored study,
processes sharing the default SQLite storage never propose the same parameters, and worker
processes end with their parent (SIGTERM, kill -9, SIGINT of a background job)."""

from __future__ import annotations

import dataclasses
import os
import signal
import subprocess
import time
from pathlib import Path

import pytest
import yaml
from test_tuning_distributed import (
    TUNE,
    _child_env,
    _param_key,
    check_storage,
    complete_now,
    finish,
    sqlite_url,
    start_tune,
    study_copy,
    trials_of,
)

from fuzzyservo.cli import main
from fuzzyservo.errors import ConfigError
from fuzzyservo.io.studies import load_study
from fuzzyservo.tuning.spec import Parameter
from fuzzyservo.tuning.storage import open_study


def cheap_copy(tmp_path: Path, tag: str) -> tuple[Path, str]:
    """:func:`study_copy` (dinca_flc under a unique name) on its 8 s `steps` alone and
    without the margin constraints (no margin runs): what these tests prove is about the
    storage, the sampler's seeding and the processes, not the objective, and a trial costs
    one short simulation instead of up to six."""
    study, name = study_copy(tmp_path, tag)
    data = yaml.safe_load(study.read_text())
    data["scenarios"] = ["steps"]
    data["constraints"] = ["overshoot_pct <= 5"]
    study.write_text(yaml.safe_dump(data, sort_keys=False))
    return study, name


# --------------------------------------------------------------------------- fingerprint
def _edited(spec, path: str, low: float, high: float):
    params = tuple(Parameter(p.path, low, high) if p.path == path else p for p in spec.parameters)
    return dataclasses.replace(spec, parameters=params)


def test_edited_search_space_stops_naming_the_change(tmp_path):
    study, _ = study_copy(tmp_path, "edit")
    spec = load_study(study)
    url = sqlite_url(tmp_path, spec.name)
    open_study(spec, url)
    open_study(spec, url)  # the same definition opens again
    with pytest.raises(ConfigError) as info:
        open_study(_edited(spec, "output.translate", 2.0, 3.0), url)
    text = str(info.value)
    assert "search space (output.translate [0, 0.5] -> [2, 3])" in text, text
    assert "--out" in text and "\n" not in text


def test_a_study_stored_before_typed_fingerprints_still_opens(tmp_path):
    """Studies stored before the rig and template were hashed from their typed objects
    (no scheme attribute) are checked on the parts hashed alike, then carry the new
    fingerprint; a changed search space is still caught."""
    from fuzzyservo.tuning.integrity import FINGERPRINT_ATTR, SCHEME, SCHEME_ATTR

    study, _ = study_copy(tmp_path, "legacy")
    spec = load_study(study)
    url = sqlite_url(tmp_path, spec.name)

    def make_legacy(stored) -> None:
        old = dict(stored.user_attrs[FINGERPRINT_ATTR], rig="0" * 16, template="1" * 16)
        stored.set_user_attr(FINGERPRINT_ATTR, old)
        stored.set_user_attr(SCHEME_ATTR, None)

    make_legacy(open_study(spec, url))
    reopened = open_study(spec, url)  # adopts the new fingerprint
    assert reopened.user_attrs[SCHEME_ATTR] == SCHEME
    assert reopened.user_attrs[FINGERPRINT_ATTR]["rig"] != "0" * 16
    make_legacy(reopened)
    with pytest.raises(ConfigError, match="search space"):
        open_study(_edited(spec, "output.translate", 2.0, 3.0), url)


def test_another_sampler_or_seed_does_not_resume_the_study(tmp_path):
    """A study's trials were proposed by its sampler and seed: resuming under another is
    refused with the change named (it was resumed silently). A study stored before the
    sampler was fingerprinted adopts the one it is opened with."""
    from fuzzyservo.tuning.integrity import FINGERPRINT_ATTR

    study, _ = study_copy(tmp_path, "sampler")
    spec = load_study(study)
    url = sqlite_url(tmp_path, spec.name)
    stored = open_study(spec, url)
    for other in (dict(sampler="tpe" if spec.sampler != "tpe" else "cmaes"), dict(seed=7)):
        with pytest.raises(ConfigError, match="sampler"):
            open_study(dataclasses.replace(spec, **other), url)
    old = {k: v for k, v in stored.user_attrs[FINGERPRINT_ATTR].items() if k != "sampler"}
    stored.set_user_attr(FINGERPRINT_ATTR, old)
    tpe = dataclasses.replace(spec, sampler="tpe" if spec.sampler != "tpe" else "cmaes")
    assert "sampler" in open_study(tpe, url).user_attrs[FINGERPRINT_ATTR]
    open_study(tpe, url)  # and keeps it
    with pytest.raises(ConfigError, match="sampler"):
        open_study(spec, url)


def test_edited_study_file_rerun_exits_2_with_one_line(tmp_path, capsys):
    study, _ = cheap_copy(tmp_path, "cli")
    out = tmp_path / "out"
    assert main(["tune", str(study), "--trials", "1", "--out", str(out)]) == 0
    data = yaml.safe_load(study.read_text())
    data["objective"] = {"metric": "itae"}
    data["scenarios"] = ["pulses"]
    study.write_text(yaml.safe_dump(data, sort_keys=False))
    capsys.readouterr()
    assert main(["tune", str(study), "--trials", "2", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err, err
    assert "scenarios" in err and "objective" in err and "another --out folder" in err, err


# --------------------------------------------------------------------------- duplicates
def _ask(study, spec) -> dict[str, float]:
    trial = study.ask()
    params = {
        p.path: trial.suggest_float(p.path, p.low, p.high, log=p.log) for p in spec.parameters
    }
    study.tell(trial, sum(params.values()))
    return params


# the test asks the study for trials directly, where `tune` runs Study.optimize; optuna
# then warns that the storage heartbeat is meant for optimize
@pytest.mark.filterwarnings("ignore:Heartbeat of storage:UserWarning")
def test_two_processes_on_default_sqlite_propose_no_duplicates(tmp_path):
    """Two processes opening one default SQLite study: interleaved here, as two `tune`
    commands interleave (before: same seed in both, the same proposals)."""
    study, _ = study_copy(tmp_path, "dup")
    spec = load_study(study)
    url = sqlite_url(tmp_path, spec.name)
    a, b = open_study(spec, url), open_study(spec, url)
    proposals = [_ask(s, spec) for _ in range(12) for s in (a, b)]
    keys = {tuple(sorted(p.items())) for p in proposals}
    assert len(keys) == len(proposals), "two processes proposed the same parameters"
    # and a fresh study with the same seed proposes the same first trials (reproducible)
    (tmp_path / "again").mkdir()
    other = open_study(spec, sqlite_url(tmp_path / "again", spec.name))
    assert [_ask(other, spec) for _ in range(3)] == proposals[:3]


@pytest.mark.slow
def test_two_tune_commands_on_default_sqlite_share_without_duplicates(tmp_path):
    study, name = cheap_copy(tmp_path, "dup2")
    out = tmp_path / "out"
    out.mkdir()
    target = 16
    procs = [start_tune(study, out, target, "--async") for _ in range(2)]
    for proc in procs:
        code, output = finish(proc)
        assert code == 0, output
    check_storage(sqlite_url(out, name), name, target, extra=2)
    keys = [_param_key(t) for t in trials_of(sqlite_url(out, name), name) if t.params]
    assert len(set(keys)) == len(keys)


# --------------------------------------------------------------------------- orphans
def _workers_of(pid: int) -> list[int]:
    """Live worker processes (multiprocessing spawn children) of ``pid``."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
            cmd = (entry / "cmdline").read_bytes().decode(errors="replace")
        except OSError:
            continue
        ppid = int(stat.rsplit(")", 1)[1].split()[1])
        state = stat.rsplit(")", 1)[1].split()[0]
        if ppid == pid and "spawn_main" in cmd and state != "Z":
            found.append(int(entry.name))
    return found


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def _start_two_workers(tmp_path: Path, tag: str, ignore_sigint: bool = False):
    study, name = cheap_copy(tmp_path, tag)
    out = tmp_path / "out"
    out.mkdir()
    # trials enough that the run cannot end (about 70 trials/s here) before the signal lands
    cmd = [*TUNE, str(study), "--trials", "5000", "--out", str(out), "--workers", "2"]

    def background() -> None:  # a job started with `&` by a non-interactive shell
        signal.signal(signal.SIGINT, signal.SIG_IGN if ignore_sigint else signal.SIG_DFL)

    proc = subprocess.Popen(
        cmd, cwd=tmp_path, env=_child_env(), stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, preexec_fn=background,
    )  # fmt: skip
    deadline = time.monotonic() + 180
    while time.monotonic() < deadline:
        workers = _workers_of(proc.pid)
        if len(workers) == 2 and complete_now(out / f"{name}.db", name) >= 2:
            return proc, workers
        if proc.poll() is not None:
            pytest.fail(f"tune ended early (exit {proc.returncode}): {proc.stdout.read()}")
        time.sleep(0.1)
    proc.kill()
    pytest.fail("the two workers did not start")


def _gone(pids: list[int], within_s: float = 60.0) -> list[int]:
    deadline = time.monotonic() + within_s
    while time.monotonic() < deadline:
        left = [p for p in pids if _alive(p)]
        if not left:
            return []
        time.sleep(0.1)
    for p in left:
        os.kill(p, signal.SIGKILL)
    return left


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM], ids=["kill-9", "sigterm"])
def test_workers_end_with_their_parent(tmp_path, sig):
    proc, workers = _start_two_workers(tmp_path, f"orphan{int(sig)}")
    proc.send_signal(sig)
    finish(proc, timeout=90)
    assert not _gone(workers), f"workers {workers} outlived their parent after signal {sig}"


@pytest.mark.slow
def test_sigint_stops_a_background_run_and_its_workers(tmp_path):
    proc, workers = _start_two_workers(tmp_path, "bgint", ignore_sigint=True)
    proc.send_signal(signal.SIGINT)
    code, output = finish(proc, timeout=90)
    assert code == 130, f"exit {code}:\n{output}"
    assert "resume" in output
    assert not _gone(workers), f"workers {workers} outlived a Ctrl-C of their parent"
