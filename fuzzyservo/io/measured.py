"""Measured rig data (CSV or MATLAB ``.mat``) ⇄ :class:`Measured`, time series in SI units.

Every column (or ``.mat`` variable) is named ``<signal>_<unit>``: ``t_s``, ``y_cm``,
``p1_bar``, ``w_rad_s`` (signal ``w`` in rad/s), ``v_m_s`` (``v`` in m/s), ``ref_1``
(dimensionless, e.g. a normalised force). The unit is the longest known suffix, so
``w_rad_s`` is ``w`` in ``rad_s``, not ``w_rad`` in ``s``. Files with plain names
(``t,r,u,y,d``) are read through ``mapping={"t": "t_s", "r": "ref_1", ...}``.

Signals are any identifier; ``t`` is time and must be given in a time unit. Values are
converted with :func:`fuzzyservo.units.to_si`. Groundwork for calibration: this module
only reads and checks data, it fits nothing.

A file that cannot be used raises :class:`~fuzzyservo.errors.DataError` with one line:
file, column, problem, fix. Row numbers are file line numbers (the header is row 1),
which is also the row a spreadsheet shows.
"""

from __future__ import annotations

import csv
import math
import re
from array import array
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, NoReturn

import numpy as np

from fuzzyservo.atomic import atomic_write
from fuzzyservo.errors import DataError, excerpt
from fuzzyservo.measured import ColumnScaling, Measured

if TYPE_CHECKING:
    from fuzzyservo.rig import MeasuredFormat
from fuzzyservo.limits import MAX_RECORD_SAMPLES, period_problem, record_problem
from fuzzyservo.units import parse_unit, to_si

__all__ = [
    "UNIT_SUFFIXES",
    "ColumnScaling",
    "Measured",
    "read_measured",
    "read_rig_data",
    "write_measured",
]

MIN_SAMPLES = 20
UNEVEN_TOLERANCE = 0.01  # relative spread (max dt - min dt) / median dt

# header suffix -> (unit expression for fuzzyservo.units, SI unit of the stored values)
UNIT_SUFFIXES: dict[str, tuple[str, str]] = {
    "s": ("s", "s"),
    "ms": ("ms", "s"),
    "min": ("min", "s"),
    "m": ("m", "m"),
    "cm": ("cm", "m"),
    "mm": ("mm", "m"),
    "um": ("um", "m"),
    "rad": ("rad", "rad"),
    "deg": ("deg", "rad"),
    "m_s": ("m/s", "m/s"),
    "cm_s": ("cm/s", "m/s"),
    "mm_s": ("mm/s", "m/s"),
    "m_s2": ("m/s^2", "m/s^2"),
    "rad_s": ("rad/s", "rad/s"),
    "deg_s": ("deg/s", "rad/s"),
    "rpm": ("rpm", "rad/s"),
    "A": ("A", "A"),
    "mA": ("mA", "A"),
    "V": ("V", "V"),
    "mV": ("mV", "V"),
    "Pa": ("Pa", "Pa"),
    "kPa": ("kPa", "Pa"),
    "bar": ("bar", "Pa"),
    "MPa": ("MPa", "Pa"),
    "N": ("N", "N"),
    "kN": ("kN", "N"),
    "N_m": ("N*m", "N*m"),
    "l_min": ("l/min", "m^3/s"),
    "m3_s": ("m^3/s", "m^3/s"),
    "1": ("1", "1"),
    "pct": ("pct", "1"),
}
_BY_LENGTH = sorted(UNIT_SUFFIXES, key=len, reverse=True)
_SIGNAL = re.compile(r"[A-Za-z][A-Za-z0-9_]*\Z")
_TIME_DIMS = parse_unit("s").dims
_MAP = "under the rig file's measured: columns"


@dataclass
class _Column:
    name: str  # as in the file
    spec: str  # <signal>_<unit>, after mapping
    signal: str
    suffix: str
    values: np.ndarray | None = None

    def label(self, kind: str) -> str:
        mapped = f" (mapped to {self.spec})" if self.spec != self.name else ""
        return f"{kind} {excerpt(self.name)}{mapped}"


def _known_units() -> str:
    return ", ".join(UNIT_SUFFIXES)


