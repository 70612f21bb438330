"""MATLAB ``.fis`` files (Fuzzy Logic Toolbox text format) ⇄ :class:`FuzzySystem`.

The format is the one ``readfis``/``writefis`` use (Fuzzy Logic Toolbox User's Guide,
"The FIS Structure — Saving FIS Files on Disk"; unchanged in R2018b+ files apart from
a ``Version=2.0`` line)::

    [System]
    Name='tipper'
    Type='mamdani'
    Version=2.0
    NumInputs=2
    NumOutputs=1
    NumRules=3
    AndMethod='min'
    OrMethod='max'
    ImpMethod='min'
    AggMethod='max'
    DefuzzMethod='centroid'

    [Input1]
    Name='service'
    Range=[0 10]
    NumMFs=3
    MF1='poor':'gaussmf',[1.5 0]
    ...

    [Output1]
    ...

    [Rules]
    1 1, 1 (1) : 2

A rule line is: one MF number per input (1-based, ``0`` no condition, ``-k`` NOT MF
k), a comma, one MF number per output (``0`` none, ``-k`` NOT MF k), the weight in
parentheses, a colon and the connective (``1`` AND, ``2`` OR). Numbers may be written
with decimals (``1.000 1.000, 1.000 (1.000) : 2``, as fuzzylite writes them).

Supported: everything the Fuzzy Logic Toolbox writes for type-1 systems — Mamdani and
Sugeno (``constant`` and ``linear`` output terms, ``wtaver``/``wtsum``), any number of
inputs and outputs, every built-in membership function (:mod:`.shapes`; extra
parameters are kept and ignored, as MATLAB does), rule weights, NOT, negated
consequents, empty method names (MATLAB's defaults). Anything else (type-2 systems,
custom method functions, fuzzylite-only shapes) is a :class:`ConfigError` naming the
file, the line and section, the problem and the fix.

The format has no evaluation settings; fuzzyservo writes its own in a comment line
MATLAB skips, ``% fuzzyservo: semantics=skfuzzy sample_points=101 points=201``
(``points``: universe samples of the ``skfuzzy`` semantics, per variable when they
differ), so a round trip is lossless. Files without it get the defaults.
"""

from __future__ import annotations

import math
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import NoReturn

from fuzzyservo.atomic import write_text
from fuzzyservo.controllers.fuzzy.controller import FuzzyController
from fuzzyservo.controllers.fuzzy.shapes import SUGENO_SHAPES
from fuzzyservo.controllers.fuzzy.system import (
    AGGREGATIONS,
    AND_METHODS,
    IMPLICATIONS,
    MAMDANI_DEFUZZIFICATIONS,
    MATLAB_SAMPLE_POINTS,
    OR_METHODS,
    SEMANTICS,
    SHAPES,
    SUGENO_DEFUZZIFICATIONS,
    FuzzySystem,
    Rule,
    Term,
    Variable,
    from_matlab,
    to_matlab,
)
from fuzzyservo.errors import ConfigError, FileWarning, excerpt
from fuzzyservo.limits import MAX_POINTS, MAX_SAMPLE_POINTS, points_problem

__all__ = [
    "controller_from_fis", "controller_from_law", "fis_text", "law_text", "parse_fis",
    "parse_fis_controller", "read_fis", "read_fis_law", "write_fis",
]  # fmt: skip

