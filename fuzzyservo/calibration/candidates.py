"""Candidates: one effect of the library fitted on a replay's training part, from several
starts so that it never ends above the model it extends, and scored on the held-out part.

Grey-box estimation in the manner of MATLAB's ``nlgreyest``: the effect's parameters (and
the rig's declared unknowns) are fitted by bounded least squares
(``scipy.optimize.least_squares``, dogleg in the box, finite differences with an
absolute step on the unit box) on the training part of the replay, from several starts,
the starting model (the effect off) among them (:func:`_minimise`). A long record's
candidates are fitted on the first ``SCREEN_SAMPLES`` of its training part
(:func:`screened`). :class:`Objective` is the replay of one candidate family on the unit
box, which the intervals (:mod:`~fuzzyservo.calibration.intervals`) reuse.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares, minimize_scalar

from fuzzyservo.calibration import gains as _gains
from fuzzyservo.calibration.decision import Evidence
from fuzzyservo.calibration.joint import record_field, split_field
from fuzzyservo.calibration.replay import DIVERGED_COST, Replay
from fuzzyservo.calibration.residuals import fit_percent
from fuzzyservo.components.effects import LIBRARY, EffectParam, owner
from fuzzyservo.controllers.base import Controller
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
# With a full grid over GRID_STARTS_FROM or more parameters (Stribeck's law), local
# searches start from the GRID_STARTS best grid points as well: sticking friction's cost
# has valleys a grid spacing apart, and on two rig-like Stribeck records whose fits
# missed, the true one lay behind the grid's fourth and second best points
# (docs/calibration-intervals.md). Two parameters (Coulomb friction with a pre-sliding
# distance) keep LOCAL_STARTS: no miss of theirs was traced to it, and each local search
# costs replays that `calibrate` pays for every round
GRID_STARTS = 6
GRID_STARTS_FROM = 4


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

    def boxes(self) -> dict[str, tuple[float, float]]:
        """Field -> the box its fit had, of each fitted parameter of the effect that is
        part of the model (an optional part the fit left off is not)."""
        return {
            param.field: self.bounds[param.field]
            for param in LIBRARY[self.name].fitted
            if not (param.optional and not self.params.get(param.key))
        }


@dataclass
class Space:
    """Parameters being fitted, each mapped from the unit interval (cubic for log ones)."""

    names: list[tuple[str, str]]  # (effect name or "", field)
    bounds: list[tuple[float, float]]
    log: list[bool]

    def subset(self, keep: Sequence[int]) -> Space:
        """The parameters at positions ``keep``, in that order."""
        return Space(
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


class Objective:
    """Replays of one candidate family with a cache (least squares revisits points).

    The search looks only at the training part, so its replays stop there (a third less
    simulation); the chosen point is then replayed in full."""

    def __init__(self, replay: Replay, base: Rig, effect: str | None, space: Space):
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


def fit_space(rig: Rig, effect: str | None, replay: Replay | None = None) -> Space:
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
    return Space(names, bounds, log)


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
    full = fit_space(base, effect, replay)
    fitted_on = screened_replay(replay, screen)
    space = full if fitted_on is replay else _only(full, effect)
    objective = Objective(fitted_on, base, effect, space)
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
        judge = objective if fitted_on is replay else Objective(replay, base, effect, space)
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
        whole = Objective(replay, base, effect, space)
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
            unknowns[f] = start_value(replay, base, f)
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


def _only(space: Space, effect: str | None) -> Space:
    """``space`` cut to ``effect``'s own parameters (the rest held as they are)."""
    return space.subset(
        [j for j, (owner, _) in enumerate(space.names) if effect and owner == effect]
    )


