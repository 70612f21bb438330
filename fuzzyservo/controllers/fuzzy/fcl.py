"""IEC 61131-7 Fuzzy Control Language (FCL) text ⇄ :class:`FuzzySystem` (pure, as
:mod:`.fis`; the files are read and written by :mod:`fuzzyservo.io.fuzzy_files`).

::

    FUNCTION_BLOCK tipper
    VAR_INPUT
        service : REAL;
    END_VAR
    VAR_OUTPUT
        tip : REAL;
    END_VAR
    FUZZIFY service
        RANGE := (0 .. 10);
        TERM poor := gaussmf 1.5 0;
        TERM good := (4, 0) (5, 1) (6, 0);
    END_FUZZIFY
    DEFUZZIFY tip
        RANGE := (0 .. 30);
        TERM cheap := (0, 0) (5, 1) (10, 0);
        METHOD : COG;
        DEFAULT := 15;
    END_DEFUZZIFY
    RULEBLOCK rules
        AND : MIN;
        OR : MAX;
        ACT : MIN;
        ACCU : MAX;
        RULE 1 : IF service IS poor OR food IS NOT rancid THEN tip IS cheap WITH 0.5;
    END_RULEBLOCK
    END_FUNCTION_BLOCK

The standard's terms: points ``(x, μ) …`` (read as trimf for three points rising 0, 1,
0 and trapmf for four points 0, 1, 1, 0, as MATLAB's and fuzzylite's converters do) and
singletons ``TERM z := 5;`` (Sugeno constants); its methods: AND MIN/PROD, OR MAX/ASUM
(probabilistic OR), ACT MIN/PROD, ACCU MAX/NSUM (MATLAB's sum: the normalisation does
not move any defuzzified value), METHOD COG, COA (bisector), MM, LM, RM (mean, smallest,
largest of maximum), COGS (weighted average of singletons). MATLAB's other shapes are
written as ``TERM n := <MATLAB name> <parameters>;`` (jFuzzyLogic writes its extra shapes
alike), linear Sugeno terms as ``TERM n := linear c1 … cn c0;``, weighted sum as
``METHOD : WTSUM;``, probor aggregation as ``ACCU : PROBOR;`` and negated consequents as
``THEN u IS NOT t``: these are extensions. ``(* fuzzyservo: … *)`` carries the
evaluation settings, as in :mod:`.fis`, so a round trip is lossless.
"""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path
from typing import NoReturn