#: the ``Version`` written by :func:`fis_text` (MATLAB R2018b and later)
VERSION = "2.0"
_SHAPE_LIST = ", ".join(SHAPES)
#: shapes fuzzylite writes into .fis files that MATLAB has no function for
FUZZYLITE_SHAPES = (
    "binarymf", "concavemf", "cosinemf", "discretemf", "function", "rampmf", "rectmf",
    "spikemf", "trianglemf", "trapezoidmf",
)  # fmt: skip
_METHODS = {
    "AndMethod": ("and_method", AND_METHODS),
    "OrMethod": ("or_method", OR_METHODS),
    "ImpMethod": ("implication", IMPLICATIONS),
    "AggMethod": ("aggregation", AGGREGATIONS),
    "DefuzzMethod": ("defuzzification", MAMDANI_DEFUZZIFICATIONS),
}
_TAG = "% fuzzyservo:"
#: the control law of a controller, written in its own ``% fuzzyservo:`` line
LAW_KEYS = ("form", "input_gain", "rate_gain", "output_gain", "u_min", "u_max")
_SYSTEM_KEYS = ("Name", "Type", "Version", "NumInputs", "NumOutputs", "NumRules", *_METHODS)
_VARIABLE_KEYS = ("Name", "Range", "NumMFs", "MF<n>")
_SECTION = re.compile(r"^\[\s*(?P<name>[^\]]*?)\s*\]$")
_NUMBERED = re.compile(r"^(?P<kind>Input|Output)(?P<n>\d+)$")
_MF_KEY = re.compile(r"^MF(?P<n>\d+)$")
_MF = re.compile(r"^'(?P<name>[^']*)'\s*:\s*'(?P<shape>[^']*)'\s*,\s*\[(?P<params>[^\[\]]*)\]$")
_NUMBER = r"[-+]?\d+(?:\.\d*)?"
_INDICES = rf"{_NUMBER}(?:[\s,]+{_NUMBER})*"
_RULE = re.compile(
    rf"^(?P<ante>{_INDICES})\s*,\s*(?P<cons>{_INDICES})\s*"
    rf"\(\s*(?P<weight>[^()]*?)\s*\)\s*:\s*(?P<conn>{_NUMBER})$"
)
_RULE_HINT = "write it like '1 2, 3 (1) : 1' (input MF numbers, output MF, (weight) : 1 AND / 2 OR)"


#: characters of an arithmetic expression in a number's place (``-pi/4``)
_MAX_EXPRESSION = 100


# --------------------------------------------------------------------------- parsing
def _number(text: str) -> float:
    """A number, or an arithmetic expression of numbers and ``pi`` (MATLAB's readfis
    evaluates ``Range=[-pi/4 pi/4]``, as its sltbu.fis demo has)."""
    try:
        return float(text)
    except ValueError:
        pass
    if len(text) > _MAX_EXPRESSION:  # the parser would recurse (or run out of memory) on it
        raise ValueError(text)
    import ast
    import operator

    ops = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
           ast.Div: operator.truediv, ast.USub: operator.neg, ast.UAdd: operator.pos}  # fmt: skip

    def value(node: ast.AST) -> float:
        if isinstance(node, ast.Constant) and isinstance(node.value, int | float):
            return float(node.value)
        if isinstance(node, ast.Name) and node.id == "pi":
            return math.pi
        if isinstance(node, ast.BinOp) and type(node.op) in ops:
            return ops[type(node.op)](value(node.left), value(node.right))
        if isinstance(node, ast.UnaryOp) and type(node.op) in ops:
            return ops[type(node.op)](value(node.operand))
        raise ValueError(text)

    try:
        return value(ast.parse(text, mode="eval").body)
    except (SyntaxError, ZeroDivisionError, RecursionError):
        raise ValueError(text) from None


@dataclass
class _Line:
    value: str
    number: int


@dataclass
class _Section:
    name: str
    number: int
    entries: dict[str, _Line] = field(default_factory=dict)
    lines: list[_Line] = field(default_factory=list)  # [Rules]
    mfs: int = 0  # MF lines read so far (MATLAB numbers them by their place)


