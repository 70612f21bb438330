"""The sections of a ``.fis`` file made into the parts of a
:class:`~fuzzyservo.controllers.fuzzy.system.FuzzySystem`: variables and their
membership functions (MATLAB's shapes, Sugeno output terms), rules from their MF
numbers, and the section counts checked. Used by :mod:`fuzzyservo.controllers.fuzzy.fis`.
"""

from __future__ import annotations

import math
import re

from fuzzyservo.controllers.fuzzy._fis_reader import _MF_KEY, _NUMBERED, _Line, _Reader, _Section
from fuzzyservo.controllers.fuzzy.shapes import SUGENO_SHAPES
from fuzzyservo.controllers.fuzzy.system import SHAPES, Rule, Term, Variable, from_matlab
from fuzzyservo.errors import excerpt

_SHAPE_LIST = ", ".join(SHAPES)
#: shapes fuzzylite writes into .fis files that MATLAB has no function for
FUZZYLITE_SHAPES = (
    "binarymf", "concavemf", "cosinemf", "discretemf", "function", "rampmf", "rectmf",
    "spikemf", "trianglemf", "trapezoidmf",
)  # fmt: skip
_VARIABLE_KEYS = ("Name", "Range", "NumMFs", "MF<n>")
_MF = re.compile(r"^'(?P<name>[^']*)'\s*:\s*'(?P<shape>[^']*)'\s*,\s*\[(?P<params>[^\[\]]*)\]$")
_NUMBER = r"[-+]?\d+(?:\.\d*)?"
_INDICES = rf"{_NUMBER}(?:[\s,]+{_NUMBER})*"
_RULE = re.compile(
    rf"^(?P<ante>{_INDICES})\s*,\s*(?P<cons>{_INDICES})\s*"
    rf"\(\s*(?P<weight>[^()]*?)\s*\)\s*:\s*(?P<conn>{_NUMBER})$"
)
_RULE_HINT = "write it like '1 2, 3 (1) : 1' (input MF numbers, output MF, (weight) : 1 AND / 2 OR)"


def _with_fix(exc: ValueError, fix: str) -> str:
    """A model's validation message, with ``fix`` appended when it names none."""
    message = str(exc)
    return message if ";" in message else f"{message}; {fix}"


def _count(reader: _Reader, section: _Section, key: str, found: int, what: str) -> None:
    if key in section.entries and reader.integer(section, key) != found:
        reader.fail(
            f"says {reader.integer(section, key)} but the file has {found} {what}; "
            f"set {key}={found} or add the missing {what}",
            f"[{section.name}].{key}",
            section.entries[key].number,
        )


def _variable(
    reader: _Reader, section: _Section, default_name: str, points: int, sugeno: bool
) -> Variable:
    where = f"[{section.name}]"
    for key, entry in section.entries.items():
        if key not in ("Name", "Range", "NumMFs") and not _MF_KEY.match(key):
            reader.fail(
                f"unknown key {excerpt(key)} (known: {', '.join(_VARIABLE_KEYS)}); remove it",
                f"{where}.{key}",
                entry.number,
            )
    name = reader.text(section, "Name") if "Name" in section.entries else default_name
    if "Range" not in section.entries:
        reader.fail("missing Range; add Range=[low high]", where, section.number)
    example = "write it like Range=[-2 2]"
    lo_hi = reader.vector(section, "Range", example)
    line = section.entries["Range"].number
    if len(lo_hi) != 2:
        reader.fail(
            f"needs two numbers [low high], got {excerpt(list(lo_hi))}; {example}",
            f"{where}.Range",
            line,
        )
    if not (lo_hi[0] < lo_hi[1] or (sugeno and section.name.startswith("Output"))):
        reader.fail(
            f"low must be below high, got [{lo_hi[0]:g} {lo_hi[1]:g}]; swap or widen the range",
            f"{where}.Range",
            line,
        )
    numbered = sorted((int(m["n"]), key) for key in section.entries if (m := _MF_KEY.match(key)))
    if not numbered and section.name.startswith("Output"):
        reader.fail(
            "has no membership functions; add MF1='name':'trimf',[a b c] lines",
            where,
            section.number,
        )
    _count(reader, section, "NumMFs", len(numbered), "membership functions")
    sugeno_output = sugeno and section.name.startswith("Output")
    terms = [_term(reader, section, key, sugeno_output) for _, key in numbered]
    try:
        return Variable(name, lo_hi[0], lo_hi[1], tuple(terms), points)
    except ValueError as exc:
        reader.fail(_with_fix(exc, "fix the section"), where, section.number)