from fuzzyservo.controllers.fuzzy.controller import FuzzyController
from fuzzyservo.controllers.fuzzy.fis import LAW_KEYS, controller_from_law
from fuzzyservo.controllers.fuzzy.fis import number_text as _num
from fuzzyservo.controllers.fuzzy.shapes import SUGENO_SHAPES
from fuzzyservo.controllers.fuzzy.system import (
    MATLAB_SAMPLE_POINTS,
    NO_TERM,
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
from fuzzyservo.limits import MAX_POINTS, MAX_SAMPLE_POINTS, points_problem

__all__ = ["fcl_names", "fcl_text", "parse_fcl", "parse_fcl_controller", "parse_fcl_law"]

_AND = {"MIN": "min", "PROD": "prod"}
_OR = {"MAX": "max", "ASUM": "probor", "PROBOR": "probor"}
_ACT = {"MIN": "min", "PROD": "prod"}
_ACCU = {"MAX": "max", "NSUM": "sum", "SUM": "sum", "PROBOR": "probor", "ASUM": "probor"}
_METHOD = {
    "COG": "centroid",
    "COA": "bisector",
    "MM": "mom",
    "LM": "som",
    "RM": "lom",
    "COGS": "wtaver",
    "WTSUM": "wtsum",
}
_BLOCK_WORDS = re.compile(
    r"(?=\b(?:VAR_INPUT|VAR_OUTPUT|END_VAR|END_FUZZIFY|END_DEFUZZIFY|END_RULEBLOCK|"
    r"END_FUNCTION_BLOCK)\b)|(?<=\bVAR_INPUT)|(?<=\bVAR_OUTPUT)"
)
_IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_TAG = "fuzzyservo:"
_KEYWORDS = {"IS", "NOT", "AND", "OR", "IF", "THEN", "WITH", "RULE", "TERM", "RANGE"}


def _fail(file: str, line: int, message: str) -> NoReturn:
    raise ConfigError(message, file=file, key=f"line {line}")


def _strip_comments(text: str) -> tuple[str, dict[str, str]]:
    """Text without ``(* … *)`` and ``//`` comments (newlines kept); the fuzzyservo settings."""
    settings: dict[str, str] = {}

    def block(m: re.Match) -> str:
        body = m.group(1).strip()
        if body.startswith(_TAG):
            for item in body[len(_TAG) :].split():
                key, _, value = item.partition("=")
                settings[key] = value
        return "\n" * m.group(0).count("\n")

    text = re.sub(r"\(\*(.*?)\*\)", block, text, flags=re.S)
    return re.sub(r"//[^\n]*", "", text), settings


def parse_fcl(text: str, file: str = "<fcl text>", points: int = 201) -> FuzzySystem:
    """The :class:`FuzzySystem` of an FCL function block (module docstring)."""
    body, settings = _strip_comments(text)
    statements: list[tuple[int, str]] = []  # (line, statement) split at ';' and block keywords
    for number, raw in enumerate(body.splitlines(), start=1):
        for piece in raw.split(";"):
            # block keywords may share a line with what they open or close
            for part in re.split(_BLOCK_WORDS, piece):
                part = part.strip()
                if part:
                    statements.append((number, part))
    # glue statements continued over several lines (a rule over two lines)
    merged: list[tuple[int, str]] = []
    for number, part in statements:
        starts = re.match(
            r"^(FUNCTION_BLOCK|END_FUNCTION_BLOCK|VAR_INPUT|VAR_OUTPUT|VAR|END_VAR|FUZZIFY|"
            r"END_FUZZIFY|DEFUZZIFY|END_DEFUZZIFY|RULEBLOCK|END_RULEBLOCK|TERM|RANGE|RULE|"
            r"(?:METHOD|DEFAULT|ACCU|ACT|AND|OR)\s*:|[A-Za-z_]\w*\s*:\s*REAL)",
            part,
            flags=re.I,
        )
        if merged and not starts and not merged[-1][1].upper().startswith("END_"):
            merged[-1] = (merged[-1][0], merged[-1][1] + " " + part)
        else:
            merged.append((number, part))

    name = Path(file).stem
    inputs: list[str] = []
    outputs: list[str] = []
    ranges: dict[str, tuple[float, float]] = {}
    terms: dict[str, list[Term]] = {}
    methods: dict[str, str] = {}
    rule_texts: list[tuple[int, str]] = []
    section: tuple[str, str] | None = None
    seen_block = False
    for number, st in merged:
        word = st.split()[0].upper()
        if word == "FUNCTION_BLOCK":
            seen_block = True
            parts = st.split()
            name = parts[1] if len(parts) > 1 else name
        elif word in ("VAR_INPUT", "VAR_OUTPUT"):
            section = (word, "")
        elif word == "END_VAR":
            section = None
        elif section and section[0] in ("VAR_INPUT", "VAR_OUTPUT") and ":" in st:
            var = st.split(":")[0].strip()
            (inputs if section[0] == "VAR_INPUT" else outputs).append(var)
        elif word in ("FUZZIFY", "DEFUZZIFY"):
            parts = st.split()
            if len(parts) != 2:
                _fail(file, number, f"write '{word} <variable>', got {excerpt(st)}")
            var = parts[1]
            if var not in (inputs if word == "FUZZIFY" else outputs):
                where = "VAR_INPUT" if word == "FUZZIFY" else "VAR_OUTPUT"
                _fail(
                    file,
                    number,
                    f"{word} {var}: {excerpt(var)} is not declared in {where}; declare it",
                )
            section = (word, var)
            terms.setdefault(var, [])
        elif word in ("END_FUZZIFY", "END_DEFUZZIFY", "END_RULEBLOCK", "END_FUNCTION_BLOCK"):
            section = None
        elif word == "RULEBLOCK":
            if "rules" in methods:
                _fail(file, number, "only one RULEBLOCK is supported; merge them")
            methods["rules"] = "1"
            section = ("RULEBLOCK", "")
        elif word == "TERM" and section and section[0] in ("FUZZIFY", "DEFUZZIFY"):
            terms[section[1]].append(_term(file, number, st))
        elif word == "RANGE" and section:
            m = re.match(r"^RANGE\s*:=\s*\(\s*(\S+)\s*\.\.\s*(\S+)\s*\)$", st, flags=re.I)
            if not m:
                _fail(file, number, f"write RANGE := (low .. high), got {excerpt(st)}")
            ranges[section[1]] = (_float(file, number, m[1]), _float(file, number, m[2]))
        elif section and section[0] == "RULEBLOCK" and word == "RULE":
            rule_texts.append((number, st))
        elif section and word in ("AND", "OR", "ACT", "ACCU", "METHOD", "DEFAULT"):
            m = re.match(r"^(\w+)\s*:=?\s*(\S+)$", st)
            if not m:
                _fail(file, number, f"write {word} : <method>, got {excerpt(st)}")
            key, value = word, m[2].upper()
            if key == "DEFAULT":
                continue  # the no-rule value: the semantics decide it (mid-range or NaN)
            table = {"AND": _AND, "OR": _OR, "ACT": _ACT, "ACCU": _ACCU, "METHOD": _METHOD}[key]
            if value not in table:
                _fail(file, number, f"unsupported {key} {value} (supported: {', '.join(table)})")
            methods[key] = table[value]
        else:
            _fail(file, number, f"cannot read {excerpt(st)} here; see IEC 61131-7 (FCL)")
    if not seen_block:
        _fail(file, 1, "no FUNCTION_BLOCK; is this an FCL file?")
    if not inputs or not outputs:
        _fail(file, 1, "needs VAR_INPUT and VAR_OUTPUT declarations")
    if not rule_texts:
        _fail(file, 1, "no rules; add a RULEBLOCK with RULE lines")

    def variable(var: str, default_points: int) -> Variable:
        if var not in ranges:
            _fail(file, 1, f"variable {excerpt(var)} has no RANGE := (low .. high); add it")
        if var not in terms or not terms[var]:
            if var in inputs:
                terms.setdefault(var, [])
            else:
                _fail(file, 1, f"output {excerpt(var)} has no terms; add a DEFUZZIFY block")
        try:
            return Variable(var, *ranges[var], tuple(terms[var]), default_points)
        except ValueError as exc:
            _fail(file, 1, str(exc))

    def count(key: str, default: int, most: int = MAX_POINTS) -> int:
        value = settings.get(key, str(default))
        problem = points_problem(value, default, most)
        if problem:
            _fail(file, 1, f"fuzzyservo setting {key} {problem}")
        return int(value)

    pts = count("points", points)
    in_vars = [variable(v, count(f"{v}.points", pts)) for v in inputs]
    out_vars = [variable(v, count(f"{v}.points", pts)) for v in outputs]
    sugeno = all(t.is_sugeno for v in out_vars for t in v.terms)
    rules = tuple(_rule(file, number, st, in_vars, out_vars) for number, st in rule_texts)
    semantics = settings.get("semantics", "skfuzzy")
    if semantics not in SEMANTICS:
        _fail(file, 1, f"semantics must be one of {list(SEMANTICS)}, got {excerpt(semantics)}")
    defuzz = methods.get("METHOD", "wtaver" if sugeno else "centroid")
    sample_points = count("sample_points", MATLAB_SAMPLE_POINTS, MAX_SAMPLE_POINTS)
    try:
        return FuzzySystem(
            name=name,
            inputs=tuple(in_vars),
            output=out_vars[0],
            other_outputs=tuple(out_vars[1:]),
            rules=rules,
            and_method=methods.get("AND", "min"),
            or_method=methods.get("OR", "max"),
            implication=methods.get("ACT", "min"),
            aggregation=methods.get("ACCU", "max"),
            defuzzification=defuzz,
            type="sugeno" if sugeno else "mamdani",
            semantics=semantics,
            sample_points=sample_points,
        )
    except ValueError as exc:
        _fail(file, 1, str(exc))


def _float(file: str, line: int, text: str) -> float:
    try:
        return float(text)
    except ValueError:
        _fail(file, line, f"{excerpt(text)} is not a number")


def _term(file: str, line: int, st: str) -> Term:
    m = re.match(r"^TERM\s+(\w+)\s*:=\s*(.+)$", st, flags=re.I)
    if not m:
        _fail(
            file,
            line,
            f"write TERM name := (x, y) (x, y) … or TERM name := shape p1 p2 …; got {excerpt(st)}",
        )
    name, spec = m[1], m[2].strip()
    try:
        if spec.startswith("("):
            pairs = re.findall(r"\(\s*([^,()]+?)\s*,\s*([^,()]+?)\s*\)", spec)
            xs = [float(a) for a, _ in pairs]
            ys = [float(b) for _, b in pairs]
            if ys == [0.0, 1.0, 0.0]:
                return Term(name, "trimf", tuple(xs))
            if ys == [0.0, 1.0, 1.0, 0.0]:
                return Term(name, "trapmf", tuple(xs))
            if ys == [1.0, 1.0, 0.0] or ys == [1.0, 0.0]:  # left shoulder
                return Term(name, "trapmf", (xs[0], xs[0], *xs[-2:]))
            if ys == [0.0, 1.0, 1.0] or ys == [0.0, 1.0]:  # right shoulder
                return Term(name, "trapmf", (*xs[:2], xs[-1], xs[-1]))
            _fail(
                file,
                line,
                f"term {name}: points {excerpt(list(zip(xs, ys, strict=True)))} are not a triangle "
                "(0 1 0), trapezoid (0 1 1 0) or shoulder; general point lists are not supported",
            )
        parts = spec.split()
        if len(parts) == 1:
            return Term(name, "constant", (float(parts[0]),))  # a singleton
        shape = parts[0]
        if shape not in SHAPES and shape not in SUGENO_SHAPES:
            _fail(
                file,
                line,
                f"term {name}: unknown shape {excerpt(shape)} (known: {', '.join(SHAPES)}, linear)",
            )
        return Term(name, shape, tuple(float(p) for p in parts[1:]))
    except ConfigError:
        raise
    except ValueError as exc:
        _fail(file, line, f"term {name}: {exc}")


_RULE = re.compile(
    r"^RULE\s+\w+\s*:\s*IF\s+(?P<ante>.+?)\s+THEN\s+(?P<cons>.+?)(?:\s+WITH\s+(?P<w>\S+))?$",
    flags=re.I,
)


def _rule(file: str, line: int, st: str, inputs: list[Variable], outputs: list[Variable]) -> Rule:
    m = _RULE.match(st)
    if not m:
        _fail(
            file,
            line,
            f"write RULE n : IF x IS a AND y IS b THEN u IS c [WITH w]; got {excerpt(st)}",
        )
    ante = m["ante"].strip()
    conns = {c.upper() for c in re.findall(r"\s(AND|OR)\s", f" {ante} ", flags=re.I)}
    if len(conns) > 1:
        _fail(
            file,
            line,
            "a rule mixing AND and OR is not supported (MATLAB has one connective per rule)",
        )
    parts = re.split(r"\s+(?:AND|OR)\s+", ante, flags=re.I)
    antecedent = [-1] * len(inputs)
    for part in parts:
        antecedent_var, idx = _clause(file, line, part.strip("() "), inputs)
        antecedent[antecedent_var] = idx
    consequents = [-1] * len(outputs)
    for part in re.split(r"\s*,\s*", m["cons"].strip()):
        k, idx = _clause(file, line, part, outputs)
        consequents[k] = idx
    weight = _float(file, line, m["w"]) if m["w"] else 1.0
    try:
        return Rule(
            tuple(antecedent),
            consequents[0],
            weight,
            "or" if conns == {"OR"} else "and",
            tuple(consequents[1:]),
        )
    except ValueError as exc:
        _fail(file, line, str(exc))


def _clause(file: str, line: int, text: str, variables: list[Variable]) -> tuple[int, int]:
    m = re.match(r"^(\w+)\s+IS\s+(NOT\s+)?(\w+)$", text.strip(), flags=re.I)
    if not m:
        _fail(
            file,
            line,
            f"cannot read {excerpt(text)}; write 'variable IS term' or 'variable IS NOT term'",
        )
    names = [v.name for v in variables]
    if m[1] not in names:
        _fail(file, line, f"{excerpt(m[1])} is not one of {names}")
    k = names.index(m[1])
    terms = [t.name for t in variables[k].terms]
    if m[3] not in terms:
        _fail(file, line, f"{m[1]} has no term {excerpt(m[3])}; its terms are {terms}")
    t = terms.index(m[3])
    return k, term_code(t, negated=bool(m[2]))


def parse_fcl_law(text: str, file: str = "<fcl text>") -> tuple[FuzzySystem, dict[str, str]]:
    """The system of FCL text and the control law its ``(* fuzzyservo: … *)`` comment
    gives (empty when it gives none)."""
    law = {k: v for k, v in _strip_comments(text)[1].items() if k in LAW_KEYS}
    return parse_fcl(text, file), law


def parse_fcl_controller(text: str, file: str) -> FuzzyController:
    """A controller from FCL text (a file named ``file``): the control law of its
    ``(* fuzzyservo: … *)`` comment, else the defaults of
    :func:`~fuzzyservo.controllers.fuzzy.fis.parse_fis_controller`."""
    return controller_from_law(*parse_fcl_law(text, file), Path(file), "line 1")


# --------------------------------------------------------------------------- writing
def _name(name: str, what: str) -> str:
    if not _IDENT.match(name) or name.upper() in _KEYWORDS:
        raise ValueError(
            f"{what} {excerpt(name)} is not an FCL identifier (letters, digits, _; not a keyword); rename it"
        )
    return name


def _term_text(t: Term) -> str:
    p = t.params
    if t.shape == "trimf" and len(p) == 3:
        return f"({_num(p[0])}, 0) ({_num(p[1])}, 1) ({_num(p[2])}, 0)"
    if t.shape == "trapmf" and len(p) == 4:
        return f"({_num(p[0])}, 0) ({_num(p[1])}, 1) ({_num(p[2])}, 1) ({_num(p[3])}, 0)"
    if t.shape == "constant":
        return _num(p[0])
    return " ".join([t.shape, *(_num(v) for v in p)])


def fcl_text(system: FuzzySystem, law: str = "") -> str:
    """``system`` as an FCL function block (module docstring), with the control law
    ``law`` (:func:`~fuzzyservo.controllers.fuzzy.fis.law_text`) in a comment when given."""
    variables = [*system.inputs, *system.outputs]
    for v in variables:
        _name(v.name, "variable name")
        names = [t.name for t in v.terms]
        if len(set(names)) != len(names):
            raise ValueError(
                f"variable {excerpt(v.name)}: FCL refers to terms by name; make {names} unique"
            )
        for t in v.terms:
            _name(t.name, "term name")
    points = max({v.points for v in variables}, key=[v.points for v in variables].count)
    inv: dict[str, dict[str, str]] = {}
    inv["and"] = {v: k for k, v in _AND.items()}
    inv["or"] = {"max": "MAX", "probor": "ASUM"}
    inv["act"] = {v: k for k, v in _ACT.items()}
    inv["accu"] = {"max": "MAX", "sum": "NSUM", "probor": "PROBOR"}
    inv["m"] = {v: k for k, v in _METHOD.items()}
    lines = [
        f"(* {_TAG} semantics={system.semantics} sample_points={system.sample_points} "
        f"points={points}"
        + "".join(f" {v.name}.points={v.points}" for v in variables if v.points != points)
        + " *)",
        *([f"(* {_TAG} {law} *)"] if law else []),
        f"FUNCTION_BLOCK {_name(system.name, 'system name')}",
        "",
        "VAR_INPUT",
        *(f"    {v.name} : REAL;" for v in system.inputs),
        "END_VAR",
        "",
        "VAR_OUTPUT",
        *(f"    {v.name} : REAL;" for v in system.outputs),
        "END_VAR",
        "",
    ]
    for v in system.inputs:
        lines += [f"FUZZIFY {v.name}", f"    RANGE := ({_num(v.low)} .. {_num(v.high)});"]
        lines += [f"    TERM {t.name} := {_term_text(t)};" for t in v.terms]
        lines += ["END_FUZZIFY", ""]
    for v in system.outputs:
        lines += [f"DEFUZZIFY {v.name}", f"    RANGE := ({_num(v.low)} .. {_num(v.high)});"]
        lines += [f"    TERM {t.name} := {_term_text(t)};" for t in v.terms]
        lines += [
            f"    METHOD : {inv['m'][system.defuzzification]};",
            f"    DEFAULT := {_num(0.5 * (v.low + v.high))};",
            "END_DEFUZZIFY",
            "",
        ]
    lines += [
        "RULEBLOCK rules",
        f"    AND : {inv['and'][system.and_method]};",
        f"    OR : {inv['or'][system.or_method]};",
        f"    ACT : {inv['act'][system.implication]};",
        f"    ACCU : {inv['accu'][system.aggregation]};",
    ]
    for n, rule in enumerate(system.rules, start=1):
        clauses = []
        for v, idx in zip(system.inputs, rule.antecedent, strict=True):
            if idx == NO_TERM:
                continue
            k, negated = term_index(idx)
            clauses.append(f"{v.name} IS {'NOT ' if negated else ''}{v.terms[k].name}")
        heads = []
        for v, idx in zip(system.outputs, rule.consequents, strict=True):
            if idx == NO_TERM:
                continue
            k, negated = term_index(idx)
            heads.append(f"{v.name} IS {'NOT ' if negated else ''}{v.terms[k].name}")
        if not heads:
            raise ValueError(
                f"rule {n} concludes nothing (every consequent 0); FCL cannot say that"
            )
        conn = " AND " if rule.connective == "and" else " OR "
        weight = f" WITH {_num(rule.weight)}" if rule.weight != 1.0 else ""
        lines.append(f"    RULE {n} : IF {conn.join(clauses)} THEN {', '.join(heads)}{weight};")
    lines += ["END_RULEBLOCK", "", "END_FUNCTION_BLOCK"]
    return "\n".join(lines) + "\n"


def fcl_names(system: FuzzySystem) -> tuple[FuzzySystem, list[str]]:
    """``system`` with term names FCL can refer to: a repeated name gets ``_2``, ``_3`` …
    (MATLAB refers to terms by number; juggler.fis names nine output terms alike)."""
    variables, notes = [], []
    for v in (*system.inputs, *system.outputs):
        seen: dict[str, int] = {}
        terms = []
        for t in v.terms:
            seen[t.name] = seen.get(t.name, 0) + 1
            name = t.name if seen[t.name] == 1 else f"{t.name}_{seen[t.name]}"
            terms.append(dataclasses.replace(t, name=name))
        if any(n > 1 for n in seen.values()):
            notes.append(f"note: FCL refers to terms by name; repeated term names of "
                         f"{excerpt(v.name)} written with _2, _3 … suffixes")  # fmt: skip
        variables.append(dataclasses.replace(v, terms=tuple(terms)))
    n = len(system.inputs)
    renamed = dataclasses.replace(system, inputs=tuple(variables[:n]), output=variables[n],
                                  other_outputs=tuple(variables[n + 1 :]))  # fmt: skip
    return renamed, notes
