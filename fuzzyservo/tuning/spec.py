"""What a tuning study is: typed and frozen, built from a study file by :mod:`fuzzyservo.io.studies`.

A study searches some numbers of a controller template (addressed by a dotted path
into the template file, e.g. ``input.reshape``, ``input.increments[3]``,
``gains.output``, ``kp``) against time-domain metrics on one or more scenarios of
a rig; the controller must hold up on all of them (the worst scenario counts,
or their mean).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

from fuzzyservo.tuning.uncertainty import Uncertainty

SAMPLERS = ("tpe", "cmaes", "nsga2", "random")
AGGREGATES = ("worst", "mean")
_CONSTRAINT = re.compile(r"^\s*(?P<metric>\w+)\s*(?P<op><=|>=)\s*(?P<bound>[-+0-9.eE]+)\s*$")


@dataclass(frozen=True)
class ParamSpec:
    """A searched number: its path in the template, bounds, scale, and integer or not."""

    path: str
    low: float
    high: float
    log: bool = False
    integer: bool = False

    def __post_init__(self) -> None:
        if not (math.isfinite(self.low) and math.isfinite(self.high)):
            raise ValueError(f"{self.path}: bounds must be finite, got ({self.low}, {self.high})")
        if not self.low < self.high:
            raise ValueError(
                f"{self.path}: `low < high` must hold, but got (low={self.low}, high={self.high}); swap them"
            )
        if self.log and self.low <= 0:
            raise ValueError(f"{self.path}: a log scale needs low > 0, got low={self.low}")


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
class StudySpec:
    """A tuning study, ready to run."""

    name: str
    rig_file: str
    scenarios: tuple[str, ...]
    controller_file: str
    parameters: tuple[ParamSpec, ...]
    objective: Objective
    baseline_file: str
    constraints: tuple[Constraint, ...] = ()
    aggregate: str = "worst"
    sampler: str = "tpe"
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
    warm_start: tuple[str, ...] = ()

    def __post_init__(self) -> None:
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
        if self.workers < 1:
            raise ValueError(f"workers: must be >= 1, got {self.workers}")
        if self.objective.pareto and self.sampler == "cmaes":
            raise ValueError(
                "sampler: cmaes optimises one objective; use nsga2 (or tpe) for a Pareto front"
            )
        paths = [p.path for p in self.parameters]
        if len(set(paths)) != len(paths):
            raise ValueError(f"parameters: each path once, got {paths}")


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
