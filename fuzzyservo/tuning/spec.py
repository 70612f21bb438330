"""What a tuning study is: typed and frozen, built in Python or from a study file (``io``).

A :class:`Study` searches some numbers of a controller ``template`` (its searchable
numbers, by the names controller files use: ``input.reshape``, ``input.increments[3]``,
``gains.output``, ``kp``; see :meth:`Controller.params`) against time-domain metrics on
one or more scenarios of a rig; the controller must hold up on all of them (the worst
scenario counts, or their mean). A trial turns its sampled numbers into a controller
through the template's own :meth:`~fuzzyservo.controllers.base.Controller.with_params`::

    study = Study(
        name="lift_pi", rig=rig, scenarios=("steps",), template=PI(kp=1.0, ki=0.5),
        parameters=(Parameter("kp", 0.5, 8.0, log=True), Parameter("ki", 0.01, 20.0, log=True)),
        objective=Objective(weights={"settling_time_s": 1.0, "sse_abs": 1000.0}),
        baseline=P(gain=4.0), trials=40, seed=1,
    )
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from fuzzyservo.errors import ConfigError, did_you_mean
from fuzzyservo.tuning.uncertainty import Uncertainty

if TYPE_CHECKING:
    from fuzzyservo.controllers.base import Controller
    from fuzzyservo.rig import Rig

#: trials in flight (pipelined runs, tuning/pipeline.py): trial n is asked knowing the
#: trials up to n - BATCH_SIZE, so a larger batch keeps more workers busy, searches less
#: informed and prunes against an older bound. 4 keeps 2-3 local workers busy (one
#: queued trial each while the parent asks); raise it for a cluster. Independent of the
#: number of workers, so the result is.
BATCH_SIZE = 4
SAMPLERS = ("tpe", "cmaes", "nsga2", "gp", "qmc", "random")
#: a study file's ``sampler`` when it names none: :func:`default_sampler` decides
AUTO = "auto"


def default_sampler(*, pareto: bool, robust: bool) -> str:
    """The sampler the measurements in docs/samplers.md support for a study (5 seeds per
    sampler at each study's budget): CMA-ES for one objective on the nominal plant (best
    median on ``dinca_flc``, 0.488 against TPE's 0.525; level with TPE on ``ehs160_flc``,
    0.1172 against 0.1165), TPE for a robust study (best median on ``dinca_robust``,
    0.612 against CMA-ES's 0.748: TPE learns from pruned trials, CMA-ES only from
    complete ones, and that study prunes some 270 of 300); NSGA-II for a Pareto front
    (CMA-ES optimises one objective)."""
    if pareto:
        return "nsga2"
    return "tpe" if robust else "cmaes"


AGGREGATES = ("worst", "mean")
_CONSTRAINT = re.compile(r"^\s*(?P<metric>\w+)\s*(?P<op><=|>=)\s*(?P<bound>[-+0-9.eE]+)\s*$")


@dataclass(frozen=True)
class Parameter:
    """A searched number: its name in the template (:meth:`Controller.params`), bounds,
    scale, integer or not, and ``where`` it was declared (``file: key``, for messages)."""

    path: str
    low: float
    high: float
    log: bool = False
    integer: bool = False
    where: str = field(default="", compare=False)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.low) and math.isfinite(self.high)):
            raise ValueError(f"{self.path}: bounds must be finite, got ({self.low}, {self.high})")
        if not self.low < self.high:
            raise ValueError(
                f"{self.path}: `low < high` must hold, but got (low={self.low}, high={self.high}); swap them"
            )
        if self.log and self.low <= 0:
            raise ValueError(f"{self.path}: a log scale needs low > 0, got low={self.low}")

    @property
    def name(self) -> str:
        return self.path

    def clip(self, value: float) -> float:
        """``value`` moved into ``[low, high]`` (rounded for an integer parameter)."""
        value = min(max(value, self.low), self.high)
        return round(value) if self.integer else value


#: constraint-only metrics computed by bisection on extra simulations (opt-in, costly)
MARGIN_METRICS: tuple[str, ...] = ("gain_margin", "delay_margin_s")


@dataclass(frozen=True)
class Constraint:
    """``metric <= bound`` (or ``>=``); ``violation`` > 0 means broken."""

    metric: str
    op: str
    bound: float

    @classmethod
    def parse(cls, text: str) -> Constraint:
        m = _CONSTRAINT.match(text)
        if not m:
            raise ValueError(f"cannot read constraint {text!r}; write it like 'overshoot_pct <= 5'")
        return cls(m["metric"], m["op"], float(m["bound"]))

    def violation(self, value: float) -> float:
        if not math.isfinite(value):
            return math.inf
        return value - self.bound if self.op == "<=" else self.bound - value

    def __str__(self) -> str:
        return f"{self.metric} {self.op} {self.bound:g}"


@dataclass(frozen=True)
class Objective:
    """One metric, a weighted sum of metrics, or several metrics for a Pareto front (all minimised).

    ``weights``: value = Σ w_m·metric_m, metrics in SI (``sse_abs`` in metres, so a weight
    of 1000 counts a millimetre like a second). ``normalize='baseline'`` divides each
    metric by the baseline controller's value first (a zero baseline value divides by 1).
    """

    weights: dict[str, float] = field(default_factory=dict)
    pareto: tuple[str, ...] = ()
    normalize: str = "none"

    @property
    def metrics(self) -> tuple[str, ...]:
        return self.pareto or tuple(self.weights)

    @property
    def n_values(self) -> int:
        return len(self.pareto) if self.pareto else 1

    def describe(self) -> str:
        if self.pareto:
            return "Pareto front of " + ", ".join(self.pareto)
        terms = " + ".join(f"{w:g}·{m}" for m, w in self.weights.items())
        return terms + (" (each divided by the baseline's)" if self.normalize == "baseline" else "")


@dataclass(frozen=True)
class Study:
    """A tuning study, ready to run: the rig and its scenarios, the controller template
    and its search space, the objective and constraints, the baseline it is measured
    against, and how it runs (sampler, seed, trials, storage, workers).

    Built from a study file by :func:`fuzzyservo.io.studies.load_study` (``path`` names
    it) or in Python; :func:`fuzzyservo.tuning.tune` runs and resumes either. Building
    one checks it: the scenarios exist in the rig and both bounds of every parameter
    make a valid controller (a :class:`ConfigError` naming the parameter otherwise).
    ``warm_start``: first trials, each the searched numbers by name, e.g. a controller's
    :meth:`~fuzzyservo.controllers.base.Controller.params` (clipped into their ranges; a
    number not searched is ignored, one left out is sampled).
    """

    name: str
    rig: Rig
    scenarios: tuple[str, ...]
    template: Controller
    parameters: tuple[Parameter, ...]
    objective: Objective
    baseline: Controller
    constraints: tuple[Constraint, ...] = ()
    aggregate: str = "worst"
    sampler: str = AUTO  # auto: default_sampler() decides when the study is built
    seed: int | None = 0
    trials: int = 100
    timeout_s: float | None = None
    storage: str | None = None
    penalty: float = 1.0e6
    description: str = ""
    path: str = ""
    uncertainty: Uncertainty | None = None
    workers: int = 1
    patience: int | None = None
    batch_size: int = BATCH_SIZE
    warm_start: tuple[Mapping[str, float], ...] = ()

    def __post_init__(self) -> None:
        if self.sampler == AUTO:
            chosen = default_sampler(
                pareto=bool(self.objective.pareto), robust=self.uncertainty is not None
            )
            object.__setattr__(self, "sampler", chosen)  # frozen: set once, while building
        if self.sampler not in SAMPLERS:
            raise ValueError(f"sampler: unknown {self.sampler!r}; choose one of {list(SAMPLERS)}")
        if self.aggregate not in AGGREGATES:
            raise ValueError(
                f"aggregate: unknown {self.aggregate!r}; choose one of {list(AGGREGATES)}"
            )
        if self.trials < 1:
            raise ValueError(f"trials: must be >= 1, got {self.trials}")
        if self.patience is not None and self.patience < 1:
            raise ValueError(f"patience: must be >= 1 trials or null, got {self.patience}")
        if self.batch_size < 1:
            raise ValueError(f"batch_size: must be >= 1 trials, got {self.batch_size}")
        if self.workers < 1:
            raise ValueError(f"workers: must be >= 1, got {self.workers}")
        if self.objective.pareto and self.sampler == "cmaes":
            raise ValueError(
                "sampler: cmaes optimises one objective; use nsga2 (or tpe) for a Pareto front"
            )
        if not self.scenarios:
            raise ValueError("scenarios: none given; name at least one scenario of the rig")
        if not self.parameters:
            raise ValueError("parameters: none to search; give at least one")
        paths = [p.path for p in self.parameters]
        if len(set(paths)) != len(paths):
            raise ValueError(f"parameters: each path once, got {paths}")
        self._check_against_rig_and_template()

    def _check_against_rig_and_template(self) -> None:
        """Scenarios exist in the rig; every parameter is a number of the template and its
        bounds build a valid controller (so a typo fails now, not at trial 1)."""
        file = self.path or None
        for n, name in enumerate(self.scenarios):
            if name not in self.rig.scenarios:
                raise ConfigError(
                    f"unknown scenario {name!r}; {did_you_mean(name, self.rig.scenarios)}"
                    f"rig {self.rig.name} has {', '.join(self.rig.scenarios)}",
                    file=file, key=f"scenarios[{n}]",
                )  # fmt: skip
        known = self.template.params()
        paths = [p.path for p in self.parameters]
        for p in self.parameters:
            if p.path not in known:
                raise ConfigError(
                    f"the template {self.template.name} has no searchable number {p.path!r}; "
                    f"{did_you_mean(p.path, known)}it has {', '.join(known) or 'none'}",
                    file=file, key=f"parameters.{p.path}",
                )  # fmt: skip
            for value in (p.low, p.high):
                try:
                    self.template.with_params(**{p.path: value})
                except ValueError as exc:
                    raise ConfigError(
                        f"with {p.path} = {value:g} the template is invalid: {exc}",
                        file=file, key=f"parameters.{p.path}",
                    ) from None  # fmt: skip
        for n, start in enumerate(self.warm_start):
            if not any(k in paths for k in start):
                raise ValueError(
                    f"warm_start[{n}]: none of the searched numbers ({', '.join(paths)}); "
                    "give a point of this search space, e.g. a controller's params()"
                )

    def trial_controller(self, values: Mapping[str, float], name: str = "") -> Controller:
        """The template with the sampled ``values`` (by parameter name); a ``ValueError``
        naming where the offending parameter was declared when they make no controller."""
        try:
            controller = self.template.with_params(**values)
        except ValueError as exc:
            where = {p.path: f" ({p.where})" if p.where else "" for p in self.parameters}
            given = ", ".join(f"{k} = {v:g}{where.get(k, '')}" for k, v in values.items())
            raise ValueError(f"with {given} the template is invalid: {exc}") from None
        return controller.renamed(name) if name else controller


STORAGE_SCHEMES = ("sqlite:///", "postgresql://", "postgres://", "postgresql+psycopg2://")


def storage_problem(url: str) -> str | None:
    """Why ``url`` is no storage fuzzyservo can open (SQLite, or PostgreSQL through the
    psycopg2 driver it ships), or ``None``. Reachability is found out when connecting."""
    if not url.startswith(STORAGE_SCHEMES):
        return (
            f"{url!r} is not a storage fuzzyservo can open (it ships SQLite and the PostgreSQL "
            "driver); give postgresql://user@host/db or sqlite:///path/to/file.db"
        )
    if url.startswith("sqlite:///"):
        from pathlib import Path

        folder = Path(url[len("sqlite:///") :]).parent
        if not folder.is_dir():
            return f"{url!r}: folder {folder} does not exist; create it or name another"
    return None
