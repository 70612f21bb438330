"""Input and output tables of ``fuzzyservo evaluate``, and the systems it evaluates.

Inputs: a CSV file with a header row; one column per input variable, named like it (any
order; other columns are ignored and reported). Outputs: a CSV with one column per
output variable, in the system's order, written with ``repr`` precision.
"""

from __future__ import annotations

import csv
import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from fuzzyservo.atomic import atomic_write
from fuzzyservo.controllers.fuzzy.controller import FuzzyController
from fuzzyservo.controllers.fuzzy.system import FuzzySystem
from fuzzyservo.errors import ConfigError, excerpt
from fuzzyservo.results import Result

__all__ = [
    "FuzzyEvaluation",
    "evaluate",
    "load_fuzzy_controller",
    "load_system",
    "read_input_table",
    "write_output_table",
]


@dataclass(frozen=True)
class FuzzyEvaluation(Result):
    """A fuzzy system's outputs for a table of inputs; ``text()`` is the output CSV."""

    system: FuzzySystem
    inputs: np.ndarray
    outputs: np.ndarray
    ignored: tuple[str, ...] = ()
    silent: int = 0

    @property
    def output_names(self) -> list[str]:
        return [v.name for v in self.system.outputs]

    @property
    def notes(self) -> list[str]:
        """Input columns ignored, and outputs where no rule fired (the CLI's stderr lines)."""
        s, out = self.system, []
        if self.ignored:
            out.append(
                f"note: column(s) {list(self.ignored)} are not inputs of {excerpt(s.name)}; ignored"
            )
        if self.silent:
            fallback = "the middle of its range" if s.semantics == "matlab" else "NaN"
            out.append(f"warning: no rule fired for {self.silent} output value(s); each is "
                       f"{fallback} ({s.semantics} semantics)")  # fmt: skip
        return out

    def text(self) -> str:
        rows = (",".join(repr(float(v)) for v in row) for row in self.outputs)
        return "\n".join([",".join(self.output_names), *rows])

    def to_dict(self) -> dict[str, Any]:
        return {"system": self.system.name, "semantics": self.system.semantics,
                "outputs": {n: self.outputs[:, k].tolist() for k, n in enumerate(self.output_names)}}  # fmt: skip

    def write(self, path: str | Path) -> Path:
        """The outputs as a CSV file (:func:`write_output_table`)."""
        return write_output_table(path, self.output_names, self.outputs)


def evaluate(
    system: FuzzySystem | str | Path, inputs: np.ndarray | str | Path, semantics: str | None = None
) -> FuzzyEvaluation:
    """What ``evalfis`` does: ``system`` (or its ``.fis``, ``.fcl`` or controller file) on
    ``inputs`` (an (m, n_inputs) array, or a CSV with a column per input named like it),
    in ``semantics`` (``skfuzzy`` or ``matlab``; default: the system's)."""
    from fuzzyservo.controllers.fuzzy.evaluate import evaluate_inputs

    if not isinstance(system, FuzzySystem):
        system = load_system(Path(system))
    if semantics:
        system = dataclasses.replace(system, semantics=semantics)
    ignored: list[str] = []
    if not isinstance(inputs, np.ndarray):
        inputs, ignored = read_input_table(inputs, [v.name for v in system.inputs])
    outputs, silent = evaluate_inputs(system, inputs)
    return FuzzyEvaluation(system, inputs, outputs, tuple(ignored), silent)


def load_fuzzy_controller(path: Path, other: str = " or a .fis") -> FuzzyController:
    """A fuzzy controller file (YAML or .fis); a classical controller is refused (the
    error names the ``other`` files that would do)."""
    from fuzzyservo.io.controllers import load_controller

    controller = load_controller(path)
    if not isinstance(controller, FuzzyController):
        raise ConfigError(
            f"is a {type(controller).__name__} controller, not a fuzzy one; give a 'kind: fuzzy' "
            f"file{other}",
            file=str(path),
        )
    return controller


def load_system(path: Path) -> FuzzySystem:
    """The inference system of a ``.fis``, ``.fcl`` or fuzzy controller (YAML) file; any
    number of inputs and outputs (a controller file gives its one- or two-input system)."""
    suffix = path.suffix.lower()
    if suffix == ".fis":
        from fuzzyservo.io.fis import read_fis

        return read_fis(path)
    if suffix == ".fcl":
        from fuzzyservo.io.fcl import read_fcl

        return read_fcl(path)
    return load_fuzzy_controller(path, other=", a .fis or a .fcl").system


def read_input_table(path: str | Path, names: list[str]) -> tuple[np.ndarray, list[str]]:
    """The columns ``names`` of a CSV file as an (m, len(names)) array; also the names of
    the columns that were ignored. Errors name the file, the column and the row."""
    p = Path(path)
    file = str(path)
    if not p.is_file():
        raise ConfigError("file not found; check the path", file=file)
    try:
        with p.open(newline="", encoding="utf-8-sig") as f:
            rows = list(csv.reader(f))
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(
            f"cannot read it as a UTF-8 CSV file ({exc}); save it as CSV", file=file
        ) from None
    rows = [r for r in rows if any(cell.strip() for cell in r)]
    if not rows:
        raise ConfigError(f"is empty; give a header row naming the inputs {names}", file=file)
    header = [h.strip() for h in rows[0]]
    missing = [n for n in names if n not in header]
    if missing:
        raise ConfigError(
            f"has no column for input(s) {missing} (columns: {header}); name one column after "
            f"each input variable: {names}",
            file=file,
        )
    index = [header.index(n) for n in names]
    data = np.empty((len(rows) - 1, len(names)))
    for r, row in enumerate(rows[1:], start=2):
        for c, (name, k) in enumerate(zip(names, index, strict=True)):
            text = row[k].strip() if k < len(row) else ""
            try:
                value = float(text)
            except ValueError:
                value = math.nan
            if not math.isfinite(value):
                raise ConfigError(
                    f"row {r}: {excerpt(text)} is not a finite number; give a number for every input",
                    file=file,
                    key=name,
                )
            data[r - 2, c] = value
    if data.shape[0] == 0:
        raise ConfigError("has a header but no rows; add input rows", file=file)
    return data, [h for h in header if h not in names]


def write_output_table(path: str | Path, names: list[str], values: np.ndarray) -> Path:
    """Write the outputs (m, len(names)) as CSV with a header row of output names."""
    with atomic_write(path, newline="") as f:
        writer = csv.writer(f)
        writer.writerow(names)
        writer.writerows([[repr(float(v)) for v in row] for row in values])
    return Path(path)