def _parse_name(file: str, kind: str, name: str, spec: str) -> _Column:
    """Split ``<signal>_<unit>`` at the longest known unit suffix."""
    where = f"{file}: {kind} {excerpt(name)}" + (
        f" (mapped to {excerpt(spec)})" if spec != name else ""
    )
    for suffix in _BY_LENGTH:
        if spec.endswith("_" + suffix):
            signal = spec[: -len(suffix) - 1]
            if _SIGNAL.match(signal):
                break
    else:
        if "_" not in spec.strip("_"):
            raise DataError(
                f"{where}: the name says no unit; name it <signal>_<unit> (e.g. y_cm, u_V) "
                f"or map it {_MAP} (e.g. {name}: y_cm) with its real signal and unit, "
                f"or leave it out with measured: drop: [{name}]"
            )
        head, unit = spec.split("_", 1)
        if not _SIGNAL.match(head):
            raise DataError(
                f"{where}: cannot read a signal name before the unit; start it with a letter, "
                "e.g. y_cm or p1_bar"
            )
        raise DataError(
            f"{where}: unknown unit {excerpt(unit)}; convert the values to a known unit "
            f"({_known_units()}) and rename it, e.g. {head}_{_BY_LENGTH[-1]}"
        )
    if signal == "t" and parse_unit(UNIT_SUFFIXES[suffix][0]).dims != _TIME_DIMS:
        raise DataError(
            f"{where}: signal 't' is time but unit {excerpt(suffix)} is not a time unit; give time in "
            "s or ms, or rename the signal (e.g. tau_N_m for a torque)"
        )
    return _Column(name=name, spec=spec, signal=signal, suffix=suffix)


def _columns(
    file: str, kind: str, names: list[str], mapping: Mapping[str, str] | None
) -> list[_Column]:
    mapping = dict(mapping or {})
    missing = [k for k in mapping if k not in names]
    if missing:
        raise DataError(
            f"{file}: the rig file's measured: columns names {kind} {excerpt(missing[0])}, which the "
            "file does not have; "
            f"use one of: {', '.join(names)}"
        )
    columns = []
    seen: dict[str, str] = {}
    for name in names:
        col = _parse_name(file, kind, name, mapping.get(name, name))
        if col.signal in seen:
            raise DataError(
                f"{file}: {col.label(kind)}: signal {excerpt(col.signal)} is also given by "
                f"{kind} {excerpt(seen[col.signal])}; keep one of them or rename a signal"
            )
        seen[col.signal] = name
        columns.append(col)
    return columns


def _check_required(
    file: str, kind: str, columns: list[_Column], require: Iterable[str], has_period: bool
) -> None:
    signals = {c.signal for c in columns}
    found = ", ".join(c.spec for c in columns)
    for signal in dict.fromkeys(("t", *require)):
        if signal in signals or (signal == "t" and has_period):
            continue
        if signal == "t":
            raise DataError(
                f"{file}: no time {kind} (found {found}); add a t_s {kind}, map one {_MAP}, "
                "or give measured: sample_period in the rig file to build time as n*T"
            )
        raise DataError(
            f"{file}: required signal {excerpt(signal)} missing (found {found}); add a "
            f"{signal}_<unit> {kind} or map one {_MAP}"
        )


def _check_finite(file: str, where: str, x: np.ndarray, row: Callable[[int], str]) -> None:
    bad = ~np.isfinite(x)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        what = "NaN" if np.isnan(x[i]) else "an infinite value"
        raise DataError(
            f"{file}: {where}: {what} at {row(i)} ({int(bad.sum())} non-finite values); "
            "fill the gap or delete those rows"
        )


