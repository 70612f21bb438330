"""The one place that talks to ``skfuzzy.control``: the reference semantics.

scikit-fuzzy keeps the state of every Antecedent, Consequent, Term and Rule it ever
saw in class-level descriptors (``skfuzzy/control/state.py``: ``StatefulProperty.data``
is keyed by instance), so a system built in a loop is never freed.
:class:`SkfuzzyReference` builds a system once, computes with it, and on
:meth:`~SkfuzzyReference.close` (or leaving its ``with`` block) removes its objects
from those class-level dictionaries.

The reference covers what scikit-fuzzy can express: min implication, max aggregation,
AND by min or product, OR by max or probabilistic OR, rule weights, NOT, and the
centroid, bisector, mom, som and lom defuzzifications.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from fuzzyservo.controllers.fuzzy.system import NO_TERM, FuzzySystem, term_index


def _probor(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a + b - a * b


class SkfuzzyReference:
    """A :class:`FuzzySystem` built as a ``skfuzzy.control.ControlSystem``."""

    def __init__(self, system: FuzzySystem):
        from skfuzzy import control as ctrl

        if system.implication != "min" or system.aggregation != "max":
            raise NotImplementedError(
                f"scikit-fuzzy offers min implication and max aggregation only, got "
                f"{system.implication!r} and {system.aggregation!r}"
            )
        self.system = system
        self._objects: list[object] = []
        self.antecedents = []
        for var in system.inputs:
            universe, table = var.table()
            a = ctrl.Antecedent(universe, var.name)
            for term, mf in zip(var.terms, table, strict=True):
                a[term.name] = mf
            self.antecedents.append(a)
        out = system.output
        universe, table = out.table()
        self.consequent = ctrl.Consequent(
            universe, out.name, defuzzify_method=system.defuzzification
        )
        for term, mf in zip(out.terms, table, strict=True):
            self.consequent[term.name] = mf
        and_func = np.fmin if system.and_method == "min" else np.multiply
        or_func = np.fmax if system.or_method == "max" else _probor
        rules = []
        for n, rule in enumerate(system.rules):
            antecedent = None
            for var, a, idx in zip(system.inputs, self.antecedents, rule.antecedent, strict=True):
                if idx == NO_TERM:
                    continue
                k, negated = term_index(idx)
                term = ~a[var.terms[k].name] if negated else a[var.terms[k].name]
                if antecedent is None:
                    antecedent = term
                elif rule.connective == "and":
                    antecedent = antecedent & term
                else:
                    antecedent = antecedent | term
            consequent = self.consequent[out.terms[rule.consequent].name] % rule.weight
            rules.append(
                ctrl.Rule(
                    antecedent, consequent, label=f"rule{n}", and_func=and_func, or_func=or_func
                )
            )
        self.control_system = ctrl.ControlSystem(rules)
        # cache=False: no per-input state is kept between computations
        self.simulation = ctrl.ControlSystemSimulation(self.control_system, cache=False)
        self._objects = [*self.antecedents, self.consequent, *rules]
        for var in (*self.antecedents, self.consequent):
            self._objects.extend(var.terms.values())
        for rule in rules:
            self._objects.extend(rule.consequent)
            self._objects.append(rule.antecedent)

    def compute(self, *inputs: float) -> float:
        """``ControlSystemSimulation.compute`` for one input point; inputs clipped to the universes."""
        for var, a, x in zip(self.system.inputs, self.antecedents, inputs, strict=True):
            self.simulation.input[a.label] = float(np.clip(x, var.low, var.high))
        self.simulation.compute()
        return float(self.simulation.output[self.consequent.label])

    def compute_many(self, points: Sequence[Sequence[float]]) -> np.ndarray:
        return np.array([self.compute(*p) for p in points])

    def close(self) -> None:
        """Drop this system's entries from scikit-fuzzy's class-level state."""
        from skfuzzy.control import antecedent_consequent, rule, state, term

        ids = {id(o) for o in self._objects}
        for module in (antecedent_consequent, rule, term):
            for cls in vars(module).values():
                if not isinstance(cls, type):
                    continue
                for attr in vars(cls).values():
                    if isinstance(attr, state.StatefulProperty):
                        for key in [k for k in attr.data if id(k) in ids]:
                            del attr.data[key]
        self._objects = []

    def __enter__(self) -> SkfuzzyReference:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
