"""``fuzzyservo reproduce``'s files: the seeds' observations (``data/reproduction.yaml``)
read with the shipped rigs, controllers and the rig files' assumptions
(:func:`load_reproduction`; :mod:`fuzzyservo.analysis.reproduction` runs them), and the
result written as JSON and Markdown.

Layout of the observation file::

    observations:
      - id: s002_onset_gain
        seed: "002"
        figure: "§5"
        quantity: P gain at which the bench starts to oscillate
        unit: "1"                  # the row's unit; measures are SI, shown in this unit
        seed_value: 15             # with tolerance; or bounds: [lower, upper] (null: open)
        tolerance: 3
        measure: onset_gain        # analysis.reproduction.MEASURES
        metric: rise_time_s        # for metric, reading, reduction, ratio
        runs: [{rig: dinca_cylinder, controller: p_k10, scenario: pulses, params: {}}]
        options: {from_s: 5, to_s: 7}
        reason: the physical cause, when the row differs (and the run that shows it)
        note: what the row depends on (an assumption it matches only at)
    rigs:                          # variants of a shipped rig: components replaced, effects added
      hydroprax_network: {rig: hydroprax_pdcv, components: {valve: {type: ..., parameters: ...}}}
      hydroprax_orifice: {rig: ..., components: ..., effects: {entrained_air: {air_fraction: ...}}}
    assumptions:                   # rig values the rig file marks `source: assumption`
      - {id: ..., rig: dinca_cylinder, target: controller.io_delay, unit: ms,
         values: [0, 10, 20, 30], rows: [s002_onset_gain, ...]}
    explanations:
      - {id: ..., seed: "002", gap: ..., rows: [...], conclusion: ...,
         variants: [{label: ..., changes: [{target: effects.coulomb_friction.force,
                                            value: 20, unit: N}]}]}
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from fuzzyservo.analysis.reproduction import (
    Assumption,
    Change,
    Explanation,
    Observation,
    Reproduction,
    ReproductionResult,
    ReproductionSpec,
    Run,
    Variant,
)
from fuzzyservo.atomic import write_text
from fuzzyservo.errors import ConfigError, excerpt
from fuzzyservo.io._yaml import Node, read_yaml
from fuzzyservo.io.controllers import load_controller
from fuzzyservo.io.jsonfile import write_json
from fuzzyservo.io.paths import data_root, package_data
from fuzzyservo.io.rigs import load_rig, rig_from_data
from fuzzyservo.rig import Rig

SPEC_FILE = "reproduction.yaml"
ASSUMPTION = "assumption"


def load_reproduction_spec(path: str | Path | None = None) -> ReproductionSpec:
    """The observation file (default: the shipped ``data/reproduction.yaml``), with each
    assumption's rig value and reason read from its rig file."""
    return _load_spec(path)[0]


def _load_spec(
    path: str | Path | None,
) -> tuple[ReproductionSpec, dict[str, Rig], dict[str, tuple[dict[str, Any], str]]]:
    """The spec, its rigs by name (shipped rigs, and the variants of ``rigs:``) and the
    variants' rig data with the file each comes from."""
    path = Path(path) if path is not None else package_data() / SPEC_FILE
    root = Node(read_yaml(path), str(path))
    root.only(("observations", "rigs", "assumptions", "explanations"))
    variants = {name: _variant_data(node) for name, node in root.children("rigs").items()}
    observations = tuple(_observation(n) for n in _items(root, "observations"))
    assumptions = tuple(_assumption(n, variants) for n in _items(root, "assumptions"))
    explanations = tuple(_explanation(n) for n in _items(root, "explanations"))
    try:
        spec = ReproductionSpec(observations, assumptions, explanations)
    except ValueError as exc:
        raise ConfigError(f"{exc}; fix the file", file=str(path)) from None
    rigs = {name: rig_from_data(*variants[name]) if name in variants else _shipped_rig(name)
            for name in spec.rigs()}  # fmt: skip
    return spec, rigs, variants


def _shipped_rig(name: str) -> Rig:
    return load_rig(data_root() / "rigs" / f"{name}.yaml")


