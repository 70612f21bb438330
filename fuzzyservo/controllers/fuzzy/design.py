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

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from fuzzyservo.controllers.fuzzy.system import Rule, Term, Variable

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
