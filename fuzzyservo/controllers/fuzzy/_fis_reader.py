"""The ``.fis`` text read line by line (the format: :mod:`fuzzyservo.controllers.fuzzy.fis`).

Sections and their ``Key=value`` entries, rule lines, the ``% fuzzyservo:`` settings
lines, and the values: quoted text, whole numbers, numbers and arithmetic expressions
of ``pi``, number vectors, method names. Every problem is located by file, section and
line. Used by :mod:`fuzzyservo.controllers.fuzzy.fis` and :mod:`fuzzyservo.controllers.fuzzy._fis_system`.
"""

from __future__ import annotations

import math
import re
import warnings
from dataclasses import dataclass, field
from typing import NoReturn

from fuzzyservo.controllers.fuzzy.system import (
    AGGREGATIONS,
    AND_METHODS,
    IMPLICATIONS,
    MAMDANI_DEFUZZIFICATIONS,
    OR_METHODS,
    SUGENO_DEFUZZIFICATIONS,
)
from fuzzyservo.errors import ConfigError, FileWarning, excerpt
from fuzzyservo.limits import MAX_POINTS, points_problem

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
_SECTION = re.compile(r"^\[\s*(?P<name>[^\]]*?)\s*\]$")
_NUMBERED = re.compile(r"^(?P<kind>Input|Output)(?P<n>\d+)$")
_MF_KEY = re.compile(r"^MF(?P<n>\d+)$")

#: characters of an arithmetic expression in a number's place (``-pi/4``)
_MAX_EXPRESSION = 100


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
