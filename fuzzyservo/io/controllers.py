"""Controller files (YAML) to controller objects.

name: p_k10
kind: P                 # P | PI | open_loop | fuzzy (see fuzzyservo.io.fuzzy)
description: ...
source: seed 002 §5
gain: 10                # V/V (P, open_loop)
kp: 1.0                 # PI, PIDF
ki: 0.5                 # PI, PIDF; 1/s
kd: 0.01                # PIDF; s
filter_time: 0.002      # PIDF; s, derivative filter time constant Tf (MATLAB's 1/N); default 0
form: parallel          # PIDF; parallel | PI-D | I-PD (default parallel)
output_limits: [-3, 3]  # V, optional: default is the rig actuator's command range

A gain of P, PI or PIDF may be declared unknown, ``kp: {value: 2, fit: [0.5, 8]}``
(the value is the start; without it the start is the middle of the bounds):
``fuzzyservo calibrate --controller`` then fits it in the closed-loop replay.
"""

from __future__ import annotations

from pathlib import Path

from fuzzyservo.atomic import write_text
from fuzzyservo.controllers.base import Controller
from fuzzyservo.controllers.classical import PI, PID_FORMS, PIDF, OpenLoop, P
from fuzzyservo.errors import ConfigError, excerpt
from fuzzyservo.io._yaml import Node, parse_yaml, read_yaml
from fuzzyservo.io.fuzzy import KEYS, fuzzy_from_node

_COMMON = ("name", "kind", "description", "source", "output_limits")
_KINDS = {
    "P": ("gain",),
    "PI": ("kp", "ki"),
    "PIDF": ("kp", "ki", "kd", "filter_time", "form"),
    "open_loop": ("gain",),
    "fuzzy": KEYS,
    "fmu": ("file", "reference", "measurement", "command", "sample_time"),
}


def load_controller(path: str | Path) -> Controller:
    """Read and validate a controller file (YAML, a MATLAB ``.fis`` or an FCL file, or a
    shipped controller's name such as ``"p_k10"``); raise :class:`ConfigError` naming file
    and key."""
    from fuzzyservo.io.paths import shipped_or_path

    path = shipped_or_path(path, "studies/controllers", "controller")
    file = str(path)
    suffix = Path(file).suffix.lower()
    if suffix in (".fis", ".fcl"):
        from fuzzyservo.io.fuzzy_files import controller_from_fcl, controller_from_fis
        from fuzzyservo.io.paths import name_problem

        controller = (controller_from_fis if suffix == ".fis" else controller_from_fcl)(path)
        if name_problem(controller.name):
            raise ConfigError(name_problem(controller.name), file=file, key="[System] Name")
        return controller
    return controller_from_data(read_yaml(path), file)


