"""The ``measured:`` section of a rig file: how its measured-data files are laid out
(preamble lines, column names, dropped columns), which column is which signal in which
unit, how raw columns are scaled, offset and tared, and the sample period. Used by
:mod:`fuzzyservo.io.rigs`.
"""

from __future__ import annotations

from fuzzyservo.errors import excerpt
from fuzzyservo.io._yaml import Node
from fuzzyservo.io.measured import ColumnScaling
from fuzzyservo.limits import period_problem
from fuzzyservo.rig import MeasuredFormat
from fuzzyservo.units import parse_unit


def _measured(node: Node) -> MeasuredFormat:
    """The ``measured:`` section: plain column names -> ``<signal>_<unit>`` (or a mapping
    with ``as``, ``from``, ``scale``, ``offset``, ``tare``), sample period, file layout."""
    node.only(
        ("columns", "sample_period", "resample", "skip_lines", "names", "drop", "source", "note")
    )
    columns: dict[str, str] = {}
    scaling: dict[str, ColumnScaling] = {}
    if node.has("columns"):
        cols = node.child("columns")
        for plain in cols.data:
            key = str(plain)
            if isinstance(cols.data[plain], dict):
                columns[key], scaling[key] = _column_scaling(cols.child(key))
            else:
                columns[key] = cols.str(key)
    skip = node.quantity("skip_lines", "1", default=0.0)
    if skip != int(skip) or skip < 0:
        node.fail(f"must be a whole number of lines >= 0, got {skip:g}", key="skip_lines")
    names = tuple(_text_list(node, "names"))
    drop = tuple(_text_list(node, "drop"))
    period = node.quantity("sample_period", "s") if node.has("sample_period") else None
    if period is not None and period_problem(period):
        node.fail(period_problem(period), key="sample_period")
    resample = node.flag("resample", False, "resample onto an even time grid")
    return MeasuredFormat(
        columns=columns,
        sample_period_s=period,
        resample=resample,
        scaling=scaling,
        skip_lines=int(skip),
        names=names,
        drop=drop,
    )


def _text_list(node: Node, key: str) -> list[str]:
    if not node.has(key):
        return []
    raw = node.data[key]
    if not isinstance(raw, list) or not raw or not all(isinstance(v, str) and v for v in raw):
        node.fail(f"must be a list of column names, like [t, r, y, u], got {excerpt(raw)}", key=key)
    return list(raw)


def _column_scaling(node: Node) -> tuple[str, ColumnScaling]:
    """One scaled column: ``{as: y_mm, from: V, scale: {value: 20, unit: mm/V},
    offset: {value: -5, unit: mm}, tare: 50}`` -> (``y_mm``, scaling in mm per raw unit).

    ``from`` is the unit of the raw numbers (default: plain numbers with a ``scale``,
    else the ``as`` unit). ``scale``
    (default 1 in the ``as`` unit per ``from`` unit) may carry a unit, which must be the
    ``as`` unit over the ``from`` unit in dimension; ``offset`` (default 0) is in the
    ``as`` unit unless it says its own; ``tare`` subtracts the mean of the first
    ``tare`` samples (a load cell's zero)."""
    from fuzzyservo.io.measured import UNIT_SUFFIXES

    node.only(("as", "from", "scale", "offset", "tare", "source", "note"))
    spec = node.str("as")
    suffix = next(
        (u for u in sorted(UNIT_SUFFIXES, key=len, reverse=True) if spec.endswith("_" + u)), None
    )
    if suffix is None or spec == "_" + suffix:
        node.fail(
            f"{excerpt(spec)} names no signal and unit; write <signal>_<unit>, e.g. y_mm or load_N",
            key="as",
        )
    target = UNIT_SUFFIXES[suffix][0]  # unit expression of the mapped column
    # without `from` and `scale` the raw numbers are already in the `as` unit (a tare only)
    raw_unit = node.str("from", default="1" if node.has("scale") else target)
    raw = node.unit(raw_unit, key="from")
    target_unit = parse_unit(target)
    if not node.has("scale"):
        if raw.dims != target_unit.dims:
            node.fail(
                f"from: {raw_unit} is not {target} in dimension; give a scale, "
                f"e.g. {{value: 20, unit: {target}/{raw_unit}}}",
                key="from",
            )
        scale = raw.factor / target_unit.factor
    elif isinstance(node.data["scale"], dict):
        scale_node = node.child("scale")
        scale_node.only(("value", "unit", "source", "note"))
        number = scale_node.number("value")
        unit = scale_node.unit(scale_node.str("unit"))
        if tuple(a + b for a, b in zip(unit.dims, raw.dims, strict=True)) != target_unit.dims:
            node.fail(
                f"unit {excerpt(scale_node.str('unit'))} does not turn {raw_unit} into {target}; "
                f"give the scale in {target}/{raw_unit} (or set from: to the raw unit)",
                key="scale.unit",
            )
        scale = number * unit.factor * raw.factor / target_unit.factor
    else:  # a plain number: the `as` unit per `from` unit (20 for 20 mm/V)
        scale = node.number("scale")
    if scale == 0:
        node.fail("must not be zero; give the sensor's sensitivity", key="scale")
    offset = 0.0
    if node.has("offset"):
        value = node.data["offset"]
        if isinstance(value, dict):
            offset = node.quantity("offset", UNIT_SUFFIXES[suffix][1]) / target_unit.factor
        else:
            offset = node.number("offset")
    tare = node.quantity("tare", "1", default=0.0)
    if tare != int(tare) or tare < 0:
        node.fail(
            f"must be a whole number of samples >= 1 (the load cell's zero is their mean), "
            f"got {tare:g}",
            key="tare",
        )
    return spec, ColumnScaling(scale=scale, offset=offset, tare_samples=int(tare))