def _variant_data(node: Node) -> tuple[dict[str, Any], str]:
    """A shipped rig's data with some of its components replaced (seed 003's other
    valves) and effects declared (``effects:``, as in a rig file), and the rig file."""
    node.only(("rig", "components", "effects"))
    path = data_root() / "rigs" / f"{node.str('rig')}.yaml"
    data = read_yaml(path)
    for inst, comp in node.child("components", default={}).data.items():
        if inst not in data["plant"]["components"]:
            node.fail(f"{path.name} has no component {excerpt(inst)}", key="components")
        data["plant"]["components"][inst] = comp
    effects = node.child("effects", default={}).data
    if effects:
        data["effects"] = {**(data.get("effects") or {}), **effects}
    data["name"] = node.key.rsplit(".", 1)[-1]
    return data, str(path)


def load_reproduction(spec: str | Path | None = None) -> Reproduction:
    """What ``fuzzyservo reproduce`` runs: the observation file ``spec`` (default: the
    shipped one), its shipped rigs and variants, its controllers and each rig's other
    assumptions; ``.run(seeds)`` measures them
    (:meth:`~fuzzyservo.analysis.reproduction.Reproduction.run`)."""
    loaded, rigs, variants = _load_spec(spec)
    controllers = {
        name: load_controller(data_root() / "studies" / "controllers" / f"{name}.yaml")
        for name in loaded.controllers()
    }
    covered = {(a.rig, _file_key(a.target)) for a in loaded.assumptions}
    covered |= {
        (a.rig, "actuator.lower") for a in loaded.assumptions if a.target == "actuator.upper"
    }
    others = {
        name: [e for e in _own_assumptions(name, variants) if (name, e["key"]) not in covered]
        for name in sorted(rigs)
        if name in variants or (data_root() / "rigs" / f"{name}.yaml").is_file()
    }
    return Reproduction(loaded, rigs, controllers, others)


def write_reproduction(
    result: ReproductionResult,
    *,
    json_path: str | Path | None = None,
    markdown_path: str | Path | None = None,
) -> list[Path]:
    """Write the result as JSON and/or Markdown (creating the folders); the paths written."""
    written = []
    if json_path:
        written.append(write_json(json_path, result))
    if markdown_path:
        written.append(write_text(markdown_path, result.to_markdown()))
    return written


def rig_assumptions(rig_name: str, data: dict[str, Any] | None = None) -> list[dict[str, Any]]:
    """Every value a shipped rig file marks ``source: assumption``: key, value, unit, note
    (``data``: a variant's rig data, read instead of the file)."""
    found: list[dict[str, Any]] = []

    def walk(data: Any, key: str) -> None:
        if isinstance(data, dict) and data.get("source") == ASSUMPTION and "value" in data:
            found.append({"key": key, "value": _number(data["value"]), "unit": data.get("unit", ""),
                          "note": " ".join(str(data.get("note", "")).split())})  # fmt: skip
        elif isinstance(data, dict):
            for k, v in data.items():
                walk(v, f"{key}.{k}" if key else str(k))

    walk(data if data is not None else read_yaml(data_root() / "rigs" / f"{rig_name}.yaml"), "")
    return found


# --------------------------------------------------------------------------- parsing
def _number(value: Any) -> float | str:
    """A rig-file value as a number (YAML 1.1 reads 1.4e9 as text), else as written."""
    try:
        return float(value)
    except (TypeError, ValueError):
        return str(value)


def _items(root: Node, key: str) -> list[Node]:
    raw = root.data.get(key, [])
    if not isinstance(raw, list):
        root.fail(
            f"must be a list of mappings (lines starting with '- '), got {excerpt(raw)}", key=key
        )
    return [Node(item, root.file, f"{key}[{i}]") for i, item in enumerate(raw)]


def _scale(node: Node, unit: str) -> float:
    return node.unit(unit).factor


def _run(node: Node) -> Run:
    node.only(("rig", "controller", "scenario", "params"))
    params = node.child("params", default={})
    return Run(
        node.str("rig"),
        node.str("controller"),
        node.str("scenario"),
        tuple((k, params.number(k)) for k in params.data),
    )


def _bounds(node: Node) -> tuple[float | None, float | None] | None:
    if "bounds" not in node.data:
        return None
    raw = node.data["bounds"]
    if not (isinstance(raw, list) and len(raw) == 2):
        node.fail(
            f"must be [lower, upper] (null for an open end), got {excerpt(raw)}", key="bounds"
        )
    return tuple(None if v is None else node._as_number(v, "bounds") for v in raw)  # type: ignore[return-value]


