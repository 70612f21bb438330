"""A fuzzy controller in words: its terms and rules (what MATLAB's showrule and the MF
editor show)."""

from __future__ import annotations

from fuzzyservo.controllers.fuzzy.controller import FuzzyController
from fuzzyservo.controllers.fuzzy.system import NO_TERM, term_index


def describe_fuzzy(controller: FuzzyController) -> str:
    """The system's type, methods and gains, each variable's terms, then the rules."""
    system = controller.system
    lines = [
        f"{controller.name}: {system.type.capitalize()}, form {controller.form}, "
        f"{len(system.rules)} rules, {system.semantics} semantics; "
        f"and {system.and_method}, or {system.or_method}, implication {system.implication}, "
        f"aggregation {system.aggregation}, defuzzification {system.defuzzification}; "
        f"gains input {controller.input_gain:g}, rate {controller.rate_gain:g}, output {controller.output_gain:g}"
    ]
    for role, var in [*(("input", v) for v in system.inputs), ("output", system.output)]:
        lines.append(f"  {role} {var.name} [{var.low:g}, {var.high:g}]")
        for t in var.terms:
            lines.append(f"    {t.name:<4} {t.shape:<8} [{' '.join(f'{p:.4g}' for p in t.params)}]")
    names = [v.name for v in system.inputs]
    for n, rule in enumerate(system.rules, start=1):
        parts = []
        for var, name, idx in zip(system.inputs, names, rule.antecedent, strict=True):
            if idx == NO_TERM:
                continue
            k, negated = term_index(idx)
            parts.append(f"{name} is {'not ' if negated else ''}{var.terms[k].name}")
        joined = f" {rule.connective} ".join(parts)
        weight = f" ({rule.weight:g})" if rule.weight != 1 else ""
        k, negated = term_index(rule.consequent)
        then = f"{'not ' if negated else ''}{system.output.terms[k].name}" if k >= 0 else "(none)"
        lines.append(f"  {n}. if {joined} then {system.output.name} is {then}{weight}")
    return "\n".join(lines)