class _Reader:
    """Locates every problem: ``file: [Section].Key (line n): problem; fix``."""

    def __init__(self, file: str):
        self.file = file
        self.settings: dict[str, tuple[str, int]] = {}  # key -> (value, line) from _TAG

    def fail(self, message: str, where: str | None = None, line: int | None = None) -> NoReturn:
        if where and line:
            key = f"{where} (line {line})"
        else:
            key = where or (f"line {line}" if line else None)
        raise ConfigError(message, file=self.file, key=key)

    def sections(self, text: str) -> dict[str, _Section]:
        sections: dict[str, _Section] = {}
        current: _Section | None = None
        for number, raw in enumerate(text.splitlines(), start=1):
            line = raw.strip()
            if line.startswith(_TAG):
                self._settings(line[len(_TAG) :], current, number)
                continue
            if not line or line[0] in "%#":
                continue
            head = _SECTION.match(line)
            if head:
                name = head["name"]
                self._check_section_name(name, number)
                if name in sections:
                    self.fail(
                        f"section [{name}] appears twice (first at line "
                        f"{sections[name].number}); merge or delete one",
                        line=number,
                    )
                current = sections[name] = _Section(name, number)
                continue
            if current is None:
                self.fail(
                    f"text before the first section: {excerpt(line)}; start the file with [System]",
                    line=number,
                )
            if current.name == "Rules":
                current.lines.append(_Line(line, number))
                continue
            key, eq, value = line.partition("=")
            key, value = key.strip(), value.strip()
            if not eq or not key:
                self.fail(
                    f"cannot read {excerpt(line)}; write Key=value (e.g. Range=[-1 1])",
                    f"[{current.name}]",
                    number,
                )
            mf = _MF_KEY.match(key) if current.name != "System" else None
            if mf is not None:
                key = self._mf_in_order(current, key, number)
            if key in current.entries:
                self.fail(
                    f"{key} is given twice (first at line {current.entries[key].number}); "
                    "delete one",
                    f"[{current.name}].{key}",
                    number,
                )
            current.entries[key] = _Line(value, number)
        return sections

    def _mf_in_order(self, section: _Section, key: str, number: int) -> str:
        """MATLAB reads a variable's MF lines in order: the k-th is MF k whatever its key
        says. A key that names another number (``MF2`` given twice, a gap) is read as
        MATLAB reads it, with a warning naming the line."""
        section.mfs += 1
        k = section.mfs
        if key != f"MF{k}":
            warnings.warn(
                f"{self.file}: [{section.name}].{key} (line {number}): read as MF{k}, the "
                f"{_ordinal(k)} membership function line, as MATLAB reads them in order; "
                f"renumber it MF{k}",
                FileWarning,
                stacklevel=2,
            )
        return f"MF{k}"

    def _settings(self, text: str, current: _Section | None, number: int) -> None:
        """``key=value`` pairs of a ``% fuzzyservo:`` line; ``points`` per section."""
        prefix = f"{current.name}." if current is not None and current.name != "System" else ""
        for item in text.split():
            key, eq, value = item.partition("=")
            if not eq or key not in ("semantics", "sample_points", "points", *LAW_KEYS):
                self.fail(
                    f"cannot read {excerpt(item)} in a '{_TAG}' line; write semantics=skfuzzy|matlab, "
                    f"sample_points=N, points=N or the control law ({', '.join(LAW_KEYS)})",
                    line=number,
                )
            self.settings[prefix + key] = (value, number)

    def setting_int(self, key: str, default: int, most: int = MAX_POINTS) -> int:
        if key not in self.settings:
            return default
        value, line = self.settings[key]
        problem = points_problem(value, default, most)
        if problem:
            self.fail(f"{key} {problem}", line=line)
        return int(value)

    def _check_section_name(self, name: str, number: int) -> None:
        if name in ("System", "Rules"):
            return
        m = _NUMBERED.match(name)
        if not m:
            self.fail(
                f"unknown section [{name}]; a .fis file has [System], [Input1] … [InputN], "
                "[Output1] … [OutputM] and [Rules]",
                line=number,
            )
        n = int(m["n"])
        if n < 1:
            self.fail(f"sections are numbered from 1, got [{name}]; renumber it", line=number)

    # -- values -----------------------------------------------------------------
    def text(self, section: _Section, key: str) -> str:
        entry = section.entries[key]
        v = entry.value
        if len(v) < 2 or v[0] != "'" or v[-1] != "'" or "'" in v[1:-1]:
            self.fail(
                f"expected text in single quotes, got {excerpt(v)}; write it like {key}='name'",
                f"[{section.name}].{key}",
                entry.number,
            )
        return v[1:-1]

    def integer(self, section: _Section, key: str) -> int:
        entry = section.entries[key]
        try:
            value = float(entry.value)
        except ValueError:
            value = math.nan
        if not (math.isfinite(value) and value == int(value) and value >= 0):
            self.fail(
                f"expected a whole number, got {excerpt(entry.value)}; write it like {key}=2",
                f"[{section.name}].{key}",
                entry.number,
            )
        return int(value)

    def numbers(self, text: str, where: str, line: int, example: str) -> tuple[float, ...]:
        parts = [p for p in re.split(r"[\s,]+", text.strip()) if p]
        values = []
        for p in parts:
            try:
                x = _number(p)
            except ValueError:
                self.fail(f"{excerpt(p)} is not a number; {example}", where, line)
            if not math.isfinite(x):
                self.fail(f"numbers must be finite, got {excerpt(p)}; {example}", where, line)
            values.append(x)
        return tuple(values)

    def vector(self, section: _Section, key: str, example: str) -> tuple[float, ...]:
        entry = section.entries[key]
        where = f"[{section.name}].{key}"
        v = entry.value
        if not (v.startswith("[") and v.endswith("]")):
            self.fail(
                f"expected numbers in brackets, got {excerpt(v)}; {example}", where, entry.number
            )
        return self.numbers(v[1:-1], where, entry.number, example)

    def method(self, system: _Section, key: str, sugeno: bool = False) -> str:
        _, allowed = _METHODS[key]
        if key == "DefuzzMethod" and sugeno:
            allowed = SUGENO_DEFUZZIFICATIONS
        if key not in system.entries:
            return allowed[0]  # MATLAB's defaults (mamfis): min, max, min, max, centroid
        value = self.text(system, key).strip()
        if not value:  # fuzzylite writes '' for an operator it does not need
            return allowed[0]
        if value.lower() not in allowed:
            self.fail(
                f"unsupported {key} {excerpt(value)} (supported: {', '.join(allowed)}); "
                f"choose one of them",
                f"[System].{key}",
                system.entries[key].number,
            )
        return value.lower()