def _observation(node: Node) -> Observation:
    node.only(("id", "seed", "figure", "quantity", "unit", "seed_value", "tolerance", "bounds",
               "measure", "metric", "runs", "options", "reason", "note"))  # fmt: skip
    unit = node.str("unit")
    options = node.child("options", default={})
    runs = node.data.get("runs", [])
    if not isinstance(runs, list) or not runs:
        node.fail("must be a list of runs ({rig, controller, scenario})", key="runs")
    try:
        return Observation(
            id=node.str("id"),
            seed=str(node.require("seed")),
            figure=node.str("figure"),
            quantity=node.str("quantity"),
            unit=unit,
            measure=node.str("measure"),
            runs=tuple(_run(Node(r, node.file, node.path(f"runs[{i}]"))) for i, r in enumerate(runs)),
            metric=node.str("metric", default=""),
            scale=_scale(node, unit),
            seed_value=node.number("seed_value") if node.data.get("seed_value") is not None else None,
            tolerance=node.number("tolerance") if "tolerance" in node.data else None,
            bounds=_bounds(node),
            options=tuple((k, options.number(k)) for k in options.data),
            reason=" ".join(node.str("reason", default="").split()),
            note=" ".join(node.str("note", default="").split()),
        )  # fmt: skip
    except ValueError as exc:
        node.fail(f"{exc}; fix the entry")


def _change(node: Node) -> Change:
    node.only(("target", "value", "unit"))
    unit = node.str("unit", default="1")
    try:
        return Change(node.str("target"), node.number("value") * _scale(node, unit))
    except ValueError as exc:
        node.fail(str(exc), key="target")


def _assumption(node: Node, variants: dict[str, tuple[dict[str, Any], str]]) -> Assumption:
    node.only(("id", "rig", "target", "unit", "values", "rows"))
    rig, target, unit = node.str("rig"), node.str("target"), node.str("unit")
    scale = _scale(node, unit)
    declared = {a["key"]: a for a in rig_assumptions(rig, _data(variants, rig))}
    file_key = _file_key(target)
    if file_key not in declared:
        node.fail(
            f"{rig}.yaml does not mark {file_key} as an assumption; give it "
            "'source: assumption' and a note saying how it was chosen",
            key="target",
        )
    entry = declared[file_key]
    value = float(entry["value"]) * _scale(node, str(entry["unit"] or unit))
    return Assumption(
        id=node.str("id"), rig=rig, target=target, unit=unit, scale=scale,
        values=tuple(v * scale for v in node.numbers("values")),
        rows=tuple(str(r) for r in node.require("rows")), value=value, reason=entry["note"],
    )  # fmt: skip


def _own_assumptions(
    name: str, variants: dict[str, tuple[dict[str, Any], str]]
) -> list[dict[str, Any]]:
    """A rig's assumptions; a variant's only those its shipped rig does not already list."""
    if name not in variants:
        return rig_assumptions(name)
    data, file = variants[name]
    listed = {e["key"] for e in rig_assumptions(Path(file).stem)}
    return [e for e in rig_assumptions(name, data) if e["key"] not in listed]


def _data(variants: dict[str, tuple[dict[str, Any], str]], name: str) -> dict[str, Any] | None:
    """A variant's rig data, or None for a shipped rig (read from its file)."""
    return variants[name][0] if name in variants else None


def _file_key(target: str) -> str:
    """The rig-file key of a change target (``plant.valve.x`` -> ``plant.components.valve.parameters.x``)."""
    head, _, rest = target.partition(".")
    if head == "plant":
        inst, _, key = rest.partition(".")
        return f"plant.components.{inst}.parameters.{key}"
    return target


def _explanation(node: Node) -> Explanation:
    node.only(("id", "seed", "gap", "rows", "variants", "conclusion"))
    variants = []
    for i, raw in enumerate(node.require("variants")):
        v = Node(raw, node.file, node.path(f"variants[{i}]"))
        v.only(("label", "changes"))
        changes = [Node(c, v.file, v.path(f"changes[{j}]")) for j, c in
                   enumerate(v.data.get("changes", []))]  # fmt: skip
        variants.append(Variant(v.str("label"), tuple(_change(c) for c in changes)))
    return Explanation(
        id=node.str("id"), seed=str(node.require("seed")), gap=" ".join(node.str("gap").split()),
        rows=tuple(str(r) for r in node.require("rows")), variants=tuple(variants),
        conclusion=" ".join(node.str("conclusion", default="").split()),
    )  # fmt: skip
