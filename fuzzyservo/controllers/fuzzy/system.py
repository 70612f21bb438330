"""A Mamdani fuzzy inference system as typed, frozen data (what a MATLAB ``.fis`` holds).

The semantics are scikit-fuzzy's (``skfuzzy.control``), which this package uses as the
reference: membership functions sampled on each variable's universe and linearly
interpolated, rule firing by AND (min or product) / OR (max or probabilistic OR),
weights multiplying the firing, min implication, max aggregation, and defuzzification
of the aggregated set on the universe upsampled at the cut levels. A universe holds
``points`` evenly spaced samples plus every breakpoint of its piecewise-linear
membership functions, so triangles and trapezoids are represented exactly.

Methods scikit-fuzzy does not offer (product implication, sum or probor aggregation)
are evaluated by the compiled evaluator only, with the same sampled universes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

#: number of parameters of each membership-function shape (MATLAB names)
SHAPES = {"trimf": 3, "trapmf": 4, "gaussmf": 2, "gbellmf": 3}
AND_METHODS = ("min", "prod")
OR_METHODS = ("max", "probor")
IMPLICATIONS = ("min", "prod")
AGGREGATIONS = ("max", "sum", "probor")
DEFUZZIFICATIONS = ("centroid", "bisector", "mom", "som", "lom")


def membership(shape: str, params: tuple[float, ...], x: np.ndarray) -> np.ndarray:
    """Membership of ``x`` in a term, with scikit-fuzzy's shape functions (MATLAB's definitions).

    ``trimf [a b c]``, ``trapmf [a b c d]``, ``gaussmf [sigma c]`` (MATLAB order),
    ``gbellmf [a b c]``: 1/(1 + |(x − c)/a|^(2b)).
    """
    import skfuzzy as fuzz

    x = np.asarray(x, dtype=float)
    if shape == "trimf":
        return fuzz.trimf(x, list(params))
    if shape == "trapmf":
        return fuzz.trapmf(x, list(params))
    if shape == "gaussmf":
        sigma, c = params
        return fuzz.gaussmf(x, c, sigma)
    if shape == "gbellmf":
        a, b, c = params
        return fuzz.gbellmf(x, a, b, c)
    raise ValueError(f"unknown membership shape {shape!r}; use one of {sorted(SHAPES)}")


@dataclass(frozen=True)
class Term:
    """A linguistic term: a name and a membership function (shape and parameters)."""

    name: str
    shape: str
    params: tuple[float, ...]

    def __post_init__(self) -> None:
        if self.shape not in SHAPES:
            raise ValueError(
                f"term {self.name!r}: unknown shape {self.shape!r}; use one of {sorted(SHAPES)}"
            )
        if len(self.params) != SHAPES[self.shape]:
            raise ValueError(
                f"term {self.name!r}: {self.shape} takes {SHAPES[self.shape]} parameters, got {len(self.params)}"
            )
        if not all(math.isfinite(p) for p in self.params):
            raise ValueError(
                f"term {self.name!r}: parameters must be finite, got {list(self.params)}"
            )
        if self.shape in ("trimf", "trapmf") and any(
            b < a for a, b in zip(self.params, self.params[1:], strict=False)
        ):
            raise ValueError(
                f"term {self.name!r}: {self.shape} breakpoints must be in order, got {list(self.params)}; sort them"
            )
        if self.shape == "trimf" and self.params[0] == self.params[2]:
            raise ValueError(f"term {self.name!r}: trimf of zero width {list(self.params)}")
        if self.shape == "gaussmf" and not self.params[0] > 0:
            raise ValueError(f"term {self.name!r}: gaussmf sigma must be > 0, got {self.params[0]}")
        if self.shape == "gbellmf" and not (self.params[0] != 0 and self.params[1] > 0):
            raise ValueError(
                f"term {self.name!r}: gbellmf needs a != 0 and b > 0, got {list(self.params)}"
            )

    @property
    def breakpoints(self) -> tuple[float, ...]:
        """Corners of a piecewise-linear shape (none for smooth shapes)."""
        return self.params if self.shape in ("trimf", "trapmf") else ()


@dataclass(frozen=True)
class Variable:
    """An input or output: a range [low, high], its terms, and the universe resolution."""

    name: str
    low: float
    high: float
    terms: tuple[Term, ...]
    points: int = 201

    def __post_init__(self) -> None:
        if not (math.isfinite(self.low) and math.isfinite(self.high) and self.low < self.high):
            raise ValueError(
                f"variable {self.name!r}: range must satisfy low < high, got [{self.low}, {self.high}]"
            )
        if not self.terms:
            raise ValueError(f"variable {self.name!r}: needs at least one term")
        names = [t.name for t in self.terms]
        if len(set(names)) != len(names):
            raise ValueError(f"variable {self.name!r}: term names must be unique, got {names}")
        if self.points < 3:
            raise ValueError(f"variable {self.name!r}: points must be >= 3, got {self.points}")

    def universe(self) -> np.ndarray:
        """Evenly spaced samples plus every breakpoint inside the range (sorted, unique)."""
        base = np.linspace(self.low, self.high, self.points)
        corners = [b for t in self.terms for b in t.breakpoints if self.low < b < self.high]
        return np.union1d(base, np.asarray(corners, dtype=float))

    def index(self, term_name: str) -> int:
        for k, t in enumerate(self.terms):
            if t.name == term_name:
                return k
        raise KeyError(
            f"variable {self.name!r} has no term {term_name!r}; terms: {[t.name for t in self.terms]}"
        )

    def table(self) -> tuple[np.ndarray, np.ndarray]:
        """The universe and each term's membership sampled on it, shape (terms, points)."""
        u = self.universe()
        return u, np.array([membership(t.shape, t.params, u) for t in self.terms])


