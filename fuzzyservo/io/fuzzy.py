"""Fuzzy controller files (YAML, ``kind: fuzzy``) to :class:`FuzzyController` objects.

    name: flc1_translated
    kind: fuzzy
    form: p                       # p | pd | pi
    input:                        # the error [V]; a seven-term design ...
      range: [-2, 2]
      increments: [0.5, 1, 1, 1, 1, 1, 1, 0.5]   # left shoulder, 6 gaps, right shoulder
      reshape: 1.0                # γ > 1 pulls the inner terms toward zero
      translate: 0.0
    rate: {...}                   # pd / two-input pi: the error rate [V/s]
    output:                       # ... or explicit terms
      range: [-3, 3]
      terms: {NB: [trapmf, [-9, -9, -2.57, -1.71]], NM: [trimf, [...]], ...}
    rules: identity               # | macvicar_whelan | 7x7 table of output terms | list of rule lines
    methods: {and: min, or: max, implication: min, aggregation: max, defuzzification: centroid}
    points: 201                   # universe samples (breakpoints are added)
    semantics: skfuzzy            # | matlab: evalfis (exact membership, sample_points output samples)
    sample_points: 101
    gains: {input: 1, rate: 1, output: 1}
    output_limits: [-10, 10]

Rule lines: ``"NB -> NB"``, ``"NB and PS -> NM"``, ``"~Z or PB -> PS 0.5"`` (``~`` NOT,
``-`` no condition on that input, a trailing number is the weight).
"""

from __future__ import annotations

import math
import re

from fuzzyservo.controllers.fuzzy.controller import FORMS, FuzzyController
from fuzzyservo.controllers.fuzzy.design import (
    SEVEN_TERMS,
    UNIFORM_INCREMENTS,
    FuzzyDesign,
    SevenTermDesign,
    identity_rules,
    macvicar_whelan,
    table_rules,
)
from fuzzyservo.controllers.fuzzy.system import (
    AGGREGATIONS,
    AND_METHODS,
    IMPLICATIONS,
    MAMDANI_DEFUZZIFICATIONS,
    MATLAB_SAMPLE_POINTS,
    NO_TERM,
    OR_METHODS,
    SEMANTICS,
    SHAPES,
    FuzzySystem,
    Rule,
    Term,
    Variable,
    term_code,
    term_index,
)
from fuzzyservo.errors import ConfigError, excerpt
from fuzzyservo.io._yaml import Node
from fuzzyservo.limits import MAX_SAMPLE_POINTS, points_problem

KEYS = (
    "form", "input", "rate", "output", "rules", "methods", "points", "gains", "semantics",
    "sample_points",
)  # fmt: skip
_VAR_KEYS = ("name", "range", "increments", "reshape", "translate", "terms")
_METHODS = {
    "and": AND_METHODS,
    "or": OR_METHODS,
    "implication": IMPLICATIONS,
    "aggregation": AGGREGATIONS,
    "defuzzification": MAMDANI_DEFUZZIFICATIONS,
}


