"""The detection-limit table and null false-positive rate on seed 002 (issue 12;
docs/calibration.md).

Run from the repository root (about 30 min on one core; use nice):

    PYTHONPATH=. python tests/detection_limits.py [draws=10] [null_draws=20]

The rig is the seed-002 file as tests/test_calibration.py measures on it (``old_loop``),
P K=10, ``pulses``, with that file's acquisition noise (position 5 µm, pressures 0.05 bar).
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from support import controller_named
from test_calibration import NOISE, old_loop

from fuzzyservo.calibration.detection import (
    SEED002_LADDERS,
    detection_ladder,
    false_positive_rate,
    limit,
)
from fuzzyservo.io.rigs import load_rig


def _size(params: dict[str, float]) -> str:
    return ", ".join(f"{k} {v:.3g}" for k, v in params.items() if k != "stribeck_velocity")


def main(draws: int = 10, null_draws: int = 20) -> None:
    """Print the seed-002 detection-limit table and null false-positive rate (docs/calibration.md)."""
    rig = load_rig(old_loop(Path(tempfile.mkdtemp())))
    controller = controller_named("p_k10")
    start = time.perf_counter()

    def say(line: str) -> None:
        print(f"[{time.perf_counter() - start:7.1f} s] {line}", flush=True)

    fp, added = false_positive_rate(rig, controller, "pulses", NOISE, null_draws, progress=say)
    print(f"null data: an effect added in {fp} of {null_draws} draws: {added}", flush=True)
    rows = []
    for effect, sizes in SEED002_LADDERS.items():
        ladder = detection_ladder(
            rig, controller, "pulses", effect, sizes, NOISE, draws, progress=say
        )
        best = limit(ladder)
        rows.append((effect, ladder, best))
    print("\n| effect | sizes tried (found / draws) | detection limit (≥ 90 %) |")
    print("|---|---|---|")
    for effect, ladder, best in rows:
        tried = "; ".join(f"{_size(d.params)}: {d.found}/{d.draws}" for d in ladder)
        lim = _size(best.params) if best else "above the largest size tried"
        print(f"| {effect} | {tried} | {lim} |")
    print(f"\nnull data: an effect added in {fp} of {null_draws} draws: {added}")
    print(f"total {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:3]))
