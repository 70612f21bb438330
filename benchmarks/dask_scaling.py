"""A study on a Dask cluster against the same study on local worker processes (issue 57).

    python benchmarks/dask_scaling.py [--study dinca_flc] [--workers 2] [--trials 300]
        [--rounds 2]

Starts a Dask scheduler and ``--workers`` ``dask worker`` processes (one thread each) on
this machine, as they would run on others, and runs ``--study`` from scratch
``--rounds`` times each way, alternately: ``--workers`` local processes, and the
cluster. Prints the wall time, the trials per second, where the time went (startup,
trials, workers idle, finish) and the best objective of every run; the two ways give the
same trials (tests/test_tuning_reproducible.py), so only the times may differ. Needs the
``cluster`` extra (``pip install 'fuzzyservo[cluster]'``).
"""

from __future__ import annotations

import argparse
import os
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from fuzzyservo import load_study, tune
from fuzzyservo.io.paths import find_file


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_cluster(workers: int, logs: Path) -> tuple[str, list[subprocess.Popen]]:
    """A scheduler and ``workers`` single-thread workers, each its own process."""
    from distributed import Client

    dask = Path(sys.executable).with_name("dask")
    address = f"tcp://127.0.0.1:{_free_port()}"
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    procs = [subprocess.Popen([str(dask), "scheduler", "--host", "127.0.0.1", "--port",
                               address.rsplit(":", 1)[1], "--no-dashboard"], env=env,
                              stdout=open(logs / "scheduler.log", "w"), stderr=subprocess.STDOUT)]  # fmt: skip
    for k in range(workers):
        procs.append(subprocess.Popen([str(dask), "worker", address, "--nthreads", "1",
                                       "--no-dashboard", "--memory-limit", "0"], env=env,
                                      stdout=open(logs / f"worker{k}.log", "w"),
                                      stderr=subprocess.STDOUT))  # fmt: skip
    with Client(address, timeout=60) as client:
        client.wait_for_workers(workers, timeout=120)
    return address, procs


def run(study_name: str, trials: int, workers: int, cluster: str | None) -> dict:
    study = load_study(find_file(study_name, "studies", "study"))
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        outcome = tune(study, tmp, trials=trials, workers=workers, cluster=cluster,
                       progress=False)  # fmt: skip
        wall = time.perf_counter() - t0
    told = outcome.trials_complete + outcome.trials_pruned
    line = outcome.timeline
    return {"how": "cluster" if cluster else "local", "wall_s": wall, "trials_per_s": told / wall,
            "best": outcome.best.values[0], "simulation_s": outcome.sim_time_s,
            **{k: line.get(k, float("nan")) for k in ("startup_s", "trials_s", "idle_s",
                                                      "finish_s", "parent_wait_s")}}  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--study", default="dinca_flc")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--trials", type=int, default=300)
    ap.add_argument("--rounds", type=int, default=2)
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as logs:
        address, procs = start_cluster(args.workers, Path(logs))
        try:
            rows = []
            for _ in range(args.rounds):
                for cluster in (None, address):
                    rows.append(run(args.study, args.trials, args.workers, cluster))
                    r = rows[-1]
                    print(f"{r['how']:>7}: {r['wall_s']:5.1f} s, {r['trials_per_s']:5.1f} trials/s; "
                          f"startup {r['startup_s']:.1f} s, trials {r['trials_s']:.1f} s (workers "
                          f"idle {r['idle_s']:.1f} s, parent waited {r['parent_wait_s']:.1f} s), "
                          f"finish {r['finish_s']:.1f} s; simulation {r['simulation_s']:.1f} s; "
                          f"best {r['best']:.4g}", flush=True)  # fmt: skip
        finally:
            for proc in procs:
                proc.kill()
                proc.wait(timeout=30)
    best = {how: max(r["trials_per_s"] for r in rows if r["how"] == how)
            for how in ("local", "cluster")}  # fmt: skip
    print(f"best of {args.rounds}: cluster {best['cluster']:.1f} trials/s against local "
          f"{best['local']:.1f}: {best['cluster'] / best['local']:.2f}×")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
