"""Trace the residual to the effect the model lacks: fit every candidate, test it on
held-out data, add the best only when noise alone would rarely do as well; twice.

Grey-box estimation in the manner of MATLAB's ``nlgreyest``: each candidate is the rig
with one more effect of :data:`~fuzzyservo.components.effects.LIBRARY` switched on; its
parameters (and the rig's declared unknowns) are fitted by bounded least squares
(``scipy.optimize.least_squares``, dogleg in the box, finite differences with an
absolute step on the unit box) on the training part of the replay, from several starts,
the starting model (the effect off) among them, so that no candidate ends above the
model it extends (:func:`_minimise`). Candidates are ranked by held-out cost (among
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
import itertools
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares, minimize_scalar

from fuzzyservo.calibration import gains as _gains
from fuzzyservo.calibration.decision import Evidence, held_out_evidence, threshold
from fuzzyservo.calibration.identifiability import Separation, separating_experiments
from fuzzyservo.calibration.joint import record_field, split_field
from fuzzyservo.calibration.null import DRAWS, SEED, Assessment, Null, assess, null_round
from fuzzyservo.calibration.replay import DIVERGED_COST, Replay
from fuzzyservo.calibration.residuals import fit_percent
from fuzzyservo.calibration.uncertainty import (
    Estimate,
    at_bound,
    correlated,
    effective_samples,
    estimates,
    gauss_newton_step,
    held_interval,
)
from fuzzyservo.components.effects import LIBRARY, EffectParam, owner
from fuzzyservo.controllers.base import Controller
from fuzzyservo.executor import make_executor
from fuzzyservo.rig import Rig

SCAN = (0.0, 0.25, 0.5, 0.75, 1.0)  # grid of each parameter (unit interval)
SCAN_FINE = tuple(np.linspace(0.05, 0.95, 10))  # scan of a single parameter
# A single parameter's scan is refined coarse-to-fine: at each level the spacing halves
# around the REFINE_KEEP best points seen so far, REFINE_LEVELS times, before Brent. A
# cost that oscillates in its parameter (a bulk modulus sets the phase of the pressure
# oscillation) has valleys narrower than the scan's spacing; refining only the best
# point follows whichever valley the coarse scan happened to land nearest.
REFINE_KEEP = 3
REFINE_LEVELS = 2
START = 0.3  # start of the other parameters (unit interval)
JACOBIAN_STEP = 0.01  # absolute finite-difference step on the unit box
# Candidates of a long record are screened on the first SCREEN_SAMPLES of its training
# part (a replay costs its length); the round's best is then refitted on all of it from
# there, and its held-out test is made again, before it is added. Only a training part
# at least SCREEN_RATIO times as long is screened: an effect that shows only after the
# window is lost to the screening (the Festo record, 11 242 training samples whose last
# ones start the lowering, loses its Stribeck friction when screened on 10 000).
SCREEN_SAMPLES = 10_000
SCREEN_RATIO = 3
LOCAL_STARTS = 2  # local searches from the best starts of a candidate's fit
JUDGED = 3  # candidates of a round judged and reported (size, z, interval, limit)


@dataclass(frozen=True)
class Candidate:
    """One effect fitted on the training part and scored on the held-out part."""

    name: str
    params: dict[str, float]  # effect parameter key -> SI value
    unknowns: dict[str, float]  # rig unknown field -> SI value fitted with it
    n_params: int
    cost_train: float
    cost_val: float
    score: float  # the ranking key: held-out cost (inf for a failed run)
    fit_val: dict[str, float]
    status: str
    evaluations: int
    seconds: float
    model: dict[str, np.ndarray] = field(
        default_factory=dict, repr=False
    )  # channels on the data grid
    evidence: Evidence | None = None  # held-out test against the round's starting model
    rig: Rig | None = field(default=None, repr=False, compare=False)  # the fitted rig
    # the box each effect parameter was fitted in (field -> (lo, hi) SI): the rig's scales
    # move with its fitted unknowns, so a later round's box may not hold the value
    bounds: dict[str, tuple[float, float]] = field(default_factory=dict, repr=False, compare=False)


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
class Outcome:
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


@dataclass
class _Space:
    """Parameters being fitted, each mapped from the unit interval (cubic for log ones)."""

    names: list[tuple[str, str]]  # (effect name or "", field)
    bounds: list[tuple[float, float]]
    log: list[bool]

    def subset(self, keep: Sequence[int]) -> _Space:
        """The parameters at positions ``keep``, in that order."""
        return _Space(
            [self.names[j] for j in keep],
            [self.bounds[j] for j in keep],
            [self.log[j] for j in keep],
        )

    def _geometric(self, j: int) -> bool:
        """Positive bounds spanning more than two decades map geometrically."""
        lo, hi = self.bounds[j]
        return lo > 0 and hi / lo > 100

    def value(self, j: int, z: float) -> float:
        lo, hi = self.bounds[j]
        z = min(max(z, 0.0), 1.0)
        if self._geometric(j):
            return lo * (hi / lo) ** z
        return lo + (hi - lo) * (z**3 if self.log[j] else z)

    def unit(self, j: int, value: float) -> float:
        lo, hi = self.bounds[j]
        if self._geometric(j):
            z = math.log(max(value, lo) / lo) / math.log(hi / lo)
        else:
            z = (value - lo) / (hi - lo) if hi > lo else 0.0
        z = min(max(z, 0.0), 1.0)
        if self.log[j] and not self._geometric(j):
            return z ** (1.0 / 3.0)
        return z


class _Objective:
    """Replays of one candidate family with a cache (least squares revisits points).

    The search looks only at the training part, so its replays stop there (a third less
    simulation); the chosen point is then replayed in full."""

    def __init__(self, replay: Replay, base: Rig, effect: str | None, space: _Space):
        self.replay = replay
        self.base = base.with_effect(effect) if effect else base
        self.effect = effect
        self.space = space
        self.cache: dict[tuple[tuple[float, ...], bool], tuple[dict[str, np.ndarray], str]] = {}

    def rig(self, z: Sequence[float]) -> Rig:
        values = {
            f: self.space.value(j, z[j])
            for j, (_, f) in enumerate(self.space.names)
            if not _gains.is_gain(f) and split_field(f) is None
        }
        return self.base.with_params(**values) if values else self.base

    def record_values(self, z: Sequence[float]) -> dict[str, list[float]]:
        """Per-record values (joint.py) at ``z``: field -> one value per record."""
        values = {f: list(v) for f, v in self.replay.values.items()}
        for j, (_, name) in enumerate(self.space.names):
            parsed = split_field(name)
            if parsed:
                values[parsed[0]][parsed[1]] = self.space.value(j, z[j])
        return values

    def run(self, z: Sequence[float], training: bool) -> tuple[dict[str, np.ndarray], str]:
        rig, controller = self.rig(z), self.controller(z)
        if self.replay.per_record:
            values = self.record_values(z)
            return self.replay.run(rig, controller, values, training=training)
        return self.replay.run(rig, controller, training=training)

    def controller(self, z: Sequence[float]) -> Controller:
        values = {f: self.space.value(j, z[j]) for j, (_, f) in enumerate(self.space.names)}
        return _gains.with_gains(self.replay.controller, values)

    def model(
        self, z: Sequence[float], training: bool = False
    ) -> tuple[dict[str, np.ndarray], str]:
        """Model channels at ``z``: all of them, or (``training``) the training part."""
        point = tuple(round(float(v), 12) for v in z)
        if (point, False) in self.cache:  # a full replay serves a training one too
            return self.cache[point, False]
        key = (point, training)
        if key not in self.cache:
            try:
                self.cache[key] = self.run(z, training)
            except ValueError:  # a parameter set the plant rejects (e.g. geometry)
                nan = np.full(self.replay.t.size, np.nan)
                self.cache[key] = ({c: nan for c in self.replay.channels}, "rejected")
        return self.cache[key]

    def residuals(self, z: np.ndarray) -> np.ndarray:
        return self.replay.residual_vector(self.model(z, training=True)[0])

    def train_cost(self, z: Sequence[float]) -> float:
        model = self.model(z, training=True)[0]
        return self.replay.cost(model, slice(0, self.replay.split))


def _space(rig: Rig, effect: str | None, replay: Replay | None = None) -> _Space:
    names: list[tuple[str, str]] = []
    bounds: list[tuple[float, float]] = []
    log: list[bool] = []
    if effect is not None:
        scales = rig.scales()
        for param in LIBRARY[effect].fitted:
            names.append((effect, param.field))
            bounds.append(_bounds(rig, param, scales))
            log.append(param.log)
    per_record = replay.per_record if replay is not None else {}
    for fieldname, (lo, hi) in rig.unknowns.items():
        if any(f == fieldname for _, f in names) or fieldname in per_record:
            continue
        names.append((owner(fieldname) or "", fieldname))
        bounds.append((lo, hi))
        log.append(False)
    for fieldname, (lo, hi) in per_record.items():  # one value per record (joint.py)
        for k in range(len(replay.values[fieldname])):
            names.append(("", record_field(fieldname, k)))
            bounds.append((lo, hi))
            log.append(False)
    if replay is not None:  # controller gains declared unknown (calibration/gains.py)
        for name, (lo, hi) in _gains.gain_unknowns(
            replay.controller, replay.drive == "ref"
        ).items():
            names.append(("", name))
            bounds.append((lo, hi))
            log.append(False)
    return _Space(names, bounds, log)


def _bounds(rig: Rig, param: EffectParam, scales) -> tuple[float, float]:
    if param.field in rig.unknowns:
        return rig.unknowns[param.field]
    return param.value_bounds(scales)


def fit(
    replay: Replay,
    base: Rig,
    effect: str | None,
    *,
    max_evaluations: int = 60,
    screen: int | None = None,
    start_from: Candidate | None = None,
) -> tuple[Rig, Candidate]:
    """Fit ``effect`` (None: only the rig's unknowns) on the training part; score it.

    The fit starts from several points (:func:`_minimise`), the starting model among
    them (the effect off, the unknowns as they are), so it never ends above the starting
    model's training cost: a candidate contains the model it extends. ``screen``: fit the
    effect's parameters on the first ``screen`` training samples only, the rig's unknowns
    held (they were fitted on the whole training part; refitted on a window they drift
    to it); the score still takes the whole held-out part. ``start_from``: a fit of the
    same effect (e.g. a screening one) to refine, unknowns included, without the scan."""
    start = time.perf_counter()
    full = _space(base, effect, replay)
    fitted_on = _screened(replay, screen)
    space = full if fitted_on is replay else _only(full, effect)
    objective = _Objective(fitted_on, base, effect, space)
    n_effect = sum(1 for owner, _ in space.names if owner == effect) if effect else 0
    z_start = _start_point(replay, base, effect, space)
    z_from = None
    if start_from is not None:
        known = dict(start_from.unknowns)
        for param in LIBRARY[effect].fitted if effect else ():
            known[param.field] = float(getattr(start_from.rig.params, param.field))
        z_from = np.array([space.unit(j, known[f]) for j, (_, f) in enumerate(space.names)])
    optional = _optional(space, effect)
    if optional and start_from is None:
        z, nested, nested_runs = _minimise_nested(fitted_on, base, effect, space, objective,
                                                  z_start, n_effect, optional,
                                                  max_evaluations)  # fmt: skip
        # the optional parts stay only if they also predict the held-out part better
        judge = objective if fitted_on is replay else _Objective(replay, base, effect, space)
        if replay.costs(judge.model(nested)[0])[1] <= replay.costs(judge.model(z)[0])[1]:
            z = nested
    else:
        nested_runs = 0
        z = _minimise(objective, z_start, n_effect, max_evaluations, scan=start_from is None,
                      z_from=z_from)  # fmt: skip
    cost_start = objective.train_cost(z_start)
    status_note = ""
    if not objective.train_cost(z) <= cost_start:  # only a start that cannot be replayed
        status_note = (
            f"failed fit: its training cost {objective.train_cost(z):.4g} ends above the "
            f"starting model's {cost_start:.4g}"
        )
    elif fitted_on is not replay:  # screened: the whole training part must agree
        whole = _Objective(replay, base, effect, space)
        if whole.train_cost(z) > whole.train_cost(z_start):
            z = z_start  # what the window found does not carry over: nothing better
    rig = objective.rig(z)
    model, status = objective.model(z)
    cost_train, cost_val = replay.costs(model)
    params = rig.effect_values(effect) if effect else {}
    unknowns = {
        f: space.value(j, z[j]) for j, (owner, f) in enumerate(space.names) if owner != effect
    }
    for owner_f, f in full.names:  # held ones (screening) as they are
        if owner_f != effect and f not in unknowns:
            unknowns[f] = _start(replay, base, f)
    candidate = Candidate(
        name=effect or "none",
        params=params,
        unknowns=unknowns,
        n_params=n_effect,
        cost_train=cost_train,
        cost_val=cost_val,
        score=cost_val if cost_val < DIVERGED_COST else math.inf,
        fit_val=fit_table(replay, model),
        status=status_note or status,
        evaluations=len(objective.cache) + nested_runs,
        seconds=time.perf_counter() - start,
        model=model,
        rig=rig,
        bounds={f: full.bounds[j] for j, (o, f) in enumerate(full.names) if effect and o == effect},
    )
    return rig, candidate


def _only(space: _Space, effect: str | None) -> _Space:
    """``space`` cut to ``effect``'s own parameters (the rest held as they are)."""
    return space.subset(
        [j for j, (owner, _) in enumerate(space.names) if effect and owner == effect]
    )


def _start_point(replay: Replay, base: Rig, effect: str | None, space: _Space) -> np.ndarray:
    """The starting model on the unit box: ``effect`` off (0, or the end of its bounds
    where it does least: a bulk modulus at the oil's, an unlimited pump;
    ``EffectParam.off_at_upper``), everything else at its current value."""
    z = []
    for j, (of, f) in enumerate(space.names):
        if effect and of == effect:
            param = LIBRARY[effect].param_by_field(f)
            z.append(1.0 if param.off_at_upper else space.unit(j, 0.0))
        else:
            z.append(space.unit(j, _start(replay, base, f)))
    return np.array(z, dtype=float)


def _start(replay: Replay, rig: Rig, name: str) -> float:
    """The current value of a fitted quantity: a controller gain, a per-record value
    (joint.py) or a rig parameter."""
    if _gains.is_gain(name):
        return _gains.gain_value(replay.controller, name)
    parsed = split_field(name)
    if parsed:
        return replay.values[parsed[0]][parsed[1]]
    return float(getattr(rig.params, name))


def _screened(replay: Replay, screen: int | None) -> Replay:
    """``replay`` with its training part cut to its first ``screen`` samples (a single
    record whose training part is SCREEN_RATIO times as long), else ``replay`` itself."""
    if screen is None or not isinstance(replay, Replay) or replay.split < SCREEN_RATIO * screen:
        return replay
    return dataclasses.replace(replay, split=screen)


def _minimise(
    objective: _Objective,
    z_start: np.ndarray,
    n_effect: int,
    budget: int,
    *,
    scan: bool = True,
    z_from: np.ndarray | None = None,
) -> np.ndarray:
    """The best point on the unit box from several starts, never worse than ``z_start``
    (the starting model). The starts: ``z_start``; with ``scan``, a scan of each effect
    parameter in turn from START (the cost is not convex in a delay, a time constant, a
    dead band or stiction, and least squares alone gets caught where friction makes the
    cost rough; a single one refined coarse-to-fine around its best few points,
    :func:`_scan`) and one Gauss-Newton step from ``z_start`` (the estimate the
    residual's projection on the effect's own sensitivity gives); ``z_from``: a
    previous fit to refine. A local search (bounded Brent for a single parameter,
    trust-region least squares for several) runs from the best of them, and with
    ``scan`` from the runner-up too (LOCAL_STARTS)."""
    n = z_start.size
    if n == 0:
        return z_start.copy()
    grid = SCAN_FINE if n == 1 else SCAN
    step = (grid[1] - grid[0]) / 2**REFINE_LEVELS
    starts = [z_start.copy()]
    if z_from is not None:
        starts.append(np.clip(z_from, 0.0, 1.0))
    # a single unknown alone (the nominal fit) is scanned over its whole bounds as an
    # effect parameter is (Brent alone looks only within a step of its start)
    if scan and (n_effect or n == 1):
        z = z_start.copy()
        z[:n_effect] = START
        if n_effect <= 1:
            z[0], step = _scan(lambda v: objective.train_cost([v, *z[1:]]), grid)
        else:
            # a full grid over the effect's parameters: friction with stiction trades its
            # parameters against each other and a coordinate search stalls
            best = min(itertools.product(SCAN, repeat=n_effect),
                       key=lambda point: objective.train_cost([*point, *z[n_effect:]]))  # fmt: skip
            z[:n_effect] = best
        starts.append(z)
    if scan and n_effect:
        starts.append(_gauss_newton(objective, z_start))
    ranked = sorted(_distinct(starts), key=objective.train_cost)
    local = [_local(objective, z, step, budget) for z in ranked[: LOCAL_STARTS if scan else 1]]
    return min([*local, *ranked], key=objective.train_cost)


def _optional(space: _Space, effect: str | None) -> list[int]:
    """Positions in ``space`` of ``effect``'s optional parameters (EffectParam.optional:
    a spool's second time constant, friction's pre-sliding distance)."""
    if not effect:
        return []
    return [
        j
        for j, (owner, f) in enumerate(space.names)
        if owner == effect and LIBRARY[effect].param_by_field(f).optional
    ]


def _minimise_nested(
    replay: Replay,
    base: Rig,
    effect: str,
    space: _Space,
    objective: _Objective,
    z_start: np.ndarray,
    n_effect: int,
    optional: list[int],
    budget: int,
) -> tuple[np.ndarray, np.ndarray, int]:
    """:func:`_minimise` for an effect with optional parts, which nests the law without
    them (a first-order spool, friction that does not stick): that law is fitted first,
    as it would be alone, then each optional part is scanned from its fit with the rest
    held, and the best of those points joins the starts of the whole law's own search
    (:func:`_minimise`; its grid only if one of those points beats the nested fit).
    Returns the best point, the nested law's fit and the replays that fit took; the
    first is never worse on the training part than the second: adding a parameter
    cannot lose to the model it extends (the issue-40 invariant, one level down). The caller keeps the optional parts only where they
    also predict the held-out part better (on the Festo record, a pre-sliding distance
    on its bound fits the training part better and the held-out part worse)."""
    keep = [j for j in range(z_start.size) if j not in optional]
    sub = _Objective(replay, base, effect, space.subset(keep))
    nested = z_start.copy()
    nested[keep] = _minimise(sub, z_start[keep], n_effect - len(optional), budget)
    starts = [nested]
    for j in optional:
        for v in SCAN[1:]:
            point = nested.copy()
            point[j] = v
            starts.append(point)
    ranked = sorted(_distinct(starts), key=objective.train_cost)
    # the whole law searched as any effect is, from those points too: with its optional
    # parts on it sits in another valley (sticking friction holds a piston with other
    # stiction than creeping friction does). Its grid over every parameter (5^4 replays
    # for Stribeck's law) only where an optional part helps the nested fit by itself;
    # else a local search of the whole law from that fit (a second spool time constant
    # helps only with the first made shorter: the lag is shared between them)
    helps = ranked[0] is not nested
    z = _minimise(objective, z_start, n_effect, budget, scan=helps, z_from=ranked[0])
    return z, nested, len(sub.cache)


def _distinct(points: Sequence[np.ndarray], tol: float = 1e-6) -> list[np.ndarray]:
    out: list[np.ndarray] = []
    for p in points:
        if all(np.max(np.abs(p - q)) > tol for q in out):
            out.append(p)
    return out


def _gauss_newton(objective: _Objective, z: np.ndarray) -> np.ndarray:
    """One Gauss-Newton step from ``z`` on the unit box, clipped to it: where the
    training residual's projection on each parameter's sensitivity puts it."""
    jac = _jacobian(objective.residuals, z)
    r = objective.residuals(z)
    if not (np.isfinite(jac).all() and np.isfinite(r).all()):
        return z.copy()
    step, *_ = np.linalg.lstsq(jac, -r, rcond=None)
    return np.clip(z + step, 0.0, 1.0)


def _local(objective: _Objective, z: np.ndarray, step: float, budget: int) -> np.ndarray:
    """Bounded Brent within ``step`` of ``z`` for one parameter, trust-region least
    squares for several; ``z`` itself if that does not improve on it."""
    n = z.size
    if n == 1:
        sol = minimize_scalar(
            lambda v: objective.train_cost([v]),
            bounds=(max(z[0] - step, 0.0), min(z[0] + step, 1.0)),
            method="bounded",
            options={"xatol": 1e-5, "maxiter": 40},
        )
        best = np.array([sol.x])
    else:
        sol = least_squares(
            objective.residuals,
            z,
            jac=lambda x: _jacobian(objective.residuals, x),
            bounds=(np.zeros(n), np.ones(n)),
            # dogbox, not trf: trf scales a step by the distance to the bound, so from a
            # parameter at 0 (an effect off) it stops after two tiny steps
            method="dogbox",
            xtol=1e-4,
            ftol=1e-4,
            max_nfev=max(budget, 15 * (n + 1)),
        )
        best = sol.x
    return best if objective.train_cost(best) <= objective.train_cost(z) else z


def _scan(cost: Callable[[float], float], grid: Sequence[float]) -> tuple[float, float]:
    """The best point of a coarse-to-fine scan of one parameter on the unit interval and
    the spacing around it: ``grid`` (evenly spaced), then REFINE_LEVELS times the
    midpoints on either side of the REFINE_KEEP best points seen so far."""
    seen: dict[float, float] = {}

    def look(v: float) -> None:
        v = round(float(v), 12)
        if 0.0 <= v <= 1.0 and v not in seen:
            seen[v] = cost(v)

    for g in grid:
        look(g)
    step = grid[1] - grid[0]
    for _ in range(REFINE_LEVELS):
        step /= 2
        for v in sorted(seen, key=seen.__getitem__)[:REFINE_KEEP]:
            look(v - step)
            look(v + step)
    return min(seen, key=seen.__getitem__), step


def _jacobian(
    residuals: Callable[[np.ndarray], np.ndarray], z: np.ndarray, step: float = JACOBIAN_STEP
) -> np.ndarray:
    """Forward differences with an absolute step on the unit box, taken inward at the
    upper bound. scipy's ``diff_step`` is relative to the point, so at z = 0 (an effect
    off, a delay whose best grid point is 0) its step is ~1e-8 and the search cannot
    leave 0; on the unit box one step size suits every parameter whatever its unit."""
    r0 = residuals(z)
    jac = np.empty((r0.size, z.size))
    for j in range(z.size):
        h = step if z[j] + step <= 1.0 else -step
        trial = z.copy()
        trial[j] += h
        jac[:, j] = (residuals(trial) - r0) / h
    return jac


def fit_table(replay: Replay, model: dict[str, np.ndarray]) -> dict[str, float]:
    """Held-out fit % per channel (MATLAB ``compare``); NaN for a channel whose held-out
    part does not move (:meth:`~fuzzyservo.calibration.replay.Scored.still_channels`:
    the fit divides by its spread, which is then rounding or noise)."""
    part = slice(replay.split, None)
    still = replay.still_channels()
    return {
        c: math.nan if c in still else fit_percent(replay.measured(c)[part], model[c][part])
        for c in replay.channels
    }


def candidate_effects(rig: Rig, effects: Sequence[str] | None = None) -> list[str]:
    """The effects a calibration of ``rig`` may add: those of ``effects`` (default: the
    :data:`~fuzzyservo.components.effects.LIBRARY`'s screened effects, in its order) that
    the rig's plant models and the rig does not declare already."""
    allowed = [e for e in LIBRARY if LIBRARY[e].screened] if effects is None else effects
    return [e for e in allowed if e in rig.plant.effects and e not in rig.effects]


def calibrate(
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
) -> Outcome:
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
    if rig.unknowns or _gains.gain_unknowns(replay.controller, replay.drive == "ref"):
        nominal, fitted = fit(replay, rig, None, max_evaluations=120)
        current_model, cost_nominal = fitted.model, fitted.cost_val
        # the effects are then fitted from the fitted gains on
        replay = replay.with_controller(
            _gains.with_gains(replay.controller, fitted.unknowns)
        ).with_values(fitted.unknowns)
    current = nominal
    cost = cost_nominal
    models = {"declared": declared_model, "nominal": current_model}
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
            results.sort(key=lambda c: c.score)
            screened = _screened(replay, screen_samples) is not replay
            if screened:
                results = _confirm(replay, current, current_model, results)
            frozen = _frozen_ends(replay, current, added, current_model)
            decided = decide(replay, current, current_model, results, cost, frozen=frozen,
                             screened=screened, draws=bootstrap_draws,
                             seed=SEED + len(rounds))  # fmt: skip
            rounds.append(decided)
            accept = decided.added is not None
            best = decided.candidates[0] if accept else None
            if not accept:
                break
            added.append(best)
            current, current_model, cost = best.rig, best.model, best.cost_val
            replay = replay.with_values(best.unknowns)
    finally:
        executor.close()
    if len(added) > 1:
        current, added, current_model, cost, refitted = _refit_jointly(
            replay, current, added, current_model, cost
        )
        replay = replay.with_values(refitted)
    models["calibrated"] = current_model
    uncertainty = _uncertainty(replay, current, added, current_model)
    return Outcome(
        declared=rig,
        nominal=nominal,
        calibrated=current,
        added=tuple(added),
        rounds=tuple(rounds),
        noise_cost=noise,
        cost_declared=cost_declared,
        cost_nominal=cost_nominal,
        cost_final=cost,
        models=models,
        seconds=time.perf_counter() - start,
        controller=replay.controller,
        uncertainty=uncertainty,
        per_record=dict(replay.values),
    )


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
    intervals (:func:`_frozen_ends`)."""
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
        ranked.sort(key=lambda c: c.score)
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


def _uncertainty(
    replay: Replay, rig: Rig, added: Sequence[Candidate], model: dict[str, np.ndarray]
) -> dict[str, Estimate]:
    """95 % intervals and at-bound flags of every fitted value: the rig's unknowns and the
    added effects' parameters (uncertainty.py): the sandwich of one Jacobian at the final
    model, widened by each parameter's profile on the training part (the parameters it
    is correlated with following it, uncertainty.correlated)."""
    unknowns = dict(rig.unknowns)
    for candidate in added:  # each in the box its fit had (the value's bounds as reported)
        for param in LIBRARY[candidate.name].fitted:
            unknowns.setdefault(param.field, candidate.bounds[param.field])
    if not unknowns:
        return {}
    joint = dataclasses.replace(rig, unknowns=unknowns)
    space = _space(joint, None)
    for name in replay.per_record:  # a per-record value (joint.py) in each record
        j = next(j for j, (_, f) in enumerate(space.names) if f == name)
        lo_hi, is_log = space.bounds.pop(j), space.log.pop(j)
        space.names.pop(j)
        for k in range(len(replay.values[name])):
            space.names.append(("", record_field(name, k)))
            space.bounds.append(lo_hi)
            space.log.append(is_log)
    objective = _Objective(replay, joint, None, space)
    values = [_start(replay, rig, f) for _, f in space.names]
    z = np.array([space.unit(j, v) for j, v in enumerate(values)])
    jac = _jacobian(objective.residuals, z)
    channels = len(replay.channels)
    follows = correlated(jac)

    def cost(j: int, v: float) -> np.ndarray:  # each training sample's, parameter j at v
        trial = z.copy()
        trial[j] = v
        r = objective.residuals(trial)
        # the values it trades with follow it down the valley; all others where it sits
        # on a bound (a one-sided Jacobian there tells little of correlation)
        others = np.flatnonzero(np.arange(z.size) != j) if at_bound(z[j]) else follows[j]
        if others.size:
            moved = trial.copy()
            moved[others] = gauss_newton_step(jac[:, others], r, z[others])
            r_moved = objective.residuals(moved)
            if np.sum(r_moved**2) < np.sum(r**2):
                r = r_moved
        return np.sum(r.reshape(channels, -1) ** 2, axis=0)

    residuals = objective.residuals(z).reshape(channels, -1)
    found = estimates(jac, residuals, z, values, space.value, space.bounds, cost, JACOBIAN_STEP,
                      replay.noise_cost())  # fmt: skip
    return {f: e for (_, f), e in zip(space.names, found, strict=True)}


def _frozen_ends(
    replay: Replay, rig: Rig, added: Sequence[Candidate], model: dict[str, np.ndarray]
) -> list[list[dict[str, np.ndarray]]]:
    """For each fitted parameter of the effects ``added`` so far (a round's candidates
    leave them as they are): ``rig``'s channels at the ends of its 95 % interval with
    the others held (uncertainty.held_interval on its own Jacobian column), for the
    round's prediction band (null.prediction_band). Held, not marginal: the marginal
    interval of correlated parameters is reached only with the others moved along
    (Stribeck's levels on the Festo record span their whole bounds), and one parameter
    at its marginal end with the others held is a model the data reject. The band keeps
    this linearised interval, not the reported one (:func:`_uncertainty`'s profile,
    several times wider where the cost is rough): the decision's error rate and power
    were measured with it."""
    if not added:
        return []
    unknowns = {}
    for candidate in added:
        for param in LIBRARY[candidate.name].fitted:
            if param.optional and not candidate.params.get(param.key):
                continue  # an optional part the fit left off: not part of the model
            # the box its fit had: one fitted in an earlier round's box (the rig's scales
            # move with its fitted unknowns) may lie outside today's, and an end clipped
            # onto the box would move it for no uncertainty of its own
            unknowns[param.field] = candidate.bounds[param.field]
    space = _space(dataclasses.replace(rig, unknowns=unknowns), None)
    objective = _Objective(replay, rig, None, space)
    values = [_start(replay, rig, f) for _, f in space.names]
    z = np.array([space.unit(j, v) for j, v in enumerate(values)])
    jac = _jacobian(objective.residuals, z)
    samples, effective = effective_samples(replay, model)
    cost_train = replay.cost(model, slice(0, replay.split))
    out = []
    for j, (_, name) in enumerate(space.names):
        held = held_interval(jac[:, j], z[j], values[j], lambda u, j=j: space.value(j, u),
                             space.bounds[j], cost_train, samples, effective)  # fmt: skip
        ends = [v for v in held.interval if math.isfinite(v) and v != held.value]
        out.append([replay.run(rig.with_params(**{name: v}))[0] for v in ends])
    return out


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


def _refit_jointly(
    replay: Replay,
    rig: Rig,
    added: list[Candidate],
    model: dict[str, np.ndarray],
    cost: float,
) -> tuple[Rig, list[Candidate], dict[str, np.ndarray], float, dict[str, float]]:
    """Refit the parameters of all added effects together, starting where each was found.

    Kept only if the held-out cost (``cost`` for ``rig``, whose channels are ``model``)
    does not get worse; the training fit always improves.
    """
    unknowns = dict(rig.unknowns)
    for candidate in added:  # each in the box its own fit had
        for param in LIBRARY[candidate.name].fitted:
            unknowns.setdefault(param.field, candidate.bounds[param.field])
    joint = dataclasses.replace(rig, unknowns=unknowns)
    refit, joint_fit = fit(replay, joint, None, max_evaluations=80)
    if joint_fit.cost_val > cost:
        return rig, added, model, cost, {}
    refit = dataclasses.replace(refit, unknowns=rig.unknowns)
    updated = [dataclasses.replace(c, params=refit.effect_values(c.name)) for c in added]
    return refit, updated, joint_fit.model, joint_fit.cost_val, joint_fit.unknowns
