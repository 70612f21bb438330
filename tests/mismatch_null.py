"""The false-positive rate on mismatch-only null data (issue 28), on the independent
generator (tests/independent_rig.py): no effect, one model error of a real bench's size
(ADC codes, a sensor filter, another orifice smoothing, a 5 % flow-gain error), each
over ``draws`` noise draws; the full calibration of the nominal seed-002 rig, whole
library, up to two effects. Prints what each draw added and the rate per mismatch.

Run from the repository root (about 1 min per draw on a loaded 2-core machine; use nice):

    PYTHONPATH=. python tests/mismatch_null.py [draws=20] [mismatch ...]
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from independent_rig import MISMATCHES, independent_draws
from support import controller_named
from test_calibration import NOISE, old_loop

from fuzzyservo.calibration.replay import make_replay
from fuzzyservo.calibration.search import search_effects
from fuzzyservo.io.rigs import load_rig


def main(draws: int = 20, mismatches: tuple[str, ...] = MISMATCHES) -> None:
    """Print each draw's verdict and the false-positive rate of each mismatch."""
    rig = load_rig(old_loop(Path(tempfile.mkdtemp())))
    controller = controller_named("p_k10")
    for mismatch in mismatches:
        added = 0
        records = independent_draws(None, NOISE, tuple(range(100, 100 + draws)), mismatch=mismatch)
        for k, data in enumerate(records):
            start = time.perf_counter()
            outcome = search_effects(make_replay(rig, data, controller), rig)
            names = [c.name for c in outcome.added]
            added += bool(names)
            null = outcome.rounds[0].null
            print(
                f"{mismatch} draw {k + 1}/{draws}: added {names or 'none'}; threshold "
                f"{null.threshold:.2f} (Bonferroni {null.bonferroni:.2f}); best "
                f"{outcome.rounds[0].candidates[0].name} z "
                f"{outcome.rounds[0].candidates[0].evidence.z:.2f} "
                f"({time.perf_counter() - start:.0f} s)",
                flush=True,
            )
        print(f"{mismatch}: an effect added in {added} of {draws} draws", flush=True)


if __name__ == "__main__":
    args = sys.argv[1:]
    n = int(args[0]) if args else 20
    main(n, tuple(args[1:]) or MISMATCHES)