def fuzzy_from_node(
    root: Node, name: str, limits: dict[str, float], description: str
) -> FuzzyController:
    """Build the controller described by a ``kind: fuzzy`` file (already checked for top-level keys)."""
    form = root.str("form", default="p")
    if form not in FORMS:
        root.fail(f"unknown form {excerpt(form)}; choose one of {list(FORMS)}", key="form")
    points = root.number("points", default=201)
    problem = points_problem(points)
    if problem:
        root.fail(problem, key="points")
    points = int(points)
    two_inputs = form == "pd" or root.has("rate")
    inputs = [_variable(root.child("input"), "e", points)]
    if two_inputs:
        if not root.has("rate"):
            root.fail(f"form {excerpt(form)} needs a 'rate' input (the error rate); add it")
        inputs.append(_variable(root.child("rate"), "de", points))
    elif form == "pd":
        root.fail("form 'pd' needs a 'rate' input; add it")
    output = _variable(root.child("output"), "u", points)
    rules = _rules(root, [_built(v) for v in inputs], _built(output))
    methods = root.child("methods", default={})
    methods.only(_METHODS)
    chosen = {}
    for key, allowed in _METHODS.items():
        value = methods.str(key, default=allowed[0])
        if value not in allowed:
            methods.fail(f"unknown method {excerpt(value)}; choose one of {list(allowed)}", key=key)
        chosen[key] = value
    semantics = root.str("semantics", default="skfuzzy")
    if semantics not in SEMANTICS:
        root.fail(
            f"unknown semantics {excerpt(semantics)}; choose one of {list(SEMANTICS)}",
            key="semantics",
        )
    sample_points = root.number("sample_points", default=MATLAB_SAMPLE_POINTS)
    problem = points_problem(sample_points, MATLAB_SAMPLE_POINTS, MAX_SAMPLE_POINTS)
    if problem:
        root.fail(problem, key="sample_points")
    gains = root.child("gains", default={})
    gains.only(("input", "rate", "output"))
    gain_values = {k: gains.number(k, default=1.0) for k in ("input", "rate", "output")}
    for k, v in gain_values.items():
        if v == 0:
            gains.fail("must not be zero; a zero gain disconnects the controller", key=k)
    design = FuzzyDesign(
        inputs=tuple(inputs),
        output=output,
        rules=rules,
        form=form,
        input_gain=gain_values["input"],
        rate_gain=gain_values["rate"],
        output_gain=gain_values["output"],
        and_method=chosen["and"],
        or_method=chosen["or"],
        implication=chosen["implication"],
        aggregation=chosen["aggregation"],
        defuzzification=chosen["defuzzification"],
        semantics=semantics,
        sample_points=int(sample_points),
        name=name,
        description=description,
        **limits,
    )
    try:
        return design.controller()
    except ValueError as exc:
        root.fail(f"{exc}")


def _variable(node: Node, default_name: str, points: int) -> SevenTermDesign | Variable:
    node.only(_VAR_KEYS)
    name = node.str("name", default=default_name)
    lo_hi = node.numbers("range")
    if len(lo_hi) != 2 or not lo_hi[0] < lo_hi[1]:
        node.fail(
            f"must be [low, high] with low < high, got {excerpt(lo_hi)}; a range of zero width has no terms",
            key="range",
        )
    low, high = lo_hi
    if node.has("terms"):
        for key in ("increments", "reshape", "translate"):
            if node.has(key):
                node.fail(
                    f"'{key}' shapes a seven-term design; with explicit 'terms' remove it", key=key
                )
        return _explicit(node.child("terms"), name, low, high, points)
    increments = node.numbers("increments", default=list(UNIFORM_INCREMENTS))
    if len(increments) != 8 or not all(d > 0 for d in increments):
        node.fail(
            f"needs 8 positive numbers (left shoulder, 6 gaps between NB..PB, right shoulder), got {excerpt(increments)}",
            key="increments",
        )
    reshape = node.number("reshape", default=1.0)
    if not reshape > 0:
        node.fail(f"must be > 0 (1 leaves the terms as they are), got {reshape}", key="reshape")
    try:
        design = SevenTermDesign(
            name, low, high, tuple(increments), reshape, node.number("translate", default=0.0),
            points,
        )  # fmt: skip
        design.variable()  # a problem of the terms fails here, at this variable's key
        return design
    except ValueError as exc:
        node.fail(str(exc))


def _built(var: SevenTermDesign | Variable) -> Variable:
    return var.variable() if isinstance(var, SevenTermDesign) else var


