"""Calibration's power and error rate on the independent generator (issue 40;
docs/calibration.md "Power and error rate").

Records from tests/independent_rig.py (its own formulations of every effect) of the
seed-002 bench under P K=10, each with a model error of a real bench's size:

* **power**: each library effect at the middle of its typical range plus the bench's
  mismatches together (``BENCH``: ADC codes, the orifices' laminar transition at 0.3 bar,
  the valve's flow gain 5 % off); is it named first and added?
* **error rate**: no effect, one mismatch (each of ``MISMATCHES``, and ``BENCH``); is
  anything added? (A 1 ms sensor filter comes back as the loop delay it acts as, with
  its lookalike stated: the issue's decided clause; counted apart.)

The rig is seed 002's (``old_loop``) with the valve's flow gain (``slot_coefficient_b``)
declared unknown within ±10 %, as an engineer unsure of it would declare it: the 5 %
flow-gain error is then fitted with the nominal model, and what the fit cannot take
(ADC codes, the orifice law) stays as model error. The nulls are run on that rig and
also on the rig without the unknown (``fixed``: the 5 % error left in the residual).

Round 1 of the calibration decides both (a record whose first round adds nothing adds
nothing); its candidates are fitted once per record and kept (``--cache``), so the
decision (search.decide) can be re-run on them cheaply.

Run from the repository root (about 10 s per record and core; use nice):

    PYTHONPATH=. python tests/calibration_power.py [draws=20] [--cache DIR] [--jobs 2]

``--only coulomb_friction`` fits only that effect's power and size cases (a change that
can touch only records with that effect). ``--refit valve_lag`` refits only that
candidate in every cached record (after a change to that effect alone), then decides.
"""

from __future__ import annotations

import argparse
import dataclasses
import pickle
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from independent_rig import BENCH, MIDDLE, MISMATCHES, independent_draws
from support import controller_named
from test_calibration import NOISE, old_loop

FLOW_GAIN_FIT = (0.054, 0.066)  # l/(min·mA·sqrt(bar)): the declared 0.0600 ± 10 %


def power_rig(folder: Path, declared: bool = True) -> Path:
    """The seed-002 rig file of these measurements: ``old_loop``, and with ``declared``
    the valve's flow gain an unknown within FLOW_GAIN_FIT."""
    import yaml

    path = old_loop(folder)
    if declared:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
        valve = data["plant"]["components"]["valve"]["parameters"]
        valve["slot_coefficient_b"]["fit"] = list(FLOW_GAIN_FIT)
        path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


SIZES = (0.25,)  # the power curve's smaller sizes, as a share of the middle one
CURVE_DRAWS = 10


def scaled(effect: str, share: float) -> dict[str, float]:
    """The generator's parameters of ``effect`` at ``share`` of its middle size (a
    slower spool, a softer oil, a smaller pump for a larger effect)."""
    p = dict(MIDDLE[effect])
    if effect == "valve_lag":
        p["wn"] /= share
    elif effect == "bulk_modulus":
        e_oil = 1.8e9
        p["e"] = 1.0 / (1.0 / e_oil + share * (1.0 / p["e"] - 1.0 / e_oil))
    elif effect == "supply_droop":
        p["qp"] /= share
    else:
        for key in p:
            if key not in ("vs",):
                p[key] *= share
    return p


def cases(draws: int) -> list[tuple[str, str | None, str, tuple[int, ...]]]:
    """(kind, effect, mismatch, seeds): the power cases, the nulls (``null`` on the
    rig with the flow gain declared, ``fixed`` on the one without), then the power
    curve's smaller sizes (``size0.25`` ...)."""
    out = []
    for effect in MIDDLE:
        out.append(("power", effect, BENCH, tuple(range(200, 200 + draws))))
    for mismatch in (*MISMATCHES, BENCH):
        out.append(("null", None, mismatch, tuple(range(300, 300 + draws))))
    for mismatch in ("flow_gain", BENCH):
        out.append(("fixed", None, mismatch, tuple(range(300, 300 + draws))))
    for share in SIZES:
        for effect in MIDDLE:
            out.append((f"size{share}", effect, BENCH, tuple(range(400, 400 + CURVE_DRAWS))))
    return out


def _fit_round(args) -> list[Path]:
    """Simulate one case's records and fit round 1's candidates on each; pickled."""
    kind, effect, mismatch, seeds, cache = args
    from fuzzyservo.calibration.candidates import candidate_effects, fit
    from fuzzyservo.calibration.replay import make_replay
    from fuzzyservo.calibration.search import _candidate
    from fuzzyservo.io.rigs import load_rig

    rig = load_rig(power_rig(Path(tempfile.mkdtemp()), declared=kind != "fixed"))
    controller = controller_named("p_k10")
    paths = []
    todo = [s for s in seeds if not (cache / f"{kind}_{effect}_{mismatch}_{s}.pkl").is_file()]
    params = scaled(effect, float(kind[4:])) if kind.startswith("size") else None
    records = (
        independent_draws(effect, NOISE, tuple(todo), params=params, mismatch=mismatch)
        if todo
        else []
    )
    for seed, data in zip(todo, records, strict=True):
        start = time.perf_counter()
        replay = make_replay(rig, data, controller)
        nominal = rig
        model, _ = replay.run(rig)
        cost = replay.cost(model, slice(replay.split, None))
        if rig.unknowns:  # as search.search_effects fits them first
            nominal, fitted = fit(replay, rig, None, max_evaluations=120)
            model, cost = fitted.model, fitted.cost_val
        results = [_candidate(replay, nominal, model, name) for name in candidate_effects(rig)]
        results.sort(key=lambda c: c.score)
        path = cache / f"{kind}_{effect}_{mismatch}_{seed}.pkl"
        with path.open("wb") as f:
            pickle.dump((replay, nominal, model, cost, results), f)
        print(f"fitted {path.name} ({time.perf_counter() - start:.0f} s)", flush=True)
        paths.append(path)
    return paths