def _ordinal(k: int) -> str:
    return f"{k}{'th' if 10 <= k % 100 <= 20 else {1: 'st', 2: 'nd', 3: 'rd'}.get(k % 10, 'th')}"


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


def parse_fis(text: str, file: str = "<fis text>", points: int = 201) -> FuzzySystem:
    """The :class:`FuzzySystem` in ``.fis`` text (module docstring); errors name ``file``.

    Universes get ``points`` evenly spaced samples unless the file's ``% fuzzyservo:``
    line says otherwise.
    """
    return _parse(text, file, points)[0]


def _parse(text: str, file: str, points: int) -> tuple[FuzzySystem, dict[str, str]]:
    """The system and the control law's settings (:data:`LAW_KEYS`) the file gives."""
    reader = _Reader(file)
    sections = reader.sections(text)
    if "System" not in sections:
        reader.fail(
            "no [System] section; is this a MATLAB .fis file? Add [System] with Type='mamdani'",
            "[System]",
        )
    system = sections["System"]
    for key, entry in system.entries.items():
        if key not in _SYSTEM_KEYS:
            reader.fail(
                f"unknown key {excerpt(key)} (known: {', '.join(_SYSTEM_KEYS)}); remove it",
                f"[System].{key}",
                entry.number,
            )
    if "Type" not in system.entries:
        reader.fail("missing Type; add Type='mamdani'", "[System]", system.number)
    fis_type = reader.text(system, "Type").strip().lower()
    if fis_type not in ("mamdani", "sugeno"):
        reader.fail(
            f"unsupported FIS type {excerpt(fis_type)} (supported: mamdani, sugeno — type-1 systems; "
            f"{'type-2 systems' if 'type2' in fis_type else 'this type'} cannot be read); "
            "convert it to a type-1 Mamdani or Sugeno system",
            "[System].Type",
            system.entries["Type"].number,
        )
    sugeno = fis_type == "sugeno"
    if "Version" in system.entries:
        reader.numbers(
            system.entries["Version"].value,
            "[System].Version",
            system.entries["Version"].number,
            "write it like Version=2.0",
        )
    input_names = _numbered(reader, sections, "Input")
    output_names = _numbered(reader, sections, "Output")
    if not input_names:
        reader.fail("no [Input1] section; add the input variable", "[System]", system.number)
    if not output_names:
        reader.fail("no [Output1] section; add the output variable", "[System]", system.number)
    if "Rules" not in sections:
        reader.fail("no [Rules] section; add the rule base", "[System]", system.number)
    _count(reader, system, "NumInputs", len(input_names), "input sections")
    _count(reader, system, "NumOutputs", len(output_names), "output sections")
    methods = {attr: reader.method(system, key, sugeno) for key, (attr, _) in _METHODS.items()}
    points = reader.setting_int("points", points)
    in_defaults = ("e", "de") if len(input_names) <= 2 else ()
    inputs = [
        _variable(
            reader,
            sections[n],
            in_defaults[k] if k < len(in_defaults) else f"input{k + 1}",
            reader.setting_int(f"{n}.points", points),
            False,
        )
        for k, n in enumerate(input_names)
    ]
    outputs = [
        _variable(
            reader,
            sections[n],
            "u" if len(output_names) == 1 else f"output{k + 1}",
            reader.setting_int(f"{n}.points", points),
            sugeno,
        )
        for k, n in enumerate(output_names)
    ]
    rule_lines = sections["Rules"].lines
    if not rule_lines:
        reader.fail("the rule base is empty; add rule lines", "[Rules]", sections["Rules"].number)
    _count(reader, system, "NumRules", len(rule_lines), "rule lines")
    rules = tuple(_rule(reader, line, inputs, outputs, sugeno) for line in rule_lines)
    name = reader.text(system, "Name") if "Name" in system.entries else Path(file).stem
    semantics = "skfuzzy"
    if "semantics" in reader.settings:
        semantics, line = reader.settings["semantics"]
        if semantics not in SEMANTICS:
            reader.fail(
                f"semantics must be one of {list(SEMANTICS)}, got {excerpt(semantics)}", line=line
            )
    law = {k: v for k, (v, _) in reader.settings.items() if k in LAW_KEYS}
    sample_points = reader.setting_int("sample_points", MATLAB_SAMPLE_POINTS, MAX_SAMPLE_POINTS)
    try:
        return FuzzySystem(
            name=name,
            inputs=tuple(inputs),
            output=outputs[0],
            other_outputs=tuple(outputs[1:]),
            rules=rules,
            type=fis_type,
            semantics=semantics,
            sample_points=sample_points,
            **methods,
        ), law
    except ValueError as exc:
        reader.fail(_with_fix(exc, "fix the file"), "[System]", system.number)


