"""Trace the residual to the effect the model lacks: fit every candidate, test it on
held-out data, add the best only when noise alone would rarely do as well; twice.

The decision rounds. Each candidate is the rig with one more effect of
:data:`~fuzzyservo.components.effects.LIBRARY` switched on, fitted so that it never ends
above the model it extends (:mod:`~fuzzyservo.calibration.candidates`). Candidates are ranked by held-out cost (among
candidates the data cannot tell apart, the one with the fewest parameters first); a
long record's candidates are fitted on the first ``SCREEN_SAMPLES`` of its training
part and the best refitted on all of it. The best is added (:func:`decide`) when its
held-out likelihood ratio over the current model passes
:mod:`~fuzzyservo.calibration.decision`'s test (error rate ``ALPHA`` split over the
candidates, and the record's own null, :mod:`~fuzzyservo.calibration.null`) and it
matters physically (:mod:`~fuzzyservo.calibration.significance`). Candidates that pass
too and that the best does not beat on the held-out data are reported as
``ambiguous_with`` (the data cannot tell them apart). The decision never looks at how
the data was made.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from fuzzyservo.calibration import gains as _gains
from fuzzyservo.calibration.candidates import (
    SCREEN_SAMPLES,
    Candidate,
    candidate_effects,
    fit,
    screened_replay,
)
from fuzzyservo.calibration.decision import held_out_evidence, threshold
from fuzzyservo.calibration.identifiability import Separation, separating_experiments
from fuzzyservo.calibration.intervals import fitted_intervals, frozen_ends
from fuzzyservo.calibration.null import DRAWS, SEED, Assessment, Null, assess, null_round
from fuzzyservo.calibration.replay import Replay
from fuzzyservo.calibration.uncertainty import (
    Estimate,
)
from fuzzyservo.components.effects import LIBRARY
from fuzzyservo.controllers.base import Controller
from fuzzyservo.executor import make_executor
from fuzzyservo.rig import Rig

JUDGED = 3  # candidates of a round judged and reported (size, z, interval, limit)


@dataclass(frozen=True)
class Round:
    """One pass over the library: the model it started from and its ranked candidates."""

    start_cost_val: float
    # best first: by held-out cost (an established special case of it ahead: _established_first)
    candidates: tuple[Candidate, ...]
    added: str | None
    threshold: float = math.inf  # the z the best had to exceed
    ambiguous_with: tuple[str, ...] = ()  # candidates the data cannot tell from the best
    experiments: tuple[Separation, ...] = ()  # excitations that would separate them, best first
    null: Null | None = None  # the record's null: threshold and false-positive rate (null.py)
    # the best candidates judged against it (the added one first if any), and for those
    # not added, the experiment that drives each furthest from the round's starting model
    assessments: tuple[Assessment, ...] = ()
    establish: tuple[tuple[str, Separation, float], ...] = ()  # (name, experiment, D recorded)
    start_cost_train: float = math.nan  # the starting model's training cost (no fit ends above)


@dataclass(frozen=True)
class SearchOutcome:
    """What calibration concluded."""

    declared: Rig
    nominal: Rig  # the declared rig with its unknowns fitted
    calibrated: Rig
    added: tuple[Candidate, ...]
    rounds: tuple[Round, ...]
    noise_cost: float
    cost_declared: float
    cost_nominal: float
    cost_final: float
    models: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)
    seconds: float = 0.0
    controller: Controller | None = None  # the replay's controller, with fitted gains
    uncertainty: dict[str, Estimate] = field(default_factory=dict)  # field -> 95 % interval
    # several records (joint.py): field -> its fitted value in each record
    per_record: dict[str, tuple[float, ...]] = field(default_factory=dict)


def search_effects(
    replay: Replay,
    rig: Rig,
    *,
    effects: Sequence[str] | None = None,
    max_effects: int = 2,
    progress: Callable[[str], None] | None = None,
    workers: int = 1,
    screen_samples: int | None = SCREEN_SAMPLES,
    cluster: str | None = None,
    bootstrap_draws: int = DRAWS,
) -> SearchOutcome:
    """Fit the rig's unknowns, then add up to ``max_effects`` effects from the library.

    ``workers`` > 1 fits a round's candidates in that many processes, ``cluster`` (a Dask
    scheduler, ``tcp://HOST:PORT``) on its workers (:mod:`fuzzyservo.executor`; each
    candidate is independent of the others, the results are the same); ``progress`` gets
    each candidate's name as it ends. A training part SCREEN_RATIO times longer
    than ``screen_samples`` (None: never) screens the candidates on its first
    ``screen_samples`` and refits the best on all of it (:func:`_confirm`).
    Each round's decision is calibrated on ``bootstrap_draws`` surrogate records of its
    residual (null.py; 0: decision.py's threshold alone) and an effect is added only
    when it matters (:func:`~fuzzyservo.calibration.null.assess`).
    """
    start = time.perf_counter()
    names = candidate_effects(rig, effects)
    noise = replay.noise_cost()
    held_out = slice(replay.split, None)
    declared_model, _ = replay.run(rig)
    cost_declared = replay.cost(declared_model, held_out)
    nominal, current_model, cost_nominal = rig, declared_model, cost_declared
    # what the user sees: each model run through the record (a segmented replay's fit
    # and test restart it; segments.py), its channels kept where they are that already
    shown = {"declared": _shown(replay, rig, declared_model)}
    if rig.unknowns or _gains.gain_unknowns(replay.controller, replay.drive == "ref"):
        nominal, fitted = fit(replay, rig, None, max_evaluations=120)
        current_model, cost_nominal = fitted.model, fitted.cost_val
        # the effects are then fitted from the fitted gains on
        replay = replay.with_controller(
            _gains.with_gains(replay.controller, fitted.unknowns)
        ).with_values(fitted.unknowns)
    shown["nominal"] = _shown(replay, nominal, current_model)
    current = nominal
    cost = cost_nominal
    added: list[Candidate] = []
    rounds: list[Round] = []
    executor = make_executor(max(1, min(workers, len(names))), cluster)
    try:
        for _ in range(max_effects):
            todo = [name for name in names if name not in current.effects]
            if not todo:  # every allowed effect is in already
                break
            task = functools.partial(_candidate, replay, current, current_model,
                                     screen=screen_samples)  # fmt: skip
            done = None if progress is None else (lambda k, todo=todo: progress(todo[k]))
            results = executor.map(task, todo, done)
            results.sort(
                key=lambda c: (c.score, c.name)
            )  # ties: by name, not by which worker ended first
            screened = screened_replay(replay, screen_samples) is not replay
            if screened:
                results = _confirm(replay, current, current_model, results)
            frozen = frozen_ends(replay, current, added, current_model)
            decided = decide(replay, current, current_model, results, cost, frozen=frozen,
                             screened=screened, draws=bootstrap_draws,
                             seed=SEED + len(rounds))  # fmt: skip
            rounds.append(decided)
            accept = decided.added is not None
            best = decided.candidates[0] if accept else None
            if not accept:
                break
            added.append(best)
            # the next round fits each candidate with the effects added so far refitted
            # along (their parameters unknowns in the boxes their fits had)
            current = _freed(best)
            current_model, cost = best.model, best.cost_val
            replay = replay.with_values(best.unknowns)
    finally:
        executor.close()
    current = dataclasses.replace(current, unknowns=dict(rig.unknowns))
    added = [dataclasses.replace(c, params=current.effect_values(c.name)) for c in added]
    uncertainty = fitted_intervals(replay, current, added, current_model)
    shown["calibrated"] = _shown(replay, current, current_model)
    models = {key: model for key, (model, _) in shown.items()}
    costs = {key: cost for key, (_, cost) in shown.items()}
    return SearchOutcome(
        declared=rig,
        nominal=nominal,
        calibrated=current,
        added=tuple(added),
        rounds=tuple(rounds),
        noise_cost=noise,
        cost_declared=costs["declared"],
        cost_nominal=costs["nominal"],
        cost_final=costs["calibrated"],
        models=models,
        seconds=time.perf_counter() - start,
        controller=replay.controller,
        uncertainty=uncertainty,
        per_record=dict(replay.values),
    )


def _shown(
    replay: Replay, rig: Rig, model: dict[str, np.ndarray]
) -> tuple[dict[str, np.ndarray], float]:
    """``rig``'s channels run through the record, and their held-out cost: ``model``
    when ``replay`` is not segmented (segments.py)."""
    whole = replay.whole()
    if whole is not replay:
        model = whole.run(rig)[0]
    return model, whole.cost(model, slice(whole.split, None))


def decide(
    replay: Replay,
    current: Rig,
    current_model: dict[str, np.ndarray],
    results: list[Candidate],
    cost: float,
    *,
    frozen: Sequence[Sequence[dict[str, np.ndarray]]] = (),
    screened: bool = False,
    draws: int = DRAWS,
    seed: int = SEED,
) -> Round:
    """One round's decision on its fitted candidates (``results``, by held-out cost) over
    the starting model ``current`` (channels ``current_model``, held-out cost ``cost``):
    the record's null (null.py), parsimony among the forms of one law, the judgement of
    the best few and, when none is added, the experiments that would establish them.
    ``frozen``: the starting model's channels at the ends of its earlier effects'
    intervals (:func:`frozen_ends`)."""
    results = list(results)
    null = null_round(replay, current_model, [c.model for c in results],
                      draws=draws, seed=seed, frozen=frozen)  # fmt: skip
    z_min = null.threshold
    results = _established_first(replay, current, current_model, results, z_min,
                                 screened=screened)  # fmt: skip
    best = results[0] if results else None
    significant = best is not None and _significant(best, z_min)
    # told apart only by Bonferroni's margin: a tie is the cautious claim, and the max-T
    # threshold (null.py) is calibrated for the best against the starting model
    tie_z = max(z_min, null.bonferroni)
    ambiguous = _ties(replay, results, z_min, tie_z) if significant else ()
    if ambiguous:  # parsimony: the simplest of the tied forms of the best's law
        tied = [c for c in results if c.name in (best.name, *ambiguous)]
        # a special case of the best's law goes first unless the best beats it at the
        # one-test level: whether the extra parameters are needed is one nested
        # comparison, not a choice among many (the max-T and Bonferroni margins are
        # for that); on the Festo record Stribeck's law beats Coulomb's with a
        # pre-sliding distance on its bound (held-out cost 117 against 246), and on the
        # independent generator's sticking friction it beats it in most draws
        same_law = [c for c in tied if c is best or (
            c.name in _special_cases(best) and _tied(replay, best, c, threshold(1)))]  # fmt: skip
        simplest = min(same_law, key=lambda c: (c.n_params, c.score))
        if simplest is not best:
            results.remove(simplest)
            results.insert(0, simplest)
            ambiguous = tuple(c.name for c in tied if c is not simplest)
            best = simplest
    judged = _judge(replay, current, current_model, results, null)
    accept = bool(judged) and judged[0].verdict == "added"
    if not accept:
        ambiguous = ()
    experiments: tuple[Separation, ...] = ()
    first = getattr(replay, "records", (replay,))[0]
    if ambiguous:
        tied = {c.name: c.rig for c in results if c.name in (best.name, *ambiguous)}
        experiments = tuple(separating_experiments(first, tied))
    establish = () if accept else _establishing(first, current, results, judged)
    return Round(
        cost,
        tuple(results),
        best.name if accept else None,
        threshold=z_min,
        ambiguous_with=ambiguous,
        experiments=experiments,
        null=null,
        assessments=judged,
        establish=establish,
        start_cost_train=replay.cost(current_model, slice(0, replay.split)),
    )


def _candidate(
    replay: Replay,
    base: Rig,
    base_model: dict[str, np.ndarray],
    name: str,
    screen: int | None = None,
    start_from: Candidate | None = None,
) -> Candidate:
    """``name`` fitted on top of ``base`` with its held-out evidence against ``base``'s
    channels (a module-level function, so a worker process can run it)."""
    _, candidate = fit(replay, base, name, screen=screen, start_from=start_from)
    evidence = held_out_evidence(replay, base_model, candidate.model)
    return dataclasses.replace(candidate, evidence=evidence)


def _confirm(
    replay: Replay, base: Rig, base_model: dict[str, np.ndarray], ranked: list[Candidate]
) -> list[Candidate]:
    """Screened candidates (best first) with the best refitted on the whole training part,
    from its screening fit; again while the refit moves another screened one first."""
    ranked = list(ranked)
    refitted: set[str] = set()
    while ranked and ranked[0].name not in refitted and math.isfinite(ranked[0].score):
        refit = _refit(replay, base, base_model, ranked.pop(0))
        refitted.add(refit.name)
        ranked.append(refit)
        ranked.sort(key=lambda c: (c.score, c.name))
    return ranked


def _refit(
    replay: Replay, base: Rig, base_model: dict[str, np.ndarray], screened: Candidate
) -> Candidate:
    """``screened`` refitted on the whole training part from its screening fit, its
    evaluations and time counting both fits."""
    refit = _candidate(replay, base, base_model, screened.name, start_from=screened)
    return dataclasses.replace(
        refit,
        evaluations=screened.evaluations + refit.evaluations,
        seconds=screened.seconds + refit.seconds,
    )


def _judge(
    replay: Replay,
    base: Rig,
    base_model: dict[str, np.ndarray],
    ranked: Sequence[Candidate],
    null: Null,
) -> tuple[Assessment, ...]:
    """The first JUDGED candidates against the round's ``null`` (null.assess)."""
    out = []
    for k, c in enumerate(ranked[:JUDGED]):
        z = c.evidence.z if c.evidence is not None else math.nan
        a = assess(replay, base, base_model, c, z, null)
        if k and a.verdict == "added":  # only the first of a round can be added
            a = dataclasses.replace(a, verdict="out-ranked")
        out.append(a)
    return tuple(out)


def _establishing(
    record: Replay, base: Rig, ranked: Sequence[Candidate], judged: Sequence[Assessment]
) -> tuple[tuple[str, Separation, float], ...]:
    """For each judged candidate not established that the data lean towards (z > 0):
    the excitation (identifiability.py) that drives it furthest from ``base``, with the
    distance the recorded experiment gives (noise units). A negligible one is
    established already, and too small to matter: no experiment for it."""
    out = []
    rigs = {c.name: c.rig for c in ranked}
    for a in judged:
        if a.verdict != "not established" or not a.z > 0.0 or rigs.get(a.name) is None:
            continue
        ranked_ex = separating_experiments(record, {"starting model": base, a.name: rigs[a.name]})
        recorded = next((s.distance for s in ranked_ex if s.name == "recorded"), math.nan)
        if ranked_ex and np.isfinite(ranked_ex[0].distance):
            out.append((a.name, ranked_ex[0], recorded))
    return tuple(out)


def _established_first(
    replay: Replay,
    base: Rig,
    base_model: dict[str, np.ndarray],
    ranked: list[Candidate],
    z_min: float,
    *,
    screened: bool,
) -> list[Candidate]:
    """``ranked`` (by held-out cost) with an established special case of the best first
    (``special_cases`` in components/effects.py), when the best by cost is not
    established and the data cannot tell the two apart (the best does not beat it by
    ``z_min`` spreads on the held-out part, as :func:`_ties` asks): parsimony, as for
    tied candidates. On the independent generator's mid-range LuGre friction, Stribeck's
    law (stiction on its bound) predicted the held-out part best with z 3.4 under a
    threshold of 3.7, and Coulomb's (Stribeck's with no stiction), z 36 and not told
    apart from it, was left out: nothing was added in 3 of 4 draws. Only a special case
    moves up (the same law with fewer parameters): another law that the data cannot
    tell from a better predictor they do not establish is a lookalike, not a finding.
    Any candidate above the threshold keeps the round's error rate (the threshold is
    that of the largest z of all candidates, null.py). A screened candidate is refitted
    on the whole training part first (:func:`_confirm`)."""
    if not ranked or _significant(ranked[0], z_min):
        return ranked
    best = ranked[0]

    def promoted(c: Candidate) -> bool:
        return _significant(c, z_min) and _tied(replay, best, c, z_min)

    for k, candidate in enumerate(ranked[1:], start=1):
        if candidate.name not in _special_cases(best) or not promoted(candidate):
            continue
        if screened:
            candidate = _refit(replay, base, base_model, candidate)
            if not promoted(candidate):
                continue
        return [candidate, *ranked[:k], *ranked[k + 1 :]]
    return ranked


def _special_cases(candidate: Candidate) -> tuple[str, ...]:
    """The effects ``candidate``'s law becomes with a parameter at 0 (effects.py)."""
    return LIBRARY[candidate.name].special_cases


def _tied(replay: Replay, best: Candidate, other: Candidate, z_min: float) -> bool:
    """``best`` does not beat ``other`` on the held-out data by ``z_min`` spreads: the
    data cannot tell them apart."""
    return held_out_evidence(replay, other.model, best.model).z < z_min


def _significant(candidate: Candidate, z_min: float) -> bool:
    """The candidate's held-out likelihood ratio over the current model exceeds ``z_min``
    noise spreads (decision.py)."""
    return candidate.evidence is not None and candidate.evidence.z > z_min


def _ties(replay: Replay, ranked: list[Candidate], z_min: float, tie_z: float) -> tuple[str, ...]:
    """Runner-ups that pass the test too (``z_min``) and that the best does not beat on
    the held-out data by ``tie_z`` spreads: the data cannot tell them from the best (and
    more parameters must earn their place as an effect does)."""
    best = ranked[0]
    return tuple(
        other.name
        for other in ranked[1:]
        if _significant(other, z_min) and _tied(replay, best, other, tie_z)
    )


def _freed(best: Candidate) -> Rig:
    """``best``'s rig with its effect's parameters among the unknowns, each in the box
    its fit had (an optional part the fit left off stays off): a later round fits every
    candidate with the effects added before refitted along, so that an effect added
    first gives back what it absorbed of one found later (round 1's Coulomb friction
    takes part of a spool lag's phase; refitted only after the last round, the lag was
    missed in 1 of 8 one-bit changes of a record)."""
    unknowns = dict(best.rig.unknowns)
    for name, box in best.boxes().items():
        unknowns.setdefault(name, box)
    return dataclasses.replace(best.rig, unknowns=unknowns)
