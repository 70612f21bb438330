"""Reading YAML mappings strictly: every key known, every value typed, every error located.

:class:`Node` wraps a parsed mapping with the file and the dotted key path so that
each problem becomes one :class:`~fuzzyservo.errors.ConfigError` line naming file,
key, value and fix. Every YAML file the package reads goes through :func:`parse_yaml`,
whose loader refuses a key given twice, nesting deeper than
:data:`~fuzzyservo.limits.MAX_YAML_DEPTH` and aliases that expand the document past
:data:`~fuzzyservo.limits.YAML_ALIAS_FACTOR` times its size (a "billion laughs"), each
before anything is built; values are echoed in messages as short excerpts.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Iterable
from pathlib import Path
from typing import Any, NoReturn

import yaml

from fuzzyservo.errors import ConfigError, excerpt
from fuzzyservo.limits import MAX_YAML_DEPTH, YAML_ALIAS_FACTOR, YAML_ALIAS_FLOOR
from fuzzyservo.units import Unit, parse_unit, to_si

# ``interval`` ([lo, hi], 95 %, in the value's unit) and ``at_bound`` are written by
# ``calibrate`` for robust tuning to sample from; a rig reads them as documentation.
QUANTITY_KEYS = ("value", "unit", "source", "note", "interval", "at_bound")


def read_yaml(path: str | Path) -> dict[str, Any]:
    """Parse a YAML file whose top level is a mapping."""
    p = Path(path)
    if not p.is_file():
        raise ConfigError(
            f"file not found (looked in {p.resolve().parent}); check the path", file=str(path)
        )
    try:
        text = p.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(
            f"not UTF-8 text (byte {exc.object[exc.start]:#04x} at offset {exc.start}); "
            "save the file as UTF-8 YAML",
            file=str(path),
        ) from None
    except OSError as exc:
        raise ConfigError(
            f"cannot read the file ({exc.strerror or exc}); check its permissions", file=str(path)
        ) from None
    return parse_yaml(text, str(path))


def parse_yaml(text: str, file: str) -> dict[str, Any]:
    """Parse YAML text whose top level is a mapping; ``file`` names it in messages."""
    try:
        data = yaml.load(text, Loader=_StrictLoader)  # a SafeLoader subclass
    except _DuplicateKey as exc:
        raise ConfigError(str(exc), file=file, key=exc.key) from None
    except _TooLarge as exc:
        where = f"line {exc.mark.line + 1}, column {exc.mark.column + 1}: "
        raise ConfigError(where + exc.message, file=file) from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise ConfigError(f"{where}not valid YAML ({problem}); fix the syntax", file=file) from None
    except RecursionError:  # a chain of merge keys (<<: *a) the depth limit does not see
        raise ConfigError(
            "nested too deeply to read (a long chain of '<<: *name' merges?); flatten it",
            file=file,
        ) from None
    if not isinstance(data, dict):
        raise ConfigError(
            f"the top level must be a mapping (key: value lines), got {_describe(data)}; "
            "start the file with 'name: ...' and the other top-level keys",
            file=file,
        )
    return data


class _DuplicateKey(yaml.YAMLError):
    def __init__(self, key: str, first: int, again: int):
        self.key = key
        super().__init__(
            f"given twice (lines {first} and {again}), and YAML would keep only the last; "
            "delete one of them"
        )


class _TooLarge(yaml.YAMLError):
    """A document past a stated limit (nesting, alias expansion), found at ``mark``."""

    def __init__(self, message: str, mark: yaml.Mark):
        self.message = message
        self.mark = mark
        super().__init__(message)


class _StrictLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` that refuses a key given twice in one mapping (PyYAML keeps the
    last), nesting deeper than ``MAX_YAML_DEPTH`` and aliases that expand the document
    past ``YAML_ALIAS_FACTOR`` times the nodes written in it (at least
    ``YAML_ALIAS_FLOOR``), all while composing, before any value is built; a scalar
    Python cannot build (a date with month 13, a 5,000-digit integer) is a YAML error at
    its line."""

    # -- composing: sizes counted as the node graph is built --------------------------
    def compose_document(self) -> yaml.Node:
        self._depth = 0  # collections open around the node being composed
        self._written = 0  # nodes written in the text
        self._expanded = 0  # nodes with each alias counted as the node it names
        self._sizes: dict[yaml.Node, int] = {}  # a finished node -> its expanded size
        self._aliases: list[tuple[int, yaml.Mark]] = []  # expanded count after each alias
        node = super().compose_document()
        limit = max(YAML_ALIAS_FLOOR, YAML_ALIAS_FACTOR * self._written)
        if self._expanded > limit:
            mark = next(mark for count, mark in self._aliases if count > limit)
            raise _TooLarge(
                f"the aliases (*name) up to here expand the file past {limit:,} nodes "
                f"({YAML_ALIAS_FACTOR} times the {self._written:,} written in it, at least "
                f"{YAML_ALIAS_FLOOR:,}); write the repeated parts out or alias fewer of them",
                mark,
            )
        self._sizes, self._aliases = {}, []
        return node

    def compose_node(self, parent: yaml.Node | None, index: Any) -> yaml.Node:
        event = self.peek_event()
        if isinstance(event, yaml.AliasEvent):
            node = super().compose_node(parent, index)  # the node it names (or an error)
            size = self._sizes.get(node)
            if size is None:  # named while still open: a loop
                raise _TooLarge(
                    f"alias {excerpt('*' + event.anchor)} is inside the block it names, "
                    "which would contain itself without end; remove the alias",
                    event.start_mark,
                )
            self._expanded += size
            self._aliases.append((self._expanded, event.start_mark))
            return node
        if isinstance(event, yaml.CollectionStartEvent) and self._depth >= MAX_YAML_DEPTH:
            raise _TooLarge(
                f"nested deeper than {MAX_YAML_DEPTH} levels (a fuzzyservo file needs fewer "
                "than 10); check for unclosed brackets or flatten the structure",
                event.start_mark,
            )
        before = self._expanded
        self._written += 1
        self._expanded += 1
        self._depth += 1
        try:
            node = super().compose_node(parent, index)
        finally:
            self._depth -= 1
        self._sizes[node] = self._expanded - before
        return node

    # -- constructing ---------------------------------------------------------------
    def construct_object(self, node: yaml.Node, deep: bool = False) -> Any:
        try:
            return super().construct_object(node, deep=deep)
        except (ValueError, OverflowError) as exc:
            kind = node.tag.rsplit(":", 1)[-1]
            reason = str(exc).split(";")[0]
            raise yaml.constructor.ConstructorError(
                None,
                None,
                f"cannot read {excerpt(node.value)} (YAML {kind}): {reason}",
                node.start_mark,
            ) from None

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict:
        seen: dict[Any, int] = {}
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":
                continue
            key = self.construct_object(key_node, deep=True)
            line = key_node.start_mark.line + 1
            try:
                if key in seen:
                    raise _DuplicateKey(str(key), seen[key], line)
            except TypeError:  # an unhashable key: SafeLoader reports it itself
                continue
            seen[key] = line
        return super().construct_mapping(node, deep=deep)


