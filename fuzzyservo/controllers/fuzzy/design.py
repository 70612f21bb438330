"""Seven-term (NB … PB) variables built from a few searchable parameters.

Seed 002 §6-7: seven terms on input and output, triangles inside and trapezoids at both
ends, identity rule base NB→NB … PB→PB. A variable's term positions come from eight
positive increments (left shoulder, six gaps, right shoulder) scaled to fill the
range, so any positive vector an optimiser proposes is a valid, fully covering set.
Two operations act on those positions:

* ``translate`` δ: every breakpoint and the range move by δ, so the control curve
  moves by exactly δ — seed 002 §6 moves the output terms so that zero error commands
  the current that holds the piston. (Moving the terms but not the range would cut
  the outer terms, and a large δ could push a term out of the range altogether.)
* ``reshape`` γ: a monotone warp ``z → sign(z)·|z|^γ`` of positions relative to the
  range centre; γ > 1 pulls the inner terms toward zero (steeper control curve near
  zero error), γ < 1 pushes them out — seed 002 §7's modified input terms.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from fuzzyservo.controllers.base import parameter_path
from fuzzyservo.controllers.fuzzy.controller import FuzzyController
from fuzzyservo.controllers.fuzzy.system import (
    AGGREGATIONS,
    AND_METHODS,
    IMPLICATIONS,
    MAMDANI_DEFUZZIFICATIONS,
    MATLAB_SAMPLE_POINTS,
    OR_METHODS,
    FuzzySystem,
    Rule,
    Term,
    Variable,
)

SEVEN_TERMS = ("NB", "NM", "NS", "Z", "PS", "PM", "PB")
UNIFORM_INCREMENTS = (0.5, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.5)


@dataclass(frozen=True)
class SevenTermDesign:
    """Parameters of a seven-term variable: range, increments, reshape γ, translation δ."""

    name: str
    low: float
    high: float
    increments: tuple[float, ...] = UNIFORM_INCREMENTS
    reshape: float = 1.0
    translate: float = 0.0
    points: int = 201

    def __post_init__(self) -> None:
        if not (math.isfinite(self.low) and math.isfinite(self.high) and self.low < self.high):
            raise ValueError(
                f"{self.name}: range must satisfy low < high, got [{self.low}, {self.high}]"
            )
        if len(self.increments) != 8:
            raise ValueError(
                f"{self.name}: increments needs 8 positive numbers (left shoulder, 6 gaps, right shoulder), "
                f"got {len(self.increments)}"
            )
        if not all(math.isfinite(d) and d > 0 for d in self.increments):
            raise ValueError(
                f"{self.name}: increments must all be > 0, got {list(self.increments)}"
            )
        if not (math.isfinite(self.reshape) and self.reshape > 0):
            raise ValueError(
                f"{self.name}: reshape must be > 0 (1 = unchanged), got {self.reshape}"
            )
        if not math.isfinite(self.translate):
            raise ValueError(f"{self.name}: translate must be finite, got {self.translate}")

    def centres(self) -> np.ndarray:
        """Peak positions c0..c6 of NB..PB: increments scaled to the range, warped, translated."""
        d = np.asarray(self.increments, dtype=float)
        cum = np.cumsum(d)[:7] / d.sum()
        c = self.low + (self.high - self.low) * cum
        return warp(c, self.low, self.high, self.reshape) + self.translate

    def variable(self) -> Variable:
        """The :class:`Variable`: trapezoids NB and PB with shoulders beyond the range, triangles inside."""
        c = self.centres()
        far = self.high - self.low
        lo, hi = self.low + self.translate - far, self.high + self.translate + far
        terms = [Term("NB", "trapmf", (lo, lo, c[0], c[1]))]
        terms += [Term(SEVEN_TERMS[k], "trimf", (c[k - 1], c[k], c[k + 1])) for k in range(1, 6)]
        terms.append(Term("PB", "trapmf", (c[5], c[6], hi, hi)))
        d = self.translate
        return Variable(self.name, self.low + d, self.high + d, tuple(terms), self.points)


#: a fuzzy design's variable slots, as controller files name them: error, error rate, command
SLOTS = ("input", "rate", "output")
_GAINS = {"gains.input": "input_gain", "gains.rate": "rate_gain", "gains.output": "output_gain"}


@dataclass(frozen=True)
class FuzzyDesign:
    """A fuzzy controller as its designer writes it (a ``kind: fuzzy`` controller file):
    each variable a :class:`SevenTermDesign` (its searchable numbers kept) or an explicit
    :class:`Variable`, the rules, the methods, the scaling gains and the output limits [V].

    :meth:`controller` builds the :class:`FuzzyController`; :meth:`with_params` is how a
    study turns sampled numbers into a new design, by the names controller files use:
    ``input.increments[3]``, ``input.reshape``, ``output.translate``, ``gains.output``
    (:meth:`params` lists them).
    """

    inputs: tuple[SevenTermDesign | Variable, ...]
    output: SevenTermDesign | Variable
    rules: tuple[Rule, ...]
    form: str = "p"
    input_gain: float = 1.0
    rate_gain: float = 1.0
    output_gain: float = 1.0
    and_method: str = AND_METHODS[0]
    or_method: str = OR_METHODS[0]
    implication: str = IMPLICATIONS[0]
    aggregation: str = AGGREGATIONS[0]
    defuzzification: str = MAMDANI_DEFUZZIFICATIONS[0]
    semantics: str = "skfuzzy"
    sample_points: int = MATLAB_SAMPLE_POINTS
    u_min: float = -math.inf
    u_max: float = math.inf
    name: str = "fuzzy"
    description: str = ""

    def slots(self) -> dict[str, SevenTermDesign | Variable]:
        """The variables by slot name (``input``, ``rate`` when two inputs, ``output``)."""
        return dict(zip(SLOTS[: len(self.inputs)], self.inputs, strict=True)) | {
            "output": self.output
        }

    def params(self) -> dict[str, float]:
        """Every searchable number by name: the scaling gains and each seven-term
        variable's increments, reshape and translation."""
        out = {name: float(getattr(self, f)) for name, f in _GAINS.items()}
        for slot, var in self.slots().items():
            if isinstance(var, SevenTermDesign):
                out |= {f"{slot}.increments[{k}]": d for k, d in enumerate(var.increments)}
                out[f"{slot}.reshape"] = var.reshape
                out[f"{slot}.translate"] = var.translate
        return out

    def with_params(self, **values: float) -> FuzzyDesign:
        """The design with the named numbers (:meth:`params`) changed; ``ValueError`` for
        an unknown name or a value no design takes (e.g. a zero increment)."""
        known = self.params()
        gains: dict[str, float] = {}
        changed: dict[str, dict[str, float]] = {}
        for name, value in values.items():
            if name not in known:
                raise ValueError(
                    f"{self.name}: no searchable number {name!r}; this design has "
                    f"{', '.join(known)}"
                )
            if name in _GAINS:
                gains[_GAINS[name]] = float(value)
            else:
                slot, *place = parameter_path(name)  # ("input", "increments", 3)
                changed.setdefault(str(slot), {})[tuple(place)] = float(value)
        slots = self.slots()
        for slot, places in changed.items():
            var = slots[slot]
            increments = list(var.increments)
            scalars: dict[str, float] = {}
            for (key, *index), value in places.items():
                if index:
                    increments[int(index[0])] = value
                else:
                    scalars[str(key)] = value
            slots[slot] = dataclasses.replace(var, increments=tuple(increments), **scalars)
        inputs = tuple(v for k, v in slots.items() if k != "output")
        return dataclasses.replace(self, inputs=inputs, output=slots["output"], **gains)

    def renamed(self, name: str) -> FuzzyDesign:
        return dataclasses.replace(self, name=name)

    def controller(self) -> FuzzyController:
        """The controller this design describes (``ValueError`` when it is no valid one)."""
        inputs = tuple(v.variable() if isinstance(v, SevenTermDesign) else v for v in self.inputs)
        output = self.output
        system = FuzzySystem(
            name=self.name,
            inputs=inputs,
            output=output.variable() if isinstance(output, SevenTermDesign) else output,
            rules=self.rules,
            and_method=self.and_method,
            or_method=self.or_method,
            implication=self.implication,
            aggregation=self.aggregation,
            defuzzification=self.defuzzification,
            description=self.description,
            semantics=self.semantics,
            sample_points=self.sample_points,
        )
        return FuzzyController(
            system=system,
            form=self.form,
            input_gain=self.input_gain,
            rate_gain=self.rate_gain,
            output_gain=self.output_gain,
            u_min=self.u_min,
            u_max=self.u_max,
            name=self.name,
            description=self.description,
            design=self,
        )


def warp(x: np.ndarray, low: float, high: float, gamma: float) -> np.ndarray:
    """Monotone reshaping about the range centre: ``z → sign(z)·|z|^γ``, ends fixed."""
    mid = 0.5 * (low + high)
    half = 0.5 * (high - low)
    z = (np.asarray(x, dtype=float) - mid) / half
    return mid + half * np.sign(z) * np.abs(z) ** gamma


def identity_rules(n_terms: int = 7) -> tuple[Rule, ...]:
    """NB→NB, NM→NM, …, PB→PB (seed 002 §6)."""
    return tuple(Rule((k,), k) for k in range(n_terms))


def macvicar_whelan(n_terms: int = 7) -> list[list[int]]:
    """The usual PD table: output index = clip(i + j − mid) for error term i and rate term j."""
    mid = n_terms // 2
    return [[min(max(i + j - mid, 0), n_terms - 1) for j in range(n_terms)] for i in range(n_terms)]


def table_rules(table: Sequence[Sequence[int]]) -> tuple[Rule, ...]:
    """Rules of a two-input table: row = error term, column = rate term, entry = output term."""
    return tuple(Rule((i, j), int(c)) for i, row in enumerate(table) for j, c in enumerate(row))