def _explicit(node: Node, name: str, low: float, high: float, points: int) -> Variable:
    terms = []
    for term_name, spec in node.data.items():
        key = str(term_name)
        if not (isinstance(spec, list) and len(spec) == 2 and isinstance(spec[1], list)):
            node.fail(
                f"write a term as [shape, [parameters]], e.g. [trimf, [-1, 0, 1]]; got {excerpt(spec)}",
                key=key,
            )
        shape, params = spec
        if shape not in SHAPES:
            node.fail(f"unknown shape {excerpt(shape)}; choose one of {sorted(SHAPES)}", key=key)
        if not all(isinstance(p, int | float) and not isinstance(p, bool) for p in params):
            node.fail(f"parameters must be numbers, got {excerpt(params)}", key=key)
        try:
            terms.append(Term(key, shape, tuple(float(p) for p in params)))
        except ValueError as exc:
            node.fail(str(exc), key=key)
    try:
        return Variable(name, low, high, tuple(terms), points)
    except ValueError as exc:
        node.fail(str(exc))


_RULE = re.compile(
    r"^\s*(?P<a>[~\w-]+)\s*(?:(?P<conn>and|or)\s+(?P<b>[~\w-]+)\s*)?->\s*(?P<c>\w+)\s*(?P<w>[0-9.eE+-]+)?\s*$"
)


def _rules(root: Node, inputs: list[Variable], output: Variable) -> tuple[Rule, ...]:
    raw = root.data.get("rules", "identity" if len(inputs) == 1 else "macvicar_whelan")
    key = "rules"
    seven = tuple(t.name for t in output.terms) == SEVEN_TERMS
    if raw == "identity":
        if len(inputs) != 1 or len(inputs[0].terms) != len(output.terms):
            root.fail("'identity' needs one input with as many terms as the output", key=key)
        return identity_rules(len(output.terms))
    if raw == "macvicar_whelan":
        if len(inputs) != 2 or not seven:
            root.fail(
                "'macvicar_whelan' needs two seven-term inputs and a seven-term output", key=key
            )
        return table_rules(macvicar_whelan())
    if not isinstance(raw, list) or not raw:
        root.fail(
            "write 'identity', 'macvicar_whelan', a table (list of rows) or a list of rule lines",
            key=key,
        )
    if all(isinstance(row, list) for row in raw):
        if len(inputs) != 2:
            root.fail(
                "a rule table needs two inputs (rows: error terms, columns: rate terms)", key=key
            )
        n_rows, n_cols = len(inputs[0].terms), len(inputs[1].terms)
        if len(raw) != n_rows or any(len(row) != n_cols for row in raw):
            root.fail(f"the table must have {n_rows} rows of {n_cols} output terms", key=key)
        table = [
            [_term_index(root, output, str(c), f"rules[{i}][{j}]") for j, c in enumerate(row)]
            for i, row in enumerate(raw)
        ]
        return table_rules(table)
    rules = []
    for n, line in enumerate(raw):
        where = f"rules[{n}]"
        m = _RULE.match(str(line))
        if not m:
            root.fail(
                f"cannot read rule {excerpt(line)}; write it like 'NB -> NB' or 'NS and PS -> Z 0.5'",
                key=where,
            )
        names = [m["a"]] + ([m["b"]] if m["b"] else [])
        if len(names) != len(inputs):
            root.fail(
                f"rule {excerpt(line)} names {len(names)} input term(s) for {len(inputs)} input(s)",
                key=where,
            )
        antecedent = []
        for var, term in zip(inputs, names, strict=True):
            if term == "-":
                antecedent.append(NO_TERM)
                continue
            k = _term_index(root, var, term.lstrip("~"), where)
            antecedent.append(term_code(k, negated=term.startswith("~")))
        weight = float(m["w"]) if m["w"] else 1.0
        try:
            rules.append(
                Rule(
                    tuple(antecedent),
                    _term_index(root, output, m["c"], where),
                    weight,
                    m["conn"] or "and",
                )
            )
        except ValueError as exc:
            root.fail(str(exc), key=where)
    return tuple(rules)


def _term_index(root: Node, var: Variable, term: str, where: str) -> int:
    try:
        return var.index(term)
    except KeyError:
        root.fail(
            f"{excerpt(var.name)} has no term {excerpt(term)}; its terms are {[t.name for t in var.terms]}",
            key=where,
        )
    raise ConfigError("unreachable")  # pragma: no cover