def _time_axis(
    file: str,
    where: str,
    t: np.ndarray,
    signals: dict[str, np.ndarray],
    row: Callable[[int], str],
    resample: bool,
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Check the time column; with ``resample`` average repeated stamps and interpolate."""
    dt = np.diff(t)
    back = np.flatnonzero(dt < 0)
    if back.size:
        i = int(back[0])
        raise DataError(
            f"{file}: {where}: time goes backwards from {t[i]:.6g} s at {row(i)} to "
            f"{t[i + 1]:.6g} s at {row(i + 1)} ({back.size} such steps); sort the rows by time "
            "or split the file where a new record starts"
        )
    repeated = np.flatnonzero(dt == 0)
    if repeated.size and not resample:
        i = int(repeated[0])
        raise DataError(
            f"{file}: {where}: repeated time stamp {t[i]:.6g} s at {row(i)} and {row(i + 1)} "
            f"({repeated.size} repeated stamps); pass --resample (or resample: true under the rig "
            "file's measured:) to average them onto a uniform grid, or give measured: "
            "sample_period to rebuild time as n*T"
        )
    if resample:
        stamps, inverse, counts = np.unique(t, return_inverse=True, return_counts=True)
        if stamps.size < 2:
            raise DataError(
                f"{file}: {where}: every row has the time stamp {t[0]:.6g} s; "
                "give a real time column, or measured: sample_period in the rig file"
            )
        # Same number of points as rows: the mean row interval is the best estimate of the
        # true period when stamps are quantised (printed with too few digits).
        grid = np.linspace(stamps[0], stamps[-1], t.size)
        out = {
            k: np.interp(grid, stamps, np.bincount(inverse, weights=v) / counts)
            for k, v in signals.items()
        }
        return grid, out
    median = float(np.median(dt))
    spread = float(dt.max() - dt.min()) / median
    if spread > UNEVEN_TOLERANCE:
        i = int(np.argmax(np.abs(dt - median)))
        raise DataError(
            f"{file}: {where}: uneven sampling, dt from {dt.min():.6g} to {dt.max():.6g} s "
            f"(median {median:.6g} s, spread {100 * spread:.1f} % > {100 * UNEVEN_TOLERANCE:g} %); "
            f"worst gap {dt[i]:.6g} s between {row(i)} and {row(i + 1)} (t = {t[i]:.6g} s); "
            "pass --resample (or resample: true under the rig file's measured:) to resample "
            "onto a uniform grid by linear interpolation"
        )
    return t, signals


def _build(
    file: str,
    kind: str,
    columns: list[_Column],
    row: Callable[[int], str],
    sample_period_s: float | None,
    resample: bool,
) -> Measured:
    if not columns:
        raise DataError(f"{file}: no signal {kind}s besides time; add the measured signals")
    n = columns[0].values.size
    if n < MIN_SAMPLES:
        raise DataError(
            f"{file}: {columns[0].label(kind)}: only {n} samples, "
            f"at least {MIN_SAMPLES} are needed; record a longer run"
        )
    signals: dict[str, np.ndarray] = {}
    units: dict[str, str] = {}
    time_col = None
    for col in columns:
        expr, si = UNIT_SUFFIXES[col.suffix]
        with np.errstate(over="ignore"):  # an overflow is reported below, in one line
            values = col.values * to_si(1.0, expr, si)
        if not np.isfinite(values).all():
            big = float(col.values[~np.isfinite(values)][0])
            raise DataError(
                f"{file}: {col.label(kind)}: {big:g} {col.suffix} overflows in {si}; "
                "check the values and the unit of the column"
            )
        if col.signal == "t":
            time_col = (col, values)
            continue
        signals[col.signal] = values
        units[col.signal] = si
    if sample_period_s is not None:
        t = np.arange(n) * sample_period_s
    else:
        if time_col is None:  # _check_required rules this out; keep the error one line anyway
            raise DataError(f"{file}: no time {kind}; add a t_s {kind}")
        col, t = time_col
        t, signals = _time_axis(file, col.label(kind), t, signals, row, resample)
    return Measured(
        t=t,
        signals=signals,
        units=units,
        source=file,
        sample_period_s=float(np.median(np.diff(t))),
        columns={c.signal: c.label(kind) for c in columns},
    )


# -- CSV ---------------------------------------------------------------------------------


def _read_csv(
    p: Path,
    file: str,
    mapping: Mapping[str, str] | None,
    require: Iterable[str],
    has_period: bool,
    layout: _Layout,
) -> tuple[list[_Column], np.ndarray]:
    """Stream the CSV row by row into one float array per column (8 bytes a value, so a
    file is never held as text); the header is checked before any row is read.
    Returns the columns (with their values) and the file line number of each row."""
    kind = "column"
    skip = layout.skip_lines
    try:
        with p.open(encoding="utf-8-sig", newline="") as fh:
            first = next((line for k, line in enumerate(fh) if k >= skip and line.strip()), "")
            if not first:
                raise DataError(
                    f"{file}: the file is empty"
                    + (f" below its first {skip} lines (measured: skip_lines)" if skip else "")
                    + "; give a header line and data rows"
                )
            delimiter = next((d for d in ",;\t" if d in first), ",")
            fh.seek(0)
            # skipped lines read as blank ones, so reader.line_num stays the file's line number
            reader = csv.reader(
                ("\n" if k < skip else line for k, line in enumerate(fh)), delimiter=delimiter
            )
            if layout.names:
                header = list(layout.names)
            else:
                header = next(
                    (
                        [c.strip() for c in cells]
                        for cells in reader
                        if any(c.strip() for c in cells)
                    ),
                    None,
                )
            if header is None:
                raise DataError(
                    f"{file}: the header line names no column; write <signal>_<unit> names "
                    "such as t_s,y_cm"
                )
            _check_header(file, header)
            width = len(header)
            dropped = _dropped(file, header, layout.drop)
            kept = [name for j, name in enumerate(header) if j not in dropped]
            columns = _columns(file, kind, kept, mapping)
            _check_required(file, kind, columns, require, has_period)
            values = [array("d") for _ in kept]
            lines = array("q")
            for cells in reader:
                if not any(c.strip() for c in cells):
                    continue
                if len(cells) != width:
                    what = "measured: names gives" if layout.names else "the header has"
                    raise DataError(
                        f"{file}: row {reader.line_num} has {len(cells)} cells, {what} "
                        f"{width}; fix or delete the row"
                        + (
                            ""
                            if layout.names
                            else " (or skip a preamble with measured: skip_lines)"
                        )
                    )
                if dropped:
                    cells = [c for j, c in enumerate(cells) if j not in dropped]
                try:
                    row = [float(c) for c in cells]
                except ValueError:
                    _bad_cell(file, kind, columns, cells, reader, first_row=not lines)
                if len(lines) == MAX_RECORD_SAMPLES:  # this row is one too many
                    raise DataError(
                        f"{file}: row {reader.line_num}: {record_problem(len(lines) + 1)}"
                    )
                for column, value in zip(values, row, strict=True):
                    column.append(value)
                lines.append(reader.line_num)
    except UnicodeDecodeError as exc:
        raise DataError(
            f"{file}: not UTF-8 text (byte {exc.object[exc.start]:#04x}); "
            "save the file as UTF-8 CSV"
        ) from None
    except OSError as exc:
        raise DataError(
            f"{file}: cannot read the file ({exc.strerror or exc}); check its permissions"
        ) from None
    if not lines:
        raise DataError(f"{file}: no data rows below the header; add measurements")
    for col, column in zip(columns, values, strict=True):
        col.values = np.frombuffer(column, dtype=np.float64)
    return columns, np.frombuffer(lines, dtype=np.int64)


@dataclass(frozen=True)
class _Layout:
    """Where the numbers are in a text file: lines above the header, the column names
    of a file without a header line, columns to leave out."""

    skip_lines: int = 0
    names: tuple[str, ...] = ()
    drop: tuple[str, ...] = ()


def _dropped(file: str, header: list[str], drop: Iterable[str]) -> set[int]:
    """Indices of the columns ``drop`` names (each must exist)."""
    out = set()
    for name in drop:
        if name not in header:
            raise DataError(
                f"{file}: measured: drop names column {excerpt(name)}, which the file does not have; "
                f"use one of: {', '.join(header)} (if lines stand above the header, skip them "
                "with measured: skip_lines)"
            )
        out.add(header.index(name))
    if len(out) == len(header):
        raise DataError(f"{file}: measured: drop leaves no column; drop fewer columns")
    return out


def _check_header(file: str, header: list[str]) -> None:
    for j, name in enumerate(header):
        if not name:
            raise DataError(
                f"{file}: column {j + 1} has no name; name it <signal>_<unit> (e.g. y_cm)"
            )
        if name in header[:j]:
            raise DataError(f"{file}: column {excerpt(name)} appears twice; rename or delete one")


def _bad_cell(
    file: str, kind: str, columns: list[_Column], cells: list[str], reader, first_row: bool
) -> NoReturn:
    """The one-line error for the first cell of this row that is not a number."""
    line = reader.line_num
    for col, cell in zip(columns, cells, strict=True):
        cell = cell.strip()
        try:
            float(cell)
            continue
        except ValueError:
            pass
        where = col.label(kind)
        if not cell:
            j = columns.index(col)
            if first_row and not any(r[j].strip() for r in reader if len(r) > j):
                raise DataError(
                    f"{file}: {where}: the column is empty; fill it or delete the column"
                )
            raise DataError(
                f"{file}: {where}: empty cell at row {line}; fill the gap or delete the row"
            )
        raise DataError(
            f"{file}: {where}: {excerpt(cell)} at row {line} is not a number; write a plain number "
            "(decimal point '.', no units or thousands separators) or delete the row"
            + (
                f", or leave a text column out with measured: drop: [{col.name}]"
                if first_row
                else ""
            )
        )
    raise DataError(f"{file}: row {line}: cannot read the numbers; check the row")


# -- MATLAB ------------------------------------------------------------------------------


def _read_mat_vectors(p: Path, file: str) -> dict[str, np.ndarray]:
    import scipy.io  # only .mat files need scipy.io

    try:
        # the headers first: a compressed variable may unpack to gigabytes
        for name, shape, kind in scipy.io.whosmat(p):
            if name.startswith("__"):
                continue
            if kind in ("cell", "struct", "object", "function", "opaque"):
                raise DataError(
                    f"{file}: variable {excerpt(name)} is a MATLAB {kind}, not real numbers; "
                    "save each signal as a numeric vector"
                )
            if record_problem(math.prod(shape)):
                raise DataError(
                    f"{file}: variable {excerpt(name)} has {math.prod(shape):,} values, "
                    f"{record_problem(math.prod(shape))}"
                )
        data = scipy.io.loadmat(p)
    except DataError:
        raise
    except Exception as exc:  # scipy raises many types for files it cannot read
        raise DataError(
            f"{file}: cannot read it as a MATLAB file ({type(exc).__name__}: {exc}); "
            "save it from MATLAB with save(..., '-v7')"
        ) from None
    vectors = {}
    for name, value in data.items():
        if name.startswith("__"):
            continue
        x = np.asarray(value)
        if x.dtype.kind not in "biuf":
            raise DataError(
                f"{file}: variable {excerpt(name)} holds {x.dtype} data, not real numbers; "
                "save each signal as a numeric vector"
            )
        if sum(d > 1 for d in x.shape) > 1:
            raise DataError(
                f"{file}: variable {excerpt(name)} is a {'x'.join(map(str, x.shape))} matrix; "
                "save each signal as its own vector"
            )
        vectors[name] = x.astype(np.float64).ravel()
    if not vectors:
        raise DataError(f"{file}: the file holds no variables; save the signals into it")
    return vectors


# -- entry point -------------------------------------------------------------------------


def read_measured(
    path: str | Path,
    *,
    mapping: Mapping[str, str] | None = None,
    sample_period_s: float | None = None,
    resample: bool = False,
    require: Iterable[str] = ("t",),
    scaling: Mapping[str, ColumnScaling] | None = None,
    skip_lines: int = 0,
    names: Sequence[str] = (),
    drop: Sequence[str] = (),
) -> Measured:
    """Read a measured-data CSV or ``.mat`` file into SI arrays.

    Parameters
    ----------
    path:
        A CSV file (one header line of ``<signal>_<unit>`` names) or a MATLAB ``.mat``
        file (one vector per variable, named the same way).
    mapping:
        Plain column or variable name -> ``<signal>_<unit>``, e.g. ``{"r": "ref_1"}``.
    sample_period_s:
        Build time as ``n * sample_period_s``; a time column, if any, is then ignored
        (for files without a usable time column, e.g. stamps printed with too few digits).
    resample:
        Average repeated time stamps and interpolate linearly onto a uniform grid with
        as many points as rows. Without it, repeated stamps or a spread of dt above 1 %
        is an error. Time that goes backwards is always an error.
    require:
        Signals that must be present, e.g. ``("t", "u", "y")`` for a closed-loop replay;
        time (``t``) is always needed, from a column or from ``sample_period_s``.
    scaling:
        Plain column or variable name -> :class:`~fuzzyservo.rig.ColumnScaling`: scale,
        offset and tare that turn its raw numbers (volts of a sensor, tonne-force) into
        the unit its name (or ``mapping``) gives.
    skip_lines, names, drop:
        CSV layout of a DAQ export: lines above the header to skip; the column names
        of a file without a header line; columns to leave out (dates, comments).

    Raises :class:`DataError` (one line: file, column, problem, fix) for a file that
    cannot be used.
    """
    file = str(path)
    p = Path(path)
    if sample_period_s is not None and (
        not isinstance(sample_period_s, int | float) or period_problem(sample_period_s)
    ):
        raise DataError(
            f"{file}: the sample period (measured: sample_period in the rig file) "
            f"{period_problem(float(sample_period_s)) if isinstance(sample_period_s, int | float) else 'must be a number'}"
        )
    if not p.is_file():
        raise DataError(f"{file}: file not found (looked in {p.resolve().parent}); check the path")

    if p.suffix.lower() == ".mat":
        kind = "variable"
        vectors = _read_mat_vectors(p, file)
        columns = _columns(file, kind, list(vectors), mapping)
        _check_required(file, kind, columns, require, sample_period_s is not None)

        def row(i: int) -> str:
            return f"sample {i + 1}"

        for col in columns:
            col.values = vectors[col.name]
            if col.values.size != columns[0].values.size:
                raise DataError(
                    f"{file}: {col.label(kind)}: {col.values.size} samples but "
                    f"{excerpt(columns[0].name)} has {columns[0].values.size}; save vectors of one length"
                )
    else:
        kind = "column"
        layout = _Layout(skip_lines=skip_lines, names=tuple(names), drop=tuple(drop))
        columns, lines = _read_csv(p, file, mapping, require, sample_period_s is not None, layout)

        def row(i: int) -> str:
            return f"row {lines[i]}"

    if sample_period_s is not None:
        columns = [c for c in columns if c.signal != "t"]  # time is rebuilt; ignore the stamps
    for col in columns:
        _check_finite(file, col.label(kind), col.values, row)
    _scale(file, kind, columns, scaling or {})
    return _build(file, kind, columns, row, sample_period_s, resample)


def _scale(
    file: str, kind: str, columns: list[_Column], scaling: Mapping[str, ColumnScaling]
) -> None:
    """Apply each column's scale, offset and tare (in the unit it is mapped to)."""
    names = {c.name for c in columns}
    for name in scaling:
        if name not in names:
            raise DataError(
                f"{file}: the rig file's measured: columns scales {kind} {excerpt(name)}, which the "
                f"file does not have (or which is dropped); use one of: {', '.join(sorted(names))}"
            )
    for col in columns:
        how = scaling.get(col.name)
        if how is None:
            continue
        values = how.scale * col.values + how.offset
        if how.tare_samples:
            if how.tare_samples > values.size:
                raise DataError(
                    f"{file}: {col.label(kind)}: tare over the first {how.tare_samples} samples "
                    f"but the file has {values.size}; give a tare of at most {values.size}"
                )
            values = values - float(np.mean(values[: how.tare_samples]))
        col.values = values


def read_rig_data(
    path: str | Path, fmt: MeasuredFormat | None, *, resample: bool = False
) -> Measured:
    """Read a data file as a rig file's ``measured:`` section (``fmt``) says: column
    mapping and scaling, sample period, resampling (also when ``resample``), layout."""
    if fmt is None:
        return read_measured(path, resample=resample)
    return read_measured(
        path,
        mapping=fmt.columns or None,
        sample_period_s=fmt.sample_period_s,
        resample=fmt.resample or resample,
        scaling=fmt.scaling,
        skip_lines=fmt.skip_lines,
        names=fmt.names,
        drop=fmt.drop,
    )


def write_measured(path: str | Path, data: Measured, units: Mapping[str, str]) -> Path:
    """Write ``data`` as a CSV with ``<signal>_<unit>`` headers, each signal converted from
    SI to the header unit given in ``units`` (a key of :data:`UNIT_SUFFIXES`; SI if absent)."""
    columns = [np.asarray(data.t, dtype=float)]
    header = [f"t_{units.get('t', 's')}"]
    for name in data.signals:
        suffix = units.get(name) or _si_suffix(data.units[name])
        expr, si = UNIT_SUFFIXES[suffix]
        factor = to_si(1.0, expr, si)
        columns.append(np.asarray(data.signals[name], dtype=float) / factor)
        header.append(f"{name}_{suffix}")
    if "t" in units:
        expr, si = UNIT_SUFFIXES[units["t"]]
        columns[0] = columns[0] / to_si(1.0, expr, si)
    rows = np.column_stack(columns)
    with atomic_write(path, newline="") as fh:
        fh.write(",".join(header) + "\n")
        for row in rows:
            fh.write(",".join(f"{v:.10g}" for v in row) + "\n")
    return Path(path)


def _si_suffix(si_unit: str) -> str:
    for suffix, (_expr, si) in UNIT_SUFFIXES.items():
        if si == si_unit and UNIT_SUFFIXES[suffix][0] == si_unit:
            return suffix
    raise ValueError(f"no column suffix for SI unit {si_unit!r}; give one in units")