def read_fis(path: str | Path, points: int = 201) -> FuzzySystem:
    """Read a MATLAB ``.fis`` file (UTF-8, else latin-1) into a :class:`FuzzySystem`.

    Raises :class:`ConfigError` naming the file, the section and line, and the fix.
    """
    return _parse(_read_text(path), str(path), points)[0]


def read_fis_law(path: str | Path) -> tuple[FuzzySystem, dict[str, str]]:
    """The system of a ``.fis`` file and the control law (:data:`LAW_KEYS`, as text) its
    ``% fuzzyservo:`` line gives (empty when it gives none)."""
    return _parse(_read_text(path), str(path), 201)


def _read_text(path: str | Path) -> str:
    p = Path(path)
    if not p.is_file():
        raise ConfigError(
            f"file not found (looked in {p.resolve().parent}); check the path", file=str(path)
        )
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise ConfigError(
            f"cannot read the file ({exc.strerror or exc}); check its permissions", file=str(path)
        ) from None
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        text = data.decode("latin-1")  # older MATLAB wrote the platform encoding (often cp1252)
    return text


def controller_from_fis(path: str | Path) -> FuzzyController:
    """A controller from a ``.fis`` file: the control law its ``% fuzzyservo:`` line gives
    (:func:`law_text`, what ``fuzzyservo export`` writes), else one input → form ``p``,
    two → ``pd``, all gains 1 and no output limits (the simulator applies the rig
    actuator's command range). Named after the file stem.
    """
    return parse_fis_controller(_read_text(path), str(path))


def parse_fis_controller(text: str, file: str) -> FuzzyController:
    """:func:`controller_from_fis` of ``.fis`` text (an upload named ``file``)."""
    system, law = _parse(text, file, 201)
    return controller_from_law(system, law, Path(file), "[Rules]")


def law_text(controller: FuzzyController) -> str:
    """The control law around the inference system (form, gains, output limits) as the
    ``key=value`` pairs a ``% fuzzyservo:`` line (``.fis``) or ``(* fuzzyservo: *)``
    comment (FCL) carries, numbers exact (``repr``)."""
    values = [number_text(getattr(controller, k)) for k in LAW_KEYS[1:]]
    pairs = [
        f"form={controller.form}",
        *(f"{k}={v}" for k, v in zip(LAW_KEYS[1:], values, strict=True)),
    ]
    return " ".join(pairs)


