"""Input and output tables of ``fuzzyservo evaluate``, and the systems it evaluates.

Inputs: a CSV file with a header row; one column per input variable, named like it (any
order; other columns are ignored and reported). Outputs: a CSV with one column per
output variable, in the system's order, written with ``repr`` precision.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from fuzzyservo.atomic import atomic_write
from fuzzyservo.controllers.fuzzy.controller import FuzzyController
from fuzzyservo.controllers.fuzzy.system import FuzzySystem
from fuzzyservo.errors import ConfigError, excerpt

__all__ = [
    "load_exportable",
    "load_fuzzy_controller",
    "load_system",
    "read_input_table",
    "write_output_table",
]


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
        from fuzzyservo.io.fuzzy_files import read_fis

        return read_fis(path)
    if suffix == ".fcl":
        from fuzzyservo.io.fuzzy_files import read_fcl

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


def load_exportable(path: str | Path) -> FuzzyController | FuzzySystem:
    """What ``path`` holds for export: a controller (a fuzzy controller YAML file, or a
    ``.fis``/FCL file with a control-law comment) or an inference system (any other
    ``.fis``/FCL file)."""
    from fuzzyservo.controllers.fuzzy.fis import controller_from_law
    from fuzzyservo.io.fuzzy_files import read_fcl_law, read_fis_law

    p = Path(path)
    suffix = p.suffix.lower()
    if suffix not in (".fis", ".fcl"):
        return load_fuzzy_controller(p, other=", a .fis or a .fcl")
    system, law = (read_fis_law if suffix == ".fis" else read_fcl_law)(p)
    return controller_from_law(system, law, p, "[Rules]") if law else system