def _start_point(replay: Replay, base: Rig, effect: str | None, space: Space) -> np.ndarray:
    """The starting model on the unit box: ``effect`` off (0, or the end of its bounds
    where it does least: a bulk modulus at the oil's, an unlimited pump;
    ``EffectParam.off_at_upper``), everything else at its current value."""
    z = []
    for j, (of, f) in enumerate(space.names):
        if effect and of == effect:
            param = LIBRARY[effect].param_by_field(f)
            z.append(1.0 if param.off_at_upper else space.unit(j, 0.0))
        else:
            z.append(space.unit(j, start_value(replay, base, f)))
    return np.array(z, dtype=float)


def start_value(replay: Replay, rig: Rig, name: str) -> float:
    """The current value of a fitted quantity: a controller gain, a per-record value
    (joint.py) or a rig parameter."""
    if _gains.is_gain(name):
        return _gains.gain_value(replay.controller, name)
    parsed = split_field(name)
    if parsed:
        return replay.values[parsed[0]][parsed[1]]
    return float(getattr(rig.params, name))


def screened_replay(replay: Replay, screen: int | None) -> Replay:
    """``replay`` with its training part cut to its first ``screen`` samples (a single
    record whose training part is SCREEN_RATIO times as long), else ``replay`` itself."""
    if screen is None or not isinstance(replay, Replay) or replay.split < SCREEN_RATIO * screen:
        return replay
    return dataclasses.replace(replay, split=screen)


def _minimise(
    objective: Objective,
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
    ``scan`` from the runner-up too (LOCAL_STARTS); after a full grid over
    GRID_STARTS_FROM or more parameters, from the GRID_STARTS best starts, the grid's
    best points among them."""
    n = z_start.size
    if n == 0:
        return z_start.copy()
    grid = SCAN_FINE if n == 1 else SCAN
    step = (grid[1] - grid[0]) / 2**REFINE_LEVELS
    starts = [z_start.copy()]
    n_local = LOCAL_STARTS
    if z_from is not None:
        starts.append(np.clip(z_from, 0.0, 1.0))
    # a single unknown alone (the nominal fit) is scanned over its whole bounds as an
    # effect parameter is (Brent alone looks only within a step of its start)
    if scan and (n_effect or n == 1):
        z = z_start.copy()
        z[:n_effect] = START
        if n_effect <= 1:
            z[0], step = _scan(lambda v: objective.train_cost([v, *z[1:]]), grid)
            starts.append(z)
        else:
            # a full grid over the effect's parameters: friction with stiction trades its
            # parameters against each other and a coordinate search stalls
            points = [np.array([*point, *z[n_effect:]])
                      for point in itertools.product(SCAN, repeat=n_effect)]  # fmt: skip
            points.sort(key=objective.train_cost)
            if n_effect >= GRID_STARTS_FROM:
                starts += points[:GRID_STARTS]
                n_local = GRID_STARTS
            else:
                starts.append(points[0])
    if scan and n_effect:
        starts.append(_gauss_newton(objective, z_start))
    ranked = sorted(_distinct(starts), key=objective.train_cost)
    local = [_local(objective, z, step, budget) for z in ranked[: n_local if scan else 1]]
    return min([*local, *ranked], key=objective.train_cost)


def _optional(space: Space, effect: str | None) -> list[int]:
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
    space: Space,
    objective: Objective,
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
    sub = Objective(replay, base, effect, space.subset(keep))
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


def _gauss_newton(objective: Objective, z: np.ndarray) -> np.ndarray:
    """One Gauss-Newton step from ``z`` on the unit box, clipped to it: where the
    training residual's projection on each parameter's sensitivity puts it."""
    jac = jacobian(objective.residuals, z)
    r = objective.residuals(z)
    if not (np.isfinite(jac).all() and np.isfinite(r).all()):
        return z.copy()
    step, *_ = np.linalg.lstsq(jac, -r, rcond=None)
    return np.clip(z + step, 0.0, 1.0)


def _local(objective: Objective, z: np.ndarray, step: float, budget: int) -> np.ndarray:
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
            jac=lambda x: jacobian(objective.residuals, x),
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


def jacobian(
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