@dataclass(frozen=True)
class Rule:
    """``IF in1 is A AND/OR in2 is B THEN out is C (weight)``.

    ``antecedent`` holds one term index per input: ``k >= 0`` the term, ``-1`` no
    condition on that input, ``-(k + 2)`` NOT term k (MATLAB writes NOT as a negative
    index). ``consequent`` is the output term index.
    """

    antecedent: tuple[int, ...]
    consequent: int
    weight: float = 1.0
    connective: str = "and"

    def __post_init__(self) -> None:
        if self.connective not in ("and", "or"):
            raise ValueError(f"rule connective must be 'and' or 'or', got {self.connective!r}")
        if not 0.0 <= self.weight <= 1.0:
            raise ValueError(f"rule weight must lie in [0, 1], got {self.weight}")


@dataclass(frozen=True)
class FuzzySystem:
    """A Mamdani system with one or two inputs and one output."""

    name: str
    inputs: tuple[Variable, ...]
    output: Variable
    rules: tuple[Rule, ...]
    and_method: str = "min"
    or_method: str = "max"
    implication: str = "min"
    aggregation: str = "max"
    defuzzification: str = "centroid"
    description: str = field(default="", compare=False)

    def __post_init__(self) -> None:
        for attr, allowed in (
            ("and_method", AND_METHODS),
            ("or_method", OR_METHODS),
            ("implication", IMPLICATIONS),
            ("aggregation", AGGREGATIONS),
            ("defuzzification", DEFUZZIFICATIONS),
        ):
            if getattr(self, attr) not in allowed:
                raise ValueError(
                    f"{attr} must be one of {list(allowed)}, got {getattr(self, attr)!r}"
                )
        if len(self.inputs) not in (1, 2):
            raise ValueError(f"a controller takes one or two inputs, got {len(self.inputs)}")
        if not self.rules:
            raise ValueError("the rule base is empty; add rules")
        for n, rule in enumerate(self.rules, start=1):
            if len(rule.antecedent) != len(self.inputs):
                raise ValueError(
                    f"rule {n}: has {len(rule.antecedent)} antecedents for {len(self.inputs)} inputs"
                )
            for var, idx in zip(self.inputs, rule.antecedent, strict=True):
                k = idx if idx >= 0 else -idx - 2
                if idx != -1 and not 0 <= k < len(var.terms):
                    raise ValueError(f"rule {n}: input {var.name!r} has no term number {k + 1}")
            if not 0 <= rule.consequent < len(self.output.terms):
                raise ValueError(
                    f"rule {n}: output {self.output.name!r} has no term number {rule.consequent + 1}"
                )
            if all(i == -1 for i in rule.antecedent):
                raise ValueError(f"rule {n}: has no condition on any input")

    def uncovered_inputs(self) -> np.ndarray:
        """Input points (on the universes' grid) where no rule fires; empty when covered."""
        grids = [v.universe() for v in self.inputs]
        if len(grids) == 1:
            pts = grids[0][:, None]
        else:
            a, b = np.meshgrid(grids[0], grids[1], indexing="ij")
            pts = np.column_stack([a.ravel(), b.ravel()])
        firing = reference_firing(self, pts)
        return pts[firing.max(axis=1) <= 0.0]

    def check_coverage(self) -> None:
        """Raise ``ValueError`` when an input point fires no rule (no output would exist)."""
        holes = self.uncovered_inputs()
        if holes.size:
            names = [v.name for v in self.inputs]
            where = ", ".join(f"{n}={v:.4g}" for n, v in zip(names, holes[0], strict=True))
            raise ValueError(
                f"the rule base leaves {len(holes)} input point(s) uncovered (e.g. {where}): "
                f"no rule fires there; add a rule or widen a membership function"
            )


def _interp_np(universe: np.ndarray, table: np.ndarray, x: np.ndarray) -> np.ndarray:
    return np.array([np.interp(x, universe, row) for row in table])


def reference_firing(system: FuzzySystem, points: np.ndarray) -> np.ndarray:
    """Rule firing strengths (weight included) at input ``points`` (m, n_inputs), numpy.

    Used to check coverage when a controller is built.
    """
    mus = []
    for i, var in enumerate(system.inputs):
        u, table = var.table()
        x = np.clip(points[:, i], var.low, var.high)
        mus.append(_interp_np(u, table, x))
    out = np.empty((points.shape[0], len(system.rules)))
    for r, rule in enumerate(system.rules):
        acc = None
        for i, idx in enumerate(rule.antecedent):
            if idx == -1:
                continue
            mu = mus[i][idx] if idx >= 0 else 1.0 - mus[i][-idx - 2]
            if acc is None:
                acc = mu
            elif rule.connective == "and":
                acc = np.minimum(acc, mu) if system.and_method == "min" else acc * mu
            else:
                acc = np.maximum(acc, mu) if system.or_method == "max" else acc + mu - acc * mu
        out[:, r] = acc * rule.weight
    return out