def controller_from_law(
    system: FuzzySystem, law: dict[str, str], path: Path, key: str
) -> FuzzyController:
    """The controller of ``system`` with the control law ``law`` (:data:`LAW_KEYS`, as
    text; missing keys: the form from the number of inputs, gains 1, no limits)."""
    settings: dict[str, object] = {}
    for k, text in law.items():
        if k == "form":
            settings[k] = text
            continue
        try:
            settings[k] = float(text)
        except ValueError:
            raise ConfigError(
                f"control law {k}={excerpt(text)} is not a number; write it like {k}=1.5",
                file=str(path), key="fuzzyservo control law",
            ) from None  # fmt: skip
    settings.setdefault("form", "p" if len(system.inputs) == 1 else "pd")
    kind = "MATLAB FIS" if path.suffix.lower() == ".fis" else "FCL function block"
    try:
        return FuzzyController(
            system=system,
            name=path.stem,
            description=f"{kind} {system.name!r} read from {path.name}",
            **settings,  # type: ignore[arg-type]
        )
    except ValueError as exc:
        raise ConfigError(_with_fix(exc, "fix the rules"), file=str(path), key=key) from None


# --------------------------------------------------------------------------- writing
def number_text(x: float) -> str:
    """Shortest text that reads back as the same float (``repr``), ``1.0`` written ``1``."""
    text = repr(float(x))
    return text[:-2] if text.endswith(".0") else text


def _quoted(name: str, what: str) -> str:
    if "'" in name or "\n" in name or "\r" in name:
        raise ValueError(
            f"{what} {excerpt(name)} cannot be written to a .fis file (names are quoted with ' and "
            "on one line); rename it"
        )
    return f"'{name}'"


def _variable_text(section: str, var: Variable, points: int) -> list[str]:
    lines = [f"[{section}]"]
    if var.points != points:
        lines.append(f"{_TAG} points={var.points}")
    lines += [
        f"Name={_quoted(var.name, 'variable name')}",
        f"Range=[{number_text(var.low)} {number_text(var.high)}]",
        f"NumMFs={len(var.terms)}",
    ]
    for k, t in enumerate(var.terms, start=1):
        params = " ".join(number_text(p) for p in t.params)
        lines.append(f"MF{k}={_quoted(t.name, 'term name')}:'{t.shape}',[{params}]")
    return [*lines, ""]


def fis_text(system: FuzzySystem, law: str = "") -> str:
    """``system`` as MATLAB ``.fis`` text (R2018b+ layout, ``Version=2.0``).

    Numbers are written with ``repr`` precision and the evaluation settings in a
    ``% fuzzyservo:`` comment, so :func:`parse_fis` gives back an equal system; ``law``
    (:func:`law_text`) in a second one, so a controller's file runs as the controller.
    """
    variables = [*system.inputs, *system.outputs]
    points = max({v.points for v in variables}, key=[v.points for v in variables].count)
    lines = [
        "[System]",
        f"Name={_quoted(system.name, 'system name')}",
        f"Type='{system.type}'",
        f"Version={VERSION}",
        f"NumInputs={len(system.inputs)}",
        f"NumOutputs={len(system.outputs)}",
        f"NumRules={len(system.rules)}",
    ]
    lines += [f"{key}='{getattr(system, attr)}'" for key, (attr, _) in _METHODS.items()]
    lines.append(
        f"{_TAG} semantics={system.semantics} sample_points={system.sample_points} points={points}"
    )
    if law:
        lines.append(f"{_TAG} {law}")
    lines.append("")
    for k, var in enumerate(system.inputs, start=1):
        lines += _variable_text(f"Input{k}", var, points)
    for k, var in enumerate(system.outputs, start=1):
        lines += _variable_text(f"Output{k}", var, points)
    lines.append("[Rules]")
    for rule in system.rules:
        ante = " ".join(str(to_matlab(i)) for i in rule.antecedent)
        cons = " ".join(str(to_matlab(i)) for i in rule.consequents)
        conn = 1 if rule.connective == "and" else 2
        lines.append(f"{ante}, {cons} ({number_text(rule.weight)}) : {conn}")
    return "\n".join(lines) + "\n"


def write_fis(system: FuzzySystem, path: str | Path, law: str = "") -> Path:
    """Write ``system`` (and the control law ``law``, :func:`fis_text`) as a MATLAB
    ``.fis`` file (UTF-8); returns the path."""
    return write_text(path, fis_text(system, law))
