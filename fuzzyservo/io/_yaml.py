"""Reading YAML mappings strictly: every key known, every value typed, every error located.

:class:`Node` wraps a parsed mapping with the file and the dotted key path so that
each problem becomes one :class:`~fuzzyservo.errors.ConfigError` line naming file,
key, value and fix.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import yaml

from fuzzyservo.errors import ConfigError
from fuzzyservo.units import to_si

QUANTITY_KEYS = ("value", "unit", "source", "note")


def read_yaml(path: str | Path) -> dict[str, Any]:
    """Parse a YAML file whose top level is a mapping."""
    p = Path(path)
    if not p.is_file():
        raise ConfigError(
            f"file not found (looked in {p.resolve().parent}); check the path", file=str(path)
        )
    try:
        data = yaml.safe_load(p.read_text(encoding="utf-8"))
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise ConfigError(
            f"{where}not valid YAML ({problem}); fix the syntax", file=str(path)
        ) from None
    if not isinstance(data, dict):
        raise ConfigError("the file must hold a YAML mapping (key: value lines)", file=str(path))
    return data


class Node:
    """A mapping inside a file, with its location for error messages."""

    def __init__(self, data: Any, file: str, key: str = ""):
        self.file = file
        self.key = key
        if not isinstance(data, dict):
            self.fail(f"must be a mapping (key: value lines), got {type(data).__name__} {data!r}")
        self.data: dict[str, Any] = data

    # -- locating ---------------------------------------------------------------
    def path(self, key: str) -> str:
        return f"{self.key}.{key}" if self.key else key

    def fail(self, message: str, key: str | None = None) -> ConfigError:
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
            self.fail(f"must be text, got {value!r}", key=key)
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
            self.fail(f"must be a list of numbers, got {value!r}", key=key)
        return [self._as_number(v, f"{key}[{i}]") for i, v in enumerate(value)]

    def _as_number(self, value: Any, key: str) -> float:
        if isinstance(value, str):
            # YAML 1.1 reads 1.4e9 (no sign after e) as text; accept what a person means
            try:
                value = float(value)
            except ValueError:
                self.fail(f"must be a number, got {value!r}", key=key)
        if isinstance(value, bool) or not isinstance(value, int | float):
            self.fail(f"must be a number, got {value!r}", key=key)
        if not math.isfinite(value):
            self.fail(f"must be finite, got {value!r}", key=key)
        return float(value)

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
            unit = q.str("unit", default=si_unit)
            try:
                return to_si(value, unit, si_unit)
            except ValueError as exc:
                q.fail(str(exc), key="unit")
        return self._as_number(raw, key)