def _with_new_fields(rig):
    """A rig unpickled from a cache written before the effect library gained a field:
    the missing fields at their default (0: the effect part off)."""
    params = getattr(rig, "params", None)
    for f in dataclasses.fields(params) if params is not None else ():
        if not hasattr(params, f.name):
            object.__setattr__(params, f.name, f.default)
    return rig


def _refit(args) -> None:
    """Refit the candidates ``names`` of one cached record and write it back: a library
    change confined to some effects re-measures without refitting the rest."""
    path, names = args
    from fuzzyservo.calibration.search import _candidate

    with path.open("rb") as f:
        replay, rig, model, cost, results = pickle.load(f)
    _with_new_fields(rig)
    for c in results:
        if c.rig is not None:
            _with_new_fields(c.rig)
    results = [_candidate(replay, rig, model, c.name) if c.name in names else c for c in results]
    results.sort(key=lambda c: c.score)
    with path.open("wb") as f:
        pickle.dump((replay, rig, model, cost, results), f)


def decide_all(cache: Path, draws: int) -> dict:
    """The decision on every cached record: (kind, effect, mismatch) -> list of
    (named first, added) per draw."""
    from fuzzyservo.calibration.search import decide

    out: dict = {}
    for kind, effect, mismatch, seeds in cases(draws):
        rows = []
        for seed in seeds:
            path = cache / f"{kind}_{effect}_{mismatch}_{seed}.pkl"
            if not path.is_file():
                continue
            with path.open("rb") as f:
                replay, rig, model, cost, results = pickle.load(f)
            r = decide(replay, rig, model, results, cost)
            a = r.assessments[0] if r.assessments else None
            rows.append((r.candidates[0].name, r.added, a.verdict if a else "", a.z if a else 0.0,
                         r.threshold, a.reason if a else ""))  # fmt: skip
        out[kind, effect, mismatch] = rows
    return out


def table(results: dict) -> str:
    lines = ["| record | draws | named first | named first and added | added (any) |",
             "|---|---|---|---|---|"]  # fmt: skip
    for (kind, effect, mismatch), rows in results.items():
        n = len(rows)
        if not n:
            continue
        name = f"{effect} + {mismatch}" if effect else f"no effect, {mismatch}"
        if kind.startswith("size"):
            name = f"{effect} at {kind[4:]} × middle + {mismatch}"
        if kind == "fixed":
            name += " (flow gain not declared)"
        first = sum(r[0] == effect for r in rows) if effect else 0
        both = sum(r[0] == effect and r[1] == effect for r in rows) if effect else 0
        added = sum(r[1] is not None for r in rows)
        lines.append(f"| {name} | {n} | {first if effect else '-'} | "
                     f"{both if effect else '-'} | {added} |")  # fmt: skip
    return "\n".join(lines)


def curve_table(results: dict) -> str:
    """Named first and added, by effect and size (the middle one from the power cases)."""
    sizes = (*SIZES, 1.0)
    head = " | ".join(f"{k:g} × middle" for k in sizes)
    lines = [f"| effect | {head} |", "|---" * (len(sizes) + 1) + "|"]
    for effect in MIDDLE:
        cells = []
        for k in sizes:
            kind = "power" if k == 1.0 else f"size{k}"
            rows = results.get((kind, effect, BENCH), [])
            both = sum(r[0] == effect and r[1] == effect for r in rows)
            cells.append(f"{both}/{len(rows)}" if rows else "-")
        lines.append(f"| {effect} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("draws", nargs="?", type=int, default=20)
    parser.add_argument("--cache", type=Path, default=Path(tempfile.gettempdir()) / "power")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--decide-only", action="store_true")
    parser.add_argument("--verbose", action="store_true")
    parser.add_argument(
        "--only",
        default="",
        help="comma-separated effects: fit only their power and size cases (the rest as "
        "cached); 'none' fits the mismatch-only nulls",
    )
    parser.add_argument(
        "--refit",
        default="",
        help="comma-separated candidates to refit "
        "in every cached record (after a change to those effects only)",
    )
    args = parser.parse_args()
    args.cache.mkdir(parents=True, exist_ok=True)
    if args.refit:
        names = frozenset(args.refit.split(","))
        with ProcessPoolExecutor(args.jobs) as pool:
            list(pool.map(_refit, [(path, names) for path in sorted(args.cache.glob("*.pkl"))]))
    elif not args.decide_only:
        only = frozenset(args.only.split(",")) if args.only else None
        # five records a task: the cases' records share out over the jobs
        work = [
            (kind, effect, mismatch, seeds[k : k + 5], args.cache)
            for kind, effect, mismatch, seeds in cases(args.draws)
            if only is None or (effect or "none") in only
            for k in range(0, len(seeds), 5)
        ]
        with ProcessPoolExecutor(args.jobs) as pool:
            list(pool.map(_fit_round, work))
    results = decide_all(args.cache, args.draws)
    if args.verbose:
        for key, rows in results.items():
            for r in rows:
                print(key, r[0], r[1], r[2], f"z {r[3]:.2f} > {r[4]:.2f}", r[5])
    print(table(results))
    print()
    print(curve_table(results))


if __name__ == "__main__":
    main()