def _describe(value: Any) -> str:
    """A value as a person wrote it in YAML: ``null`` for None, type and repr otherwise."""
    if value is None:
        return "nothing (null)"
    return f"{type(value).__name__} {excerpt(value)}"


def _unit_fix(message: str) -> str:
    """Unit messages from :mod:`fuzzyservo.units` with a fix appended where they have none."""
    if ";" in message or "write it like" in message:
        return message
    return f"{message}; write it like 'm^3/s' or 'l/(min*sqrt(bar))'"


class Node:
    """A mapping inside a file, with its location for error messages."""

    def __init__(self, data: Any, file: str, key: str = ""):
        self.file = file
        self.key = key
        if not isinstance(data, dict):
            self.fail(
                f"must be a mapping (key: value lines indented under it), got {_describe(data)}; "
                "write its keys on indented lines below it"
            )
        self.data: dict[str, Any] = data

    # -- locating ---------------------------------------------------------------
    def path(self, key: str) -> str:
        return f"{self.key}.{key}" if self.key else key

    def fail(self, message: str, key: str | None = None) -> NoReturn:
        raise ConfigError(
            message, file=self.file, key=self.path(key) if key else (self.key or None)
        )

    # -- structure --------------------------------------------------------------
    def only(self, allowed: Iterable[str]) -> None:
        """Reject keys that are not in ``allowed``, suggesting the closest known one."""
        allowed = list(allowed)
        for key in self.data:
            if key not in allowed:
                close = difflib.get_close_matches(str(key), allowed, n=1)
                hint = (
                    f"did you mean {close[0]!r}?" if close else f"known keys: {', '.join(allowed)}"
                )
                self.fail(f"unknown key; {hint}", key=str(key))

    def has(self, key: str) -> bool:
        return key in self.data

    def require(self, key: str) -> Any:
        if key not in self.data:
            self.fail(f"missing key {key!r}; add it", key=None)
        return self.data[key]

    def child(self, key: str, default: dict | None = None) -> Node:
        if key not in self.data:
            if default is None:
                self.fail(f"missing section {key!r}; add it")
            return Node(default, self.file, self.path(key))
        return Node(self.data[key], self.file, self.path(key))

    def children(self, key: str) -> dict[str, Node]:
        node = self.child(key, default={})
        return {str(k): Node(v, self.file, node.path(str(k))) for k, v in node.data.items()}

    # -- scalars ----------------------------------------------------------------
    def str(self, key: str, default: str | None = None) -> str:
        if key not in self.data:
            if default is None:
                self.fail(f"missing key {key!r}; add it")
            return default
        value = self.data[key]
        if not isinstance(value, str):
            self.fail(
                f"must be text, got {_describe(value)}; write it as text (in quotes if YAML "
                "would read it as something else)",
                key=key,
            )
        return value

    def flag(self, key: str, default: bool, meaning: str = "") -> bool:
        """``true`` or ``false`` (``meaning``: what the two say, for the message)."""
        value = self.data.get(key, default)
        if not isinstance(value, bool):
            what = f" ({meaning})" if meaning else ""
            self.fail(f"must be true or false{what}, got {excerpt(value)}", key=key)
        return value

    def name(self, key: str, default: str) -> str:
        """Text that becomes part of output file names: no path, see :func:`name_problem`."""
        from fuzzyservo.io.paths import name_problem

        value = self.str(key, default=default)
        problem = name_problem(value)
        if problem:
            self.fail(problem, key=key)
        return value

    def number(self, key: str, default: float | None = None) -> float:
        if key not in self.data:
            if default is None:
                self.fail(f"missing key {key!r}; add it")
            return float(default)
        return self._as_number(self.data[key], key)

    def numbers(self, key: str, default: list[float] | None = None) -> list[float]:
        if key not in self.data:
            if default is None:
                self.fail(f"missing key {key!r}; add it")
            return list(default)
        value = self.data[key]
        if not isinstance(value, list):
            self.fail(
                f"must be a list of numbers, got {_describe(value)}; write it like [1, 2.5]",
                key=key,
            )
        return [self._as_number(v, f"{key}[{i}]") for i, v in enumerate(value)]

    def _as_number(self, value: Any, key: str) -> float:
        fix = "write a plain number such as 70 or 1.4e+9"
        if isinstance(value, str):
            # YAML 1.1 reads 1.4e9 (no sign after e) as text; accept what a person means
            try:
                value = float(value)
            except ValueError:
                self.fail(
                    f"must be a number, got text {excerpt(value)}; {fix} (a unit goes under 'unit:')",
                    key=key,
                )
        if isinstance(value, dict) and "value" in value:
            self.fail(
                f"must be a plain number (this key takes no unit), got {excerpt(value)}; {fix}",
                key=key,
            )
        if isinstance(value, bool) or not isinstance(value, int | float):
            self.fail(f"must be a number, got {_describe(value)}; {fix}", key=key)
        try:
            number = float(value)
        except OverflowError:
            number = math.inf
        if not math.isfinite(number):
            self.fail(f"must be finite, got {excerpt(value)}; {fix}", key=key)
        return number

    def quantity(self, key: str, si_unit: str, default: float | None = None) -> float:
        """A physical value: ``{value: 70, unit: bar, source: ...}`` or a bare number in ``si_unit``."""
        if key not in self.data:
            if default is None:
                self.fail(f"missing key {key!r} (a value in {si_unit}); add it")
            return float(default)
        raw = self.data[key]
        if isinstance(raw, dict):
            q = Node(raw, self.file, self.path(key))
            q.only(QUANTITY_KEYS)
            value = q.number("value")
            return q.convert(value, q.str("unit", default=si_unit), si_unit)
        return self._as_number(raw, key)

    # -- units ------------------------------------------------------------------
    def unit(self, text: str, key: str = "unit") -> Unit:
        """Parse the unit ``text`` written at ``key``; a bad expression fails there."""
        try:
            return parse_unit(text)
        except ValueError as exc:
            self.fail(_unit_fix(str(exc)), key=key)
        except (ArithmeticError, RecursionError):
            # fractions and float powers overflow or divide by zero on e.g. 'm**(1/0)'
            self.fail(_unit_fix(f"cannot read unit {excerpt(text)}"), key=key)

    def convert(self, value: float, unit: str, si_unit: str, key: str = "unit") -> float:
        """``value`` given in ``unit`` as a number in ``si_unit``; a wrong unit fails at ``key``."""
        self.unit(unit, key)
        try:
            converted = to_si(value, unit, si_unit)
        except ValueError as exc:
            self.fail(_unit_fix(str(exc)), key=key)
        except ArithmeticError:
            converted = math.inf
        if not math.isfinite(converted):
            self.fail(f"{value!r} {unit} overflows in {si_unit}; give a smaller value", key=key)
        return converted