def rule_text(system: FuzzySystem, rule: Rule) -> str:
    """One rule as a rule line ``"NB and PS -> NM 0.5"`` (what :func:`_rules` reads back)."""
    names = [_term_text(v, idx) for v, idx in zip(system.inputs, rule.antecedent, strict=True)]
    weight = f" {rule.weight:g}" if rule.weight != 1.0 else ""
    then = _term_text(system.output, rule.consequent)
    return f" {rule.connective} ".join(names) + f" -> {then}{weight}"


def _term_text(var: Variable, code: int) -> str:
    """A term code as a rule line writes it: ``NB``, ``~NB`` (NOT NB) or ``-`` (none)."""
    if code == NO_TERM:
        return "-"
    k, negated = term_index(code)
    return ("~" if negated else "") + var.terms[k].name


def fuzzy_controller_data(controller: FuzzyController) -> dict:
    """The ``kind: fuzzy`` mapping of a controller, with explicit terms and rule lines.

    What a controller read from a ``.fis`` (or edited term by term) is written back as;
    :func:`fuzzyservo.io.controllers.controller_from_data` rebuilds the same controller.
    """
    system = controller.system

    def variable(var: Variable) -> dict:
        return {
            "name": var.name,
            "range": [var.low, var.high],
            "terms": {t.name: [t.shape, list(t.params)] for t in var.terms},
        }

    data: dict = {"name": controller.name, "kind": "fuzzy", "form": controller.form}
    if controller.description:
        data["description"] = controller.description
    data["input"] = variable(system.inputs[0])
    if len(system.inputs) == 2:
        data["rate"] = variable(system.inputs[1])
    data["output"] = variable(system.output)
    data["rules"] = [rule_text(system, r) for r in system.rules]
    data["methods"] = {
        "and": system.and_method,
        "or": system.or_method,
        "implication": system.implication,
        "aggregation": system.aggregation,
        "defuzzification": system.defuzzification,
    }
    data["points"] = system.output.points
    data["gains"] = {
        "input": controller.input_gain,
        "rate": controller.rate_gain,
        "output": controller.output_gain,
    }
    if controller.has_limits:
        data["output_limits"] = [controller.u_min, controller.u_max]
    return data


def design_data(design: FuzzyDesign) -> dict:
    """The ``kind: fuzzy`` mapping of a design: seven-term variables by their range,
    increments, reshape and translation, explicit ones term by term, rule lines.
    :func:`fuzzyservo.io.controllers.controller_from_data` rebuilds the same controller."""
    system = design.controller().system

    def variable(var: SevenTermDesign | Variable) -> dict:
        if isinstance(var, Variable):
            return {
                "name": var.name,
                "range": [var.low, var.high],
                "terms": {t.name: [t.shape, list(t.params)] for t in var.terms},
            }
        return {
            "name": var.name,
            "range": [var.low, var.high],
            "increments": list(var.increments),
            "reshape": var.reshape,
            "translate": var.translate,
        }

    data: dict = {"name": design.name, "kind": "fuzzy", "form": design.form}
    if design.description:
        data["description"] = design.description
    data |= {slot: variable(var) for slot, var in design.slots().items()}
    if len(design.inputs) == 1 and design.rules == identity_rules(len(system.output.terms)):
        data["rules"] = "identity"
    elif design.rules == table_rules(macvicar_whelan()):
        data["rules"] = "macvicar_whelan"
    else:
        data["rules"] = [rule_text(system, r) for r in system.rules]
    data["methods"] = {
        "and": design.and_method,
        "or": design.or_method,
        "implication": design.implication,
        "aggregation": design.aggregation,
        "defuzzification": design.defuzzification,
    }
    data["points"] = design.output.points
    data["semantics"] = design.semantics
    if design.semantics == "matlab":
        data["sample_points"] = design.sample_points
    data["gains"] = {
        "input": design.input_gain,
        "rate": design.rate_gain,
        "output": design.output_gain,
    }
    if math.isfinite(design.u_min) and math.isfinite(design.u_max):
        data["output_limits"] = [design.u_min, design.u_max]
    return data