def controller_from_data(data: dict, file: str) -> Controller:
    """Build a controller from the mapping a controller file holds (``file`` names it in errors)."""
    root = Node(data, file)
    if not root.has("kind"):
        root.fail(f"missing key 'kind'; add one of {sorted(_KINDS)}")
    kind = root.str("kind")
    if kind not in _KINDS:
        root.fail(
            f"unknown controller kind {excerpt(kind)}; choose one of {sorted(_KINDS)}", key="kind"
        )
    for key in root.data:
        other = [k for k, keys in _KINDS.items() if key in keys and key not in _KINDS[kind]]
        if other:
            root.fail(f"is a key of kind {other[0]}, not {kind}; remove it or change kind", key=key)
    root.only((*_COMMON, *_KINDS[kind]))
    name = root.name("name", default=Path(file).stem)
    limits = {}
    if root.has("output_limits"):
        lo_hi = root.numbers("output_limits")
        if len(lo_hi) != 2 or not lo_hi[0] < lo_hi[1]:
            root.fail(
                f"must be [u_min, u_max] with u_min < u_max (V), got {excerpt(lo_hi)}; "
                "write it like [-10, 10]",
                key="output_limits",
            )
        limits = {"u_min": lo_hi[0], "u_max": lo_hi[1]}
    if kind == "fuzzy":
        return fuzzy_from_node(root, name, limits, root.str("description", default=""))
    if kind == "fmu":
        return _fmu_controller(root, name, limits)
    # read every number first: ConfigErrors from the reads keep their own key
    unknowns: list[tuple[str, float, float]] = []
    if kind == "P":
        make, gains = P, {"gain": _gain(root, "gain", unknowns)}
    elif kind == "PI":
        make, gains = PI, {"kp": _gain(root, "kp", unknowns), "ki": _gain(root, "ki", unknowns)}
    elif kind == "PIDF":
        make = PIDF
        gains = {k: _gain(root, k, unknowns, default=0.0) for k in ("kp", "ki", "kd")}
        gains["filter_time_s"] = _gain(root, "filter_time", unknowns, default=0.0)
        form = root.str("form", default="parallel")
        if form not in PID_FORMS:
            root.fail(
                f"unknown PID form {excerpt(form)}; choose one of {list(PID_FORMS)}", key="form"
            )
        gains["form"] = form
        if not any(gains[k] or any(u[0] == k for u in unknowns) for k in ("kp", "ki", "kd")):
            root.fail("kp, ki and kd are all zero; give at least one gain", key="kp")
    else:
        make, gains = OpenLoop, {"gain": root.number("gain", default=1.0)}
    try:
        return make(**gains, name=name, unknowns=tuple(unknowns), **limits)
    except ValueError as exc:
        raise ConfigError(f"{exc}; fix the controller file", file=file) from None


def _fmu_controller(root: Node, name: str, limits: dict[str, float]) -> Controller:
    """``kind: fmu``: a co-simulation FMU (``file``, relative to the controller file) and
    the names of its reference and measurement inputs and its command output."""
    from fuzzyservo.controllers.fmu import FmuController

    if not root.has("file"):
        root.fail("missing key 'file'; give the FMU, e.g. file: controller.fmu")
    path = Path(root.str("file"))
    if not path.is_absolute():
        path = Path(root.file).parent / path
    if path.suffix.lower() != ".fmu" or not path.is_file():
        root.fail(f"{path} is not an FMU file (.fmu) that exists; check the path", key="file")
    period = root.number("sample_time", default=None) if root.has("sample_time") else None
    names = {k: root.str(k, default=k) for k in ("reference", "measurement", "command")}
    try:
        controller = FmuController(file=str(path), sample_time_s=period, name=name,
                                   description=root.str("description", default=""),
                                   **names, **limits)  # fmt: skip
        controller.start(period or 0.01).close()  # the FMU opens and its variables match
    except ValueError as exc:
        raise ConfigError(f"{exc}", file=root.file, key="file") from None
    return controller


def _gain(
    root: Node, key: str, unknowns: list[tuple[str, float, float]], default: float | None = None
) -> float:
    """A gain: a plain number, or ``{value: x, fit: [lo, hi]}`` declaring it unknown (the
    field name and bounds go to ``unknowns``)."""
    field = "filter_time_s" if key == "filter_time" else key
    raw = root.data.get(key)
    if not (isinstance(raw, dict) and "fit" in raw):
        value = root.number(key, default=default)
        if field == "filter_time_s" and value < 0:
            root.fail(
                f"must be >= 0 s, got {value}; give the derivative filter's time constant", key=key
            )
        return value
    node = Node(raw, root.file, root.path(key))
    node.only(("value", "fit", "source", "note"))
    bounds = node.numbers("fit")
    if len(bounds) != 2 or not bounds[0] < bounds[1]:
        node.fail(
            f"must be [lower, upper] with lower < upper, got {excerpt(bounds)}; give the range the "
            "gain may take",
            key="fit",
        )
    lo, hi = bounds
    if field == "filter_time_s" and lo < 0:
        node.fail(f"lower bound {lo} < 0; a filter time constant is >= 0 s", key="fit")
    value = node.number("value", default=0.5 * (lo + hi))
    if not lo <= value <= hi:
        node.fail(
            f"value {value:g} lies outside its fit bounds [{lo:g}, {hi:g}]; widen the bounds "
            "or move the value",
            key="fit",
        )
    unknowns.append((field, float(lo), float(hi)))
    return value