def _term(reader: _Reader, section: _Section, key: str, sugeno_output: bool) -> Term:
    entry = section.entries[key]
    where = f"[{section.name}].{key}"
    m = _MF.match(entry.value)
    if not m:
        reader.fail(
            f"cannot read membership function {excerpt(entry.value)}; write it like "
            f"{key}='NB':'trimf',[-1 -0.5 0]",
            where,
            entry.number,
        )
    shape = m["shape"].strip()
    allowed = SUGENO_SHAPES if sugeno_output else tuple(SHAPES)
    if shape not in allowed:
        if shape in FUZZYLITE_SHAPES:
            problem = f"{excerpt(shape)} is a fuzzylite shape that MATLAB has no function for"
        elif sugeno_output and shape in SHAPES:
            problem = f"a Sugeno output term is 'constant' or 'linear', not {excerpt(shape)}"
        elif shape in SUGENO_SHAPES:
            problem = (
                f"{excerpt(shape)} is a Sugeno output term, here in a Mamdani system or an input"
            )
        else:
            problem = f"unsupported membership function {excerpt(shape)}"
        reader.fail(
            f"{problem} (supported: {', '.join(allowed)}); replace it with one of them",
            where,
            entry.number,
        )
    params = reader.numbers(
        m["params"], where, entry.number, f"write it like {key}='NB':'trimf',[-1 -0.5 0]"
    )
    need = SHAPES.get(shape, 1)
    if len(params) < need or (shape == "constant" and len(params) != 1):
        reader.fail(
            f"{shape} takes {need} parameters, got {len(params)} {excerpt(list(params))}; give {need}",
            where,
            entry.number,
        )
    try:
        return Term(m["name"], shape, params)
    except ValueError as exc:
        reader.fail(_with_fix(exc, "fix the parameters"), where, entry.number)


def _indices(reader: _Reader, text: str, line: _Line) -> list[int]:
    values = []
    for v in re.split(r"[\s,]+", text.strip()):
        x = float(v)
        if x != int(x):
            reader.fail(
                f"rule {excerpt(line.value)}: MF number {v} is not a whole number; {_RULE_HINT}",
                "[Rules]",
                line.number,
            )
        values.append(int(x))
    return values


def _rule(
    reader: _Reader, line: _Line, inputs: list[Variable], outputs: list[Variable], sugeno: bool
) -> Rule:
    where = "[Rules]"
    m = _RULE.match(line.value)
    if not m:
        reader.fail(f"cannot read rule {excerpt(line.value)}; {_RULE_HINT}", where, line.number)
    ante = _indices(reader, m["ante"], line)
    cons = _indices(reader, m["cons"], line)
    if len(ante) != len(inputs):
        reader.fail(
            f"rule {excerpt(line.value)} gives {len(ante)} input MF number(s) for {len(inputs)} "
            f"input(s); {_RULE_HINT}",
            where,
            line.number,
        )
    if len(cons) != len(outputs):
        reader.fail(
            f"rule {excerpt(line.value)} gives {len(cons)} output MF number(s) for {len(outputs)} "
            f"output(s); give one output MF number per output (0: none)",
            where,
            line.number,
        )
    for kind, variables, values in (("input", inputs, ante), ("output", outputs, cons)):
        for var, v in zip(variables, values, strict=True):
            if abs(v) > len(var.terms):
                reader.fail(
                    f"rule {excerpt(line.value)} refers to MF{abs(v)} of {kind} {excerpt(var.name)}, which "
                    f"has {len(var.terms)}; use 1..{len(var.terms)} (0 for none)",
                    where,
                    line.number,
                )
    if all(v == 0 for v in ante):
        reader.fail(
            f"rule {excerpt(line.value)} has no condition on any input; give an input MF number or "
            "delete the rule",
            where,
            line.number,
        )
    if sugeno and any(c < 0 for c in cons):
        reader.fail(
            f"rule {excerpt(line.value)}: a negated output MF has no meaning in a Sugeno system; "
            "use an output MF number",
            where,
            line.number,
        )
    weight_text = m["weight"]
    try:
        weight = float(weight_text)
    except ValueError:
        weight = math.nan
    if not 0.0 <= weight <= 1.0:
        reader.fail(
            f"rule {excerpt(line.value)}: weight must be a number in [0, 1], got {excerpt(weight_text)}; "
            "write it like (1) or (0.5)",
            where,
            line.number,
        )
    conn = float(m["conn"])
    if conn not in (1, 2):
        reader.fail(
            f"rule {excerpt(line.value)}: connective must be 1 (AND) or 2 (OR), got {m['conn']}; fix it",
            where,
            line.number,
        )
    decoded = [from_matlab(c) for c in cons]
    return Rule(
        tuple(from_matlab(v) for v in ante),
        decoded[0],
        weight,
        "and" if conn == 1 else "or",
        tuple(decoded[1:]),
    )


def _numbered(reader: _Reader, sections: dict[str, _Section], kind: str) -> list[str]:
    found = sorted(
        (int(m["n"]), name)
        for name in sections
        if (m := _NUMBERED.match(name)) and m["kind"] == kind
    )
    for expected, (n, name) in enumerate(found, start=1):
        if n != expected:
            reader.fail(
                f"[{name}] without [{kind}{expected}]; number the sections {kind}1, {kind}2, … "
                "without gaps",
                line=sections[name].number,
            )
    return [name for _, name in found]
