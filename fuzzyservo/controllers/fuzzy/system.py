"""A type-1 fuzzy inference system as typed, frozen data (what a MATLAB ``.fis`` holds).

Mamdani or Sugeno (constant or linear output terms, ``wtaver``/``wtsum``), any number
of inputs and outputs, rule weights, NOT in antecedents and consequents. Two
evaluation semantics (``semantics``):

* ``skfuzzy`` (the default), described below;
* ``matlab``: what ``evalfis`` computes — exact input membership, implication per rule,
  aggregation over the rules, the output sampled at ``sample_points`` (101) evenly
  spaced points and defuzzified there; mid-range output when no rule fires
  (:mod:`.exact`).

The semantics are scikit-fuzzy's (``skfuzzy.control``), which this package uses as the
reference: membership functions sampled on each variable's universe and linearly
interpolated, rule firing by AND (min or product) / OR (max or probabilistic OR),
weights multiplying the firing, min implication, max aggregation, and defuzzification
of the aggregated set on the universe upsampled at the cut levels. A universe holds
``points`` evenly spaced samples plus every breakpoint of its piecewise-linear
membership functions, so triangles and trapezoids are represented exactly.

Methods scikit-fuzzy does not offer (product implication, sum or probor aggregation,
negated consequents) are evaluated by the compiled evaluator only, with the same
sampled universes and implication per rule before aggregation. scikit-fuzzy has no
Sugeno systems: those are evaluated with exact input membership in both semantics.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

from fuzzyservo._jit import njit
from fuzzyservo.controllers.fuzzy.shapes import MF_SHAPES, PIECEWISE_LINEAR, SUGENO_SHAPES, mf_array
from fuzzyservo.errors import excerpt
from fuzzyservo.limits import MAX_SAMPLE_POINTS, points_problem

#: number of parameters each membership-function shape reads (MATLAB names)
SHAPES = MF_SHAPES
TYPES = ("mamdani", "sugeno")
SEMANTICS = ("skfuzzy", "matlab")
AND_METHODS = ("min", "prod")
OR_METHODS = ("max", "probor")
IMPLICATIONS = ("min", "prod")
AGGREGATIONS = ("max", "sum", "probor")
MAMDANI_DEFUZZIFICATIONS = ("centroid", "bisector", "mom", "som", "lom")
SUGENO_DEFUZZIFICATIONS = ("wtaver", "wtsum")
DEFUZZIFICATIONS = (*MAMDANI_DEFUZZIFICATIONS, *SUGENO_DEFUZZIFICATIONS)
#: MATLAB's evalfis default number of output sample points
MATLAB_SAMPLE_POINTS = 101


def membership(shape: str, params: tuple[float, ...], x: np.ndarray) -> np.ndarray:
    """Membership of ``x`` in a term, sampled for the ``skfuzzy`` semantics.

    trimf, trapmf, gaussmf ``[sigma c]`` and gbellmf use scikit-fuzzy's functions (the
    reference of that semantics); the other shapes MATLAB's definitions (:mod:`.shapes`).
    """
    import skfuzzy as fuzz

    x = np.asarray(x, dtype=float)
    if shape not in SHAPES:
        raise ValueError(f"unknown membership shape {shape!r}; use one of {sorted(SHAPES)}")
    p = params[: SHAPES[shape]]
    if shape == "trimf":
        return fuzz.trimf(x, list(p))
    if shape == "trapmf":
        return fuzz.trapmf(x, list(p))
    if shape == "gaussmf":
        sigma, c = p
        return fuzz.gaussmf(x, c, sigma)
    if shape == "gbellmf":
        a, b, c = p
        return fuzz.gbellmf(x, a, b, c)
    return mf_array(shape, p, x)


@dataclass(frozen=True)
class Term:
    """A linguistic term: a name and a membership function (shape and parameters)."""

    name: str
    shape: str
    params: tuple[float, ...]

    def __post_init__(self) -> None:
        if self.shape not in SHAPES and self.shape not in SUGENO_SHAPES:
            raise ValueError(
                f"term {excerpt(self.name)}: unknown shape {self.shape!r}; use one of "
                f"{sorted(SHAPES)} (Sugeno outputs: {list(SUGENO_SHAPES)})"
            )
        need = SHAPES.get(self.shape, 1)
        if len(self.params) < need or (self.shape == "constant" and len(self.params) != 1):
            raise ValueError(
                f"term {excerpt(self.name)}: {self.shape} takes {need} parameters, got {len(self.params)}"
            )
        if not all(math.isfinite(p) for p in self.params):
            raise ValueError(
                f"term {excerpt(self.name)}: parameters must be finite, got {excerpt(list(self.params))}"
            )
        p = self.params[:need]
        if self.shape in ("trimf", "trapmf") and any(b < a for a, b in itertools.pairwise(p)):
            raise ValueError(
                f"term {excerpt(self.name)}: {self.shape} breakpoints must be in order, got {excerpt(list(self.params))}; sort them"
            )
        if self.shape == "trimf" and self.params[0] == self.params[2]:
            raise ValueError(
                f"term {excerpt(self.name)}: trimf of zero width {excerpt(list(self.params))}"
            )
        if self.shape == "gaussmf" and not self.params[0] > 0:
            raise ValueError(
                f"term {excerpt(self.name)}: gaussmf sigma must be > 0, got {self.params[0]}"
            )
        if self.shape == "gauss2mf" and not (p[0] > 0 and p[2] > 0):
            raise ValueError(
                f"term {excerpt(self.name)}: gauss2mf sigmas must be > 0, got {excerpt(list(p))}"
            )
        if self.shape == "gbellmf" and not (self.params[0] != 0 and self.params[1] > 0):
            raise ValueError(
                f"term {excerpt(self.name)}: gbellmf needs a != 0 and b > 0, got {excerpt(list(self.params))}"
            )

    @property
    def breakpoints(self) -> tuple[float, ...]:
        """Corners of a piecewise-linear shape (none for smooth shapes)."""
        return self.params[: SHAPES[self.shape]] if self.shape in PIECEWISE_LINEAR else ()

    @property
    def is_sugeno(self) -> bool:
        return self.shape in SUGENO_SHAPES


@dataclass(frozen=True)
class Variable:
    """An input or output: a range [low, high], its terms, and the universe resolution."""

    name: str
    low: float
    high: float
    terms: tuple[Term, ...]
    points: int = 201

    def __post_init__(self) -> None:
        # a Sugeno output's range is only its no-rule-fired value (MATLAB's juggler.fis has [0 0])
        sugeno = bool(self.terms) and all(t.is_sugeno for t in self.terms)
        if not (
            math.isfinite(self.low)
            and math.isfinite(self.high)
            and (self.low < self.high or (sugeno and self.low == self.high))
        ):
            raise ValueError(
                f"variable {self.name!r}: range must satisfy low < high, got [{self.low}, {self.high}]"
            )
        # term names may repeat (MATLAB refers to terms by number: its juggler.fis names all
        # nine output terms 'out1mf'); formats that refer by name check uniqueness
        if points_problem(self.points):
            raise ValueError(f"variable {excerpt(self.name)}: points {points_problem(self.points)}")

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


#: grid points the coverage check evaluates at once (8 bytes per rule and term each)
_COVERAGE_BLOCK = 1 << 16

#: the term code of "no condition on this input" / "nothing about this output"
NO_TERM = -1


def term_code(k: int, negated: bool = False) -> int:
    """Term ``k`` (counted from 0), or NOT term ``k``, as a rule's term code: ``k``, or
    ``-(k + 2)`` when negated (MATLAB writes NOT as a negative MF number; shifted by one
    so that ``-1`` stays free for :data:`NO_TERM`). :func:`term_index` is its inverse."""
    return -k - 2 if negated else k


@njit(cache=True, inline="always")
def term_index(code: int) -> tuple[int, bool]:
    """A rule's term code decoded: ``(term, negated)``; :data:`NO_TERM` gives ``(-1, False)``.

    The one place that decodes it: compiled, so the evaluators call it too (the generated
    C has its port, ``term_index`` in :mod:`fuzzyservo.codegen._c_runtime`)."""
    if code >= NO_TERM:
        return code, False
    return -code - 2, True


def from_matlab(number: int) -> int:
    """A rule's MF number as a ``.fis`` file writes it (k > 0: MF k, 0: none, −k: NOT MF k;
    MFs counted from 1) as a term code."""
    return NO_TERM if number == 0 else term_code(abs(number) - 1, number < 0)


def to_matlab(code: int) -> int:
    """A term code as the MF number a ``.fis`` file writes (:func:`from_matlab` inverted)."""
    k, negated = term_index(code)
    return 0 if code == NO_TERM else (-(k + 1) if negated else k + 1)


@dataclass(frozen=True)
class Rule:
    """``IF in1 is A AND/OR in2 is B … THEN out1 is C, out2 is D … (weight)``.

    ``antecedent`` holds one term code per input (:func:`term_code`: term k or NOT term k;
    :data:`NO_TERM`: no condition on that input). ``consequent`` is the first output's
    term code (:data:`NO_TERM`: the rule says nothing about that output);
    ``other_consequents`` those of the second, third … outputs.
    """

    antecedent: tuple[int, ...]
    consequent: int
    weight: float = 1.0
    connective: str = "and"
    other_consequents: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        if self.connective not in ("and", "or"):
            raise ValueError(f"rule connective must be 'and' or 'or', got {self.connective!r}")
        if not 0.0 <= self.weight <= 1.0:
            raise ValueError(f"rule weight must lie in [0, 1], got {self.weight}")

    @property
    def consequents(self) -> tuple[int, ...]:
        return (self.consequent, *self.other_consequents)


@dataclass(frozen=True)
class FuzzySystem:
    """A Mamdani or Sugeno system: inputs, outputs (``output`` and ``other_outputs``), rules."""

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
    other_outputs: tuple[Variable, ...] = ()
    type: str = "mamdani"
    semantics: str = "skfuzzy"
    sample_points: int = MATLAB_SAMPLE_POINTS

    @property
    def outputs(self) -> tuple[Variable, ...]:
        return (self.output, *self.other_outputs)

    def __post_init__(self) -> None:
        for attr, allowed in (
            ("type", TYPES),
            ("semantics", SEMANTICS),
            ("and_method", AND_METHODS),
            ("or_method", OR_METHODS),
            ("implication", IMPLICATIONS),
            ("aggregation", AGGREGATIONS),
            (
                "defuzzification",
                MAMDANI_DEFUZZIFICATIONS if self.type == "mamdani" else SUGENO_DEFUZZIFICATIONS,
            ),
        ):
            if getattr(self, attr) not in allowed:
                raise ValueError(
                    f"{attr} must be one of {list(allowed)}, got {getattr(self, attr)!r}"
                )
        if not self.inputs:
            raise ValueError("a system needs at least one input")
        problem = points_problem(self.sample_points, MATLAB_SAMPLE_POINTS, MAX_SAMPLE_POINTS)
        if problem:
            raise ValueError(f"sample_points {problem}")
        n_in = len(self.inputs)
        for var in self.outputs:
            for t in var.terms:
                if self.type == "mamdani" and t.is_sugeno:
                    raise ValueError(
                        f"output {var.name!r}: term {t.name!r} is a Sugeno term ({t.shape}) in a "
                        "Mamdani system; give it a membership function or make the system Sugeno"
                    )
                if self.type == "sugeno" and not t.is_sugeno:
                    raise ValueError(
                        f"output {var.name!r}: term {t.name!r} is a {t.shape} in a Sugeno system; "
                        "Sugeno output terms are 'constant' or 'linear'"
                    )
                if t.shape == "linear" and len(t.params) != n_in + 1:
                    raise ValueError(
                        f"output {var.name!r}: linear term {t.name!r} needs {n_in + 1} "
                        f"coefficients (one per input and a constant), got {len(t.params)}"
                    )
        if not self.rules:
            raise ValueError("the rule base is empty; add rules")
        for n, rule in enumerate(self.rules, start=1):
            if len(rule.antecedent) != n_in:
                raise ValueError(
                    f"rule {n}: has {len(rule.antecedent)} antecedents for {n_in} inputs"
                )
            if len(rule.consequents) != len(self.outputs):
                raise ValueError(
                    f"rule {n}: has {len(rule.consequents)} consequents for "
                    f"{len(self.outputs)} outputs"
                )
            for var, idx in zip(self.inputs, rule.antecedent, strict=True):
                k, _ = term_index(idx)
                if idx != NO_TERM and not 0 <= k < len(var.terms):
                    raise ValueError(f"rule {n}: input {var.name!r} has no term number {k + 1}")
            for var, idx in zip(self.outputs, rule.consequents, strict=True):
                k, negated = term_index(idx)
                if idx != NO_TERM and not 0 <= k < len(var.terms):
                    raise ValueError(f"rule {n}: output {var.name!r} has no term number {k + 1}")
                if negated and self.type == "sugeno":
                    raise ValueError(
                        f"rule {n}: a negated consequent (NOT {var.terms[k].name}) has no "
                        "meaning in a Sugeno system; use a term"
                    )
            if all(i == NO_TERM for i in rule.antecedent):
                raise ValueError(f"rule {n}: has no condition on any input")

    def uncovered_inputs(self) -> np.ndarray:
        """Input points (on the universes' grid) where no rule fires; empty when covered."""
        return np.concatenate(list(self._uncovered()))

    def _uncovered(self) -> Iterator[np.ndarray]:
        """The uncovered grid points, a block of at most ``_COVERAGE_BLOCK`` grid points
        at a time (two inputs of n points make n² of them)."""
        grids = [v.universe() for v in self.inputs]
        shape = tuple(g.size for g in grids)
        total = math.prod(shape)
        for start in range(0, total, _COVERAGE_BLOCK):
            index = np.unravel_index(np.arange(start, min(start + _COVERAGE_BLOCK, total)), shape)
            pts = np.column_stack([g[i] for g, i in zip(grids, index, strict=True)])
            yield pts[reference_firing(self, pts).max(axis=1) <= 0.0]

    def check_coverage(self) -> None:
        """Raise ``ValueError`` when an input point fires no rule (no output would exist)."""
        count, first = 0, None
        for holes in self._uncovered():
            count += len(holes)
            first = holes[0] if first is None and len(holes) else first
        if count:
            names = [v.name for v in self.inputs]
            where = ", ".join(f"{n}={v:.4g}" for n, v in zip(names, first, strict=True))
            raise ValueError(
                f"the rule base leaves {count} input point(s) uncovered (e.g. {where}): "
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
            k, negated = term_index(idx)
            if idx == NO_TERM:
                continue
            mu = 1.0 - mus[i][k] if negated else mus[i][k]
            if acc is None:
                acc = mu
            elif rule.connective == "and":
                acc = np.minimum(acc, mu) if system.and_method == "min" else acc * mu
            else:
                acc = np.maximum(acc, mu) if system.or_method == "max" else acc + mu - acc * mu
        out[:, r] = acc * rule.weight
    return out