def read_controller_data(path: str | Path) -> dict:
    """The mapping of a controller file; a ``.fis`` becomes explicit terms and rule lines."""
    if Path(path).suffix.lower() == ".fis":
        from fuzzyservo.io.fuzzy import fuzzy_controller_data
        from fuzzyservo.io.fuzzy_files import controller_from_fis

        return fuzzy_controller_data(controller_from_fis(path))
    return read_yaml(path)


def controller_data_from_text(text: str, filename: str) -> dict:
    """The mapping of a controller file's text (an upload): ``.yaml``/``.yml`` or ``.fis``."""
    suffix = Path(filename).suffix.lower()
    if suffix == ".fis":
        from fuzzyservo.controllers.fuzzy.fis import parse_fis_controller
        from fuzzyservo.io.fuzzy import fuzzy_controller_data

        controller = parse_fis_controller(text, filename)
        return fuzzy_controller_data(controller.renamed(controller.system.name))
    if suffix in (".yaml", ".yml"):
        return parse_yaml(text, filename)
    raise ConfigError("a controller file ends in .yaml or .fis", file=filename)


def controller_yaml(data: dict) -> str:
    """A controller mapping as the YAML text :func:`write_controller_file` writes."""
    import yaml

    return yaml.safe_dump(
        _plain(data, ""), sort_keys=False, allow_unicode=True, default_flow_style=None, width=88
    )


_KIND_OF = {OpenLoop: "open_loop", P: "P", PI: "PI", PIDF: "PIDF"}


def controller_data(controller: Controller) -> dict:
    """The mapping of a controller file that :func:`controller_from_data` turns back into
    ``controller``: a fuzzy controller by its design when it has one (else term by term),
    a classical one by its gains (an unknown gain as ``{value, fit}``)."""
    from fuzzyservo.controllers.fuzzy.controller import FuzzyController
    from fuzzyservo.io.fuzzy import design_data, fuzzy_controller_data

    if isinstance(controller, FuzzyController):
        if controller.design is not None:
            return design_data(controller.design)
        return fuzzy_controller_data(controller)
    kind = _KIND_OF.get(type(controller))
    if kind is None:
        raise ValueError(f"no controller file holds a {type(controller).__name__}")
    data: dict = {"name": controller.name, "kind": kind}
    if isinstance(controller, PIDF):
        data["form"] = controller.form
    bounds = controller.gain_bounds()
    tunable = {"gain": "gain"} if kind == "open_loop" else controller.TUNABLE
    for key, field in tunable.items():
        value = getattr(controller, field)
        data[key] = {"value": value, "fit": list(bounds[field])} if field in bounds else value
    if controller.has_limits:
        data["output_limits"] = [controller.u_min, controller.u_max]
    return data


def write_controller_file(data: dict, path: str | Path) -> Path:
    """Write a controller mapping as a controller file (UTF-8 YAML, keys in their order).

    Numbers are written as plain YAML numbers (numpy scalars become Python ones, whose
    ``repr`` round-trips, so the file rebuilds the same controller bit for bit); a
    non-finite number is a ``ValueError`` naming its key, since no controller file takes one.
    """
    return write_text(path, controller_yaml(data))


def _plain(value, key: str):
    """``value`` with Python numbers, lists and dicts only (what ``yaml.safe_dump`` writes)."""
    import math
    import numbers

    if isinstance(value, dict):
        return {str(k): _plain(v, f"{key}.{k}" if key else str(k)) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v, f"{key}[{i}]") for i, v in enumerate(value)]
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return value
    if isinstance(value, numbers.Integral):
        return int(value)
    if isinstance(value, numbers.Real):
        number = float(value)
        if not math.isfinite(number):
            raise ValueError(
                f"{key or 'value'}: a controller file takes finite numbers only, got {number!r}; "
                "replace it before writing"
            )
        return number
    raise ValueError(
        f"{key or 'value'}: cannot write {type(value).__name__} {excerpt(value)} to a controller "
        "file; give numbers, text, lists or mappings"
    )
