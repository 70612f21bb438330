"""Which sampler finds the best controller on our studies? (issue 26)

    python benchmarks/compare_samplers.py [--studies dinca_flc,dinca_robust,ehs160_flc]
        [--samplers tpe,cmaes,gp,nsga2,qmc,random] [--seeds 5] [--trials N] [--workers 2]
        [--out out/samplers]

Runs every shipped study with every sampler, ``--seeds`` seeds each, at the study's own
trial budget (or ``--trials``), through the public API (:func:`fuzzyservo.tune`), and
writes ``samplers.json`` (each run's best-so-far curve), ``samplers.md`` (the table: median
and spread of the final best per study and sampler) and ``samplers.png`` (median and
interquartile band of the best feasible objective against trials). NSGA-II on one
objective is a genetic algorithm (what MATLAB's ``tunefis`` offers besides particle
swarm); ``gp`` needs PyTorch (``pip install 'fuzzyservo[gp]'``) and is left out without it.
Runs are reproducible (pipelined tuning): the same command gives the same table.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import json
import math
import statistics
import sys
import tempfile
import time
from pathlib import Path

from fuzzyservo import load_study, tune
from fuzzyservo.io.paths import find_file


def best_so_far(history: list[dict], trials: int) -> list[float | None]:
    """The best feasible objective after each trial number (None before the first)."""
    by_number = {h["number"]: h["values"][0] for h in history if h["feasible"]}
    best, curve = math.inf, []
    for n in range(trials):
        best = min(best, by_number.get(n, math.inf))
        curve.append(best if math.isfinite(best) else None)
    return curve


def run(study_name: str, sampler: str, seed: int, trials: int | None, workers: int) -> dict:
    study = load_study(find_file(study_name, "studies", "study"))
    study = dataclasses.replace(study, sampler=sampler, seed=seed)
    budget = trials or study.trials
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        outcome = tune(study, tmp, trials=budget, workers=workers, progress=False)
        wall = time.perf_counter() - t0
    curve = best_so_far(outcome.history, budget)
    return {"study": study_name, "sampler": sampler, "seed": seed, "trials": budget,
            "wall_s": round(wall, 2), "best": curve[-1], "curve": curve}  # fmt: skip


def table(runs: list[dict]) -> str:
    lines = ["| study | sampler | runs | median best | min | max | median wall |",
             "|---|---|---|---|---|---|---|"]  # fmt: skip
    keys = sorted({(r["study"], r["sampler"]) for r in runs})
    for study, sampler in keys:
        mine = [r for r in runs if (r["study"], r["sampler"]) == (study, sampler)]
        bests = [r["best"] if r["best"] is not None else math.inf for r in mine]
        walls = [r["wall_s"] for r in mine]
        lines.append(
            f"| {study} | {sampler} | {len(mine)} | {statistics.median(bests):.4g} | "
            f"{min(bests):.4g} | {max(bests):.4g} | {statistics.median(walls):.0f} s |"
        )
    return "\n".join(lines) + "\n"


def plot(runs: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    studies = sorted({r["study"] for r in runs})
    fig, axes = plt.subplots(1, len(studies), figsize=(5 * len(studies), 4), squeeze=False)
    for ax, study in zip(axes[0], studies, strict=True):
        for sampler in sorted({r["sampler"] for r in runs if r["study"] == study}):
            curves = np.array(
                [
                    [math.nan if v is None else v for v in r["curve"]]
                    for r in runs
                    if (r["study"], r["sampler"]) == (study, sampler)
                ]
            )
            x = np.arange(1, curves.shape[1] + 1)
            med = np.nanmedian(curves, axis=0)
            ax.plot(x, med, label=sampler)
            ax.fill_between(x, np.nanpercentile(curves, 25, axis=0),
                            np.nanpercentile(curves, 75, axis=0), alpha=0.15)  # fmt: skip
        values = [v for r in runs if r["study"] == study for v in r["curve"] if v is not None]
        log = bool(values) and min(values) > 0
        ax.set(title=study, xlabel="trials", ylabel="best feasible objective",
               yscale="log" if log else "linear")  # fmt: skip
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--studies", default="dinca_flc,dinca_robust,ehs160_flc")
    ap.add_argument("--samplers", default="tpe,cmaes,gp,nsga2,qmc,random")
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--trials", type=int, default=None, help="default: each study's budget")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default="out/samplers")
    args = ap.parse_args(argv)
    samplers = args.samplers.split(",")
    if "gp" in samplers and importlib.util.find_spec("torch") is None:
        print(
            "gp left out: PyTorch is not installed (pip install 'fuzzyservo[gp]')", file=sys.stderr
        )
        samplers.remove("gp")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    runs = []
    jobs = [(s, m, k) for s in args.studies.split(",") for m in samplers for k in range(args.seeds)]
    for i, (study, sampler, seed) in enumerate(jobs, 1):
        runs.append(run(study, sampler, seed, args.trials, args.workers))
        r = runs[-1]
        print(f"[{i}/{len(jobs)}] {study} {sampler} seed {seed}: best {r['best']} ({r['wall_s']} s)",
              flush=True)  # fmt: skip
        (out / "samplers.json").write_text(json.dumps(runs), encoding="utf-8")
    (out / "samplers.md").write_text(table(runs), encoding="utf-8")
    plot(runs, out / "samplers.png")
    print(table(runs))
    print(f"written to {out}/")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
