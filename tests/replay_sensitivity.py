"""How the training cost of a friction record's replay moves at the true values: with a
parameter changed by a millionth, a ten-thousandth and a hundredth of itself, and with
the replay integrated ten times more tightly than the record was (the docs'
"Coverage of the 95 % intervals" explains what the table shows).

A fit and its profile need a cost that is smooth in the parameters: where a change of a
millionth moves the cost as much as one of a hundredth, the replay is chaotic there,
and no search or interval built on the replayed output can find the true values. The
records are interval_coverage.py's draws of its two columns: rig-like (the feedback
noise in the loop) replayed from the recorded valve current, and with the noise added to
a noise-free loop's record replayed through the controller.

Run from the repository root (a few seconds per draw):

    PYTHONPATH=. nice python tests/replay_sensitivity.py [draws=5] [--segments]

``--segments``: the same on the segmented replay that ``calibrate --segments`` fits
(calibration/segments.py), with its segment length.
"""

from __future__ import annotations

import math
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np
from interval_coverage import replayed
from support import rig_named

from fuzzyservo.calibration.candidates import candidate_effects
from fuzzyservo.calibration.replay import Replay
from fuzzyservo.calibration.segments import probe_rigs, segmented
from fuzzyservo.components.effects import LIBRARY
from fuzzyservo.rig import Rig
from fuzzyservo.simulation import DEFAULT_TOL

ROWS = {  # interval_coverage.py's draws: the docs' label
    "coulomb_friction": "Coulomb, smooth law",
    "coulomb_friction:lugre": "Coulomb, LuGre",
    "stribeck_friction": "Stribeck, sticking",
    "stribeck_friction:static": "Stribeck, creeping",
}
CHANGES = (1e-6, 1e-4, 1e-2)  # relative change of the effect's first parameter
SUP = str.maketrans("0123456789", "⁰¹²³⁴⁵⁶⁷⁸⁹")


def training_cost(replay: Replay, rig: Rig, *, tol: float = DEFAULT_TOL) -> float:
    model, _ = replay.run(rig, training=True, tol=tol)
    return replay.cost(model, slice(0, replay.split))


def sensitivity(
    rig: Rig,
    name: str,
    k: int,
    *,
    open_loop: bool,
    changes: tuple[float, ...] = CHANGES,
    tight: bool = True,
    segments: bool = False,
) -> list[float]:
    """Draw ``k``'s training cost at the truth, then its relative change with each of
    ``changes`` and (``tight``) with a tolerance ten times tighter; ``segments``: on the
    segmented replay a calibration with ``segments=True`` fits (its segment length, s,
    last)."""
    truth, replay = replayed(rig, name, k, in_loop=open_loop, open_loop=open_loop)
    if segments:
        replay = segmented(replay, rig, probe_rigs(rig, candidate_effects(rig)))
    effect = name.partition(":")[0]
    at_truth = training_cost(replay, rig.with_effect(effect, **truth))
    first = LIBRARY[effect].fitted[0].key
    moved = []
    for change in changes:
        nudged = {**truth, first: truth[first] * (1.0 + change)}
        moved.append(training_cost(replay, rig.with_effect(effect, **nudged)))
    if tight:
        moved.append(training_cost(replay, rig.with_effect(effect, **truth), tol=DEFAULT_TOL / 10))
    out = [at_truth, *(abs(c / at_truth - 1.0) for c in moved)]
    return [*out, replay.segment_s] if segments else out


def percent(share: float) -> str:
    """``share`` as the docs' table prints it: two significant digits, no exponent."""
    p = 100.0 * share
    if p >= 1000:
        return f"{round(p, -2):,.0f} %"
    return np.format_float_positional(p, precision=2, fractional=False, trim="-") + " %"


def main(draws: int = 5, *, segments: bool = False) -> None:
    rig = rig_named("dinca_cylinder")
    heads = " | ".join(f"×(1 + 10{'⁻' + str(-round(math.log10(c))).translate(SUP)})"
                       for c in CHANGES)  # fmt: skip
    last = " segment [s] |" if segments else ""
    print(f"| friction | replay | cost at the truth | {heads} | tolerance / 10 |{last}")
    print("|---" * (4 + len(CHANGES) + segments) + "|")
    for name, label in ROWS.items():
        for open_loop in (True, False):
            rows = [sensitivity(rig, name, k, open_loop=open_loop, segments=segments)
                    for k in range(draws)]  # fmt: skip
            cells = [f"{statistics.median(r[0] for r in rows):.3g}"]
            cells += [percent(statistics.median(r[j] for r in rows))
                      for j in range(1, 2 + len(CHANGES))]  # fmt: skip
            if segments:
                cells.append(f"{statistics.median(r[-1] for r in rows):.3g}")
            replay = "valve current" if open_loop else "through P K=10"
            print(f"| {label} | {replay} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    main(int(args[0]) if args else 5, segments="--segments" in sys.argv)
