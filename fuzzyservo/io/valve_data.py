"""Valve data (CSV) and trained valve networks (JSON) ⇄ arrays in SI units.

A valve-data CSV has one header line naming six columns, each ``<quantity>_<unit>``, in
this order: ``p_s_bar, u_c_V, p_a_bar, p_b_bar, q_a_l_min, q_b_l_min`` (seed 003 §3:
supply pressure, control voltage, chamber pressures, port flows). Pressures may also be
given in ``Pa``, ``kPa`` or ``MPa``, flows in ``m3_s``.

A network file holds the 4-5-2 network of :mod:`fuzzyservo.components.valves` (SI
inputs and outputs), its normalisation and the training and validation RMS errors.
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fuzzyservo.atomic import atomic_write, write_text
from fuzzyservo.components.valves import (
    NN_B1,
    NN_B2,
    NN_HIDDEN,
    NN_IN_OFFSET,
    NN_IN_SCALE,
    NN_INPUTS,
    NN_OUT_OFFSET,
    NN_OUT_SCALE,
    NN_OUTPUTS,
    NN_SIZE,
    NN_W1,
    NN_W2,
)
from fuzzyservo.errors import DataError, excerpt

if TYPE_CHECKING:
    pass

COLUMNS = ("p_s", "u_c", "p_a", "p_b", "q_a", "q_b")
DEFAULT_UNITS = ("bar", "V", "bar", "bar", "l_min", "l_min")
# header unit token -> factor to SI, per kind of column
_PRESSURE = {"bar": 1e5, "Pa": 1.0, "kPa": 1e3, "MPa": 1e6}
_UNITS = {
    "p_s": _PRESSURE,
    "u_c": {"V": 1.0},
    "p_a": _PRESSURE,
    "p_b": _PRESSURE,
    "q_a": {"l_min": 1e-3 / 60, "m3_s": 1.0},
    "q_b": {"l_min": 1e-3 / 60, "m3_s": 1.0},
}
FORMAT = "fuzzyservo valve network 1"


def _header_factors(header: list[str], file: str) -> list[float]:
    expected = ", ".join(f"{c}_{u}" for c, u in zip(COLUMNS, DEFAULT_UNITS, strict=True))
    if len(header) != len(COLUMNS):
        raise DataError(
            f"{file}: header has {len(header)} columns, expected {len(COLUMNS)}; "
            f"write the header as: {expected}"
        )
    factors = []
    for name, column in zip(header, COLUMNS, strict=True):
        name = name.strip()
        unit = name[len(column) + 1 :] if name.startswith(column + "_") else None
        if unit not in _UNITS[column]:
            raise DataError(
                f"{file}: column {excerpt(name)} is not {column} with a known unit "
                f"({', '.join(column + '_' + u for u in _UNITS[column])}); "
                f"write the header as: {expected}"
            )
        factors.append(_UNITS[column][unit])
    return factors


def read_valve_csv(path: str | Path) -> np.ndarray:
    """Rows (p_s, u_c, p_a, p_b, q_a, q_b) in SI (Pa, V, m³/s); :class:`DataError` on a bad file."""
    file = str(path)
    p = Path(path)
    if not p.is_file():
        raise DataError(f"{file}: file not found; check the path")
    try:
        with p.open(newline="", encoding="utf-8") as fh:
            rows = [row for row in csv.reader(fh) if row and any(c.strip() for c in row)]
    except (OSError, UnicodeDecodeError) as exc:
        raise DataError(f"{file}: cannot read the file ({exc}); save it as UTF-8 CSV") from None
    if not rows:
        raise DataError(f"{file}: the file is empty; give a header line and data rows")
    factors = _header_factors(rows[0], file)
    if len(rows) < 2:
        raise DataError(f"{file}: no data rows below the header; add measurements")
    data = np.empty((len(rows) - 1, len(COLUMNS)))
    for i, row in enumerate(rows[1:]):
        line = i + 2
        if len(row) != len(COLUMNS):
            raise DataError(
                f"{file}: line {line} has {len(row)} values, expected {len(COLUMNS)}; fix the row"
            )
        for j, cell in enumerate(row):
            try:
                value = float(cell)
            except ValueError:
                value = math.nan
            if not math.isfinite(value):
                raise DataError(
                    f"{file}: line {line}, column {rows[0][j].strip()}: {excerpt(cell.strip())} is not a "
                    "finite number; fix or delete the row"
                )
            data[i, j] = value * factors[j]
    return data


def write_valve_csv(path: str | Path, data: np.ndarray) -> Path:
    """Write SI rows as a valve-data CSV in the default units (bar, V, l/min)."""
    p = Path(path)
    factors = [_UNITS[c][u] for c, u in zip(COLUMNS, DEFAULT_UNITS, strict=True)]
    with atomic_write(p, newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(f"{c}_{u}" for c, u in zip(COLUMNS, DEFAULT_UNITS, strict=True))
        for row in np.asarray(data, dtype=np.float64):
            writer.writerow(f"{v / f:.10g}" for v, f in zip(row, factors, strict=True))
    return p


@dataclass(frozen=True)
class ValveNetwork:
    """A trained valve network: the flat weight vector and how well it fits (RMS, m³/s)."""

    weights: tuple[float, ...]
    train_rms_m3_s: tuple[float, ...] = ()
    validation_rms_m3_s: tuple[float, ...] = ()


_BLOCKS = (
    ("input_offset", NN_IN_OFFSET, (NN_INPUTS,)),
    ("input_scale", NN_IN_SCALE, (NN_INPUTS,)),
    ("w1", NN_W1, (NN_HIDDEN, NN_INPUTS)),
    ("b1", NN_B1, (NN_HIDDEN,)),
    ("w2", NN_W2, (NN_OUTPUTS, NN_HIDDEN)),
    ("b2", NN_B2, (NN_OUTPUTS,)),
    ("output_offset", NN_OUT_OFFSET, (NN_OUTPUTS,)),
    ("output_scale", NN_OUT_SCALE, (NN_OUTPUTS,)),
)


def write_valve_network(
    path: str | Path,
    weights: np.ndarray,
    train_rms_m3_s: tuple[float, ...],
    validation_rms_m3_s: tuple[float, ...],
    training: dict,
) -> Path:
    """Write a network as JSON: layers, SI input/output names, weights and RMS errors."""
    w = np.asarray(weights, dtype=np.float64)
    payload: dict = {
        "format": FORMAT,
        "layers": [NN_INPUTS, NN_HIDDEN, NN_OUTPUTS],
        "activation": ["tanh", "linear"],
        "inputs": ["p_s_pa", "u_c_v", "p_a_pa", "p_b_pa"],
        "outputs": ["q_a_m3_s", "q_b_m3_s"],
    }
    for name, start, shape in _BLOCKS:
        payload[name] = w[start : start + int(np.prod(shape))].reshape(shape).tolist()
    to_l_min = 60e3
    payload["training"] = {
        **training,
        "train_rms_l_min": dict(
            zip(("q_a", "q_b"), [v * to_l_min for v in train_rms_m3_s], strict=True)
        ),
        "validation_rms_l_min": dict(
            zip(("q_a", "q_b"), [v * to_l_min for v in validation_rms_m3_s], strict=True)
        ),
    }
    return write_text(path, json.dumps(payload, indent=2) + "\n")


def read_valve_network(path: str | Path) -> ValveNetwork:
    """Read a network file; :class:`DataError` naming the file and the block that is wrong."""
    file = str(path)
    try:
        payload = json.loads(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise DataError(f"{file}: file not found; run `fuzzyservo fit-valve` to write it") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        # RecursionError: nested deeper than the JSON parser goes
        raise DataError(f"{file}: not a readable JSON file ({exc}); rewrite it") from None
    if not isinstance(payload, dict) or payload.get("format") != FORMAT:
        raise DataError(
            f"{file}: format is not {FORMAT!r}; write the file with `fuzzyservo fit-valve`"
        )
    w = np.empty(NN_SIZE)
    for name, start, shape in _BLOCKS:
        try:
            block = np.asarray(payload[name], dtype=np.float64)
        except (KeyError, TypeError, ValueError):
            raise DataError(
                f"{file}: {name}: missing or not numbers; expected shape {shape}"
            ) from None
        if block.shape != shape or not np.isfinite(block).all():
            raise DataError(
                f"{file}: {name}: expected {shape} finite numbers, got shape {block.shape}"
            )
        w[start : start + block.size] = block.ravel()
    if not (w[NN_IN_SCALE : NN_IN_SCALE + NN_INPUTS] != 0).all():
        raise DataError(f"{file}: input_scale: must not contain zeros")
    training = payload.get("training", {})

    def _rms(key: str) -> tuple[float, ...]:
        values = training.get(key, {})
        return tuple(float(values[k]) / 60e3 for k in ("q_a", "q_b") if k in values)

    return ValveNetwork(
        weights=tuple(float(v) for v in w),
        train_rms_m3_s=_rms("train_rms_l_min"),
        validation_rms_m3_s=_rms("validation_rms_l_min"),
    )


def network_file(rig_path: str | Path) -> Path:
    """The weights file a rig file's network_valve names (relative to the rig file)."""
    from fuzzyservo.errors import ConfigError
    from fuzzyservo.io._yaml import read_yaml

    path = Path(rig_path)
    parts = read_yaml(path).get("plant", {}).get("components") or {}
    for part in parts.values():
        entry = (part.get("parameters") or {}).get("weights") if isinstance(part, dict) else None
        if isinstance(entry, dict) and "file" in entry:
            return path.parent / entry["file"]
    raise ConfigError(
        "has no network_valve with a weights file; give --out FILE",
        file=str(path),
        key="plant.components",
    )
