"""The 50 000-sample calibration timing of docs/calibration.md (issue 12, item 7).

Run from the repository root (nice it; a few minutes):

    PYTHONPATH=. python tests/long_record_timing.py [workers=2]

The seed-002 rig file with its loop at 1 kHz, P K=10, 50 s of ``pulses`` with a 300 N
Coulomb friction the rig does not declare, 5 µm and 0.05 bar of noise; ``calibrate``
with the whole library. Prints wall and CPU time (this process and its workers), the
replays and each round's candidates.
"""

from __future__ import annotations

import os
import resource
import sys
import tempfile
import time
from pathlib import Path

import yaml

from fuzzyservo.bench import data_root
from fuzzyservo.calibration.replay import make_replay
from fuzzyservo.calibration.search import search_effects
from fuzzyservo.calibration.synthetic import synthetic_run
from fuzzyservo.io.controllers import load_controller
from fuzzyservo.io.rigs import load_rig

NOISE = {"y": 5e-6, "p_s": 5e3, "p_t": 5e3, "p_a": 5e3, "p_b": 5e3}


def cpu_s() -> float:
    """CPU time of this process and of its finished children (the workers) [s]."""
    own, children = (
        resource.getrusage(resource.RUSAGE_SELF),
        resource.getrusage(resource.RUSAGE_CHILDREN),
    )
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def main(workers: int) -> None:
    root = data_root()
    spec = yaml.safe_load((root / "rigs" / "dinca_cylinder.yaml").read_text(encoding="utf-8"))
    spec["controller"]["sample_time"] = {"value": 1, "unit": "ms", "source": "1 kHz"}
    path = Path(tempfile.mkdtemp()) / "dinca_cylinder_1khz.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False), encoding="utf-8")
    rig = load_rig(path)
    controller = load_controller(root / "studies" / "controllers" / "p_k10.yaml")
    friction = {"coulomb_friction": {"force": 300.0}}
    data = synthetic_run(rig, controller, "pulses", friction, NOISE, duration_s=50.0)
    print(f"{data.t.size} samples; load average {os.getloadavg()}", flush=True)
    cpu0, t0 = cpu_s(), time.perf_counter()
    outcome = search_effects(
        make_replay(rig, data, controller),
        rig,
        workers=workers,
        progress=lambda name: print(f"{time.perf_counter() - t0:7.1f} s  {name}", flush=True),
    )
    wall, cpu = time.perf_counter() - t0, cpu_s() - cpu0
    replays = sum(c.evaluations for r in outcome.rounds for c in r.candidates)
    print(f"load average {os.getloadavg()}")
    print(f"{workers} worker(s): wall {wall:.1f} s, CPU {cpu:.1f} s, {replays} replays")
    for r in outcome.rounds:
        print(f"round (threshold z {r.threshold:.2f}): added {r.added}")
        for c in r.candidates:
            z = c.evidence.z if c.evidence else float("nan")
            print(f"  {c.name:18s} held-out {c.score:9.3f}  z {z:7.1f}  replays {c.evaluations}")
    print("added:", [(c.name, c.params) for c in outcome.added])


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 2)
