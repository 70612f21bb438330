"""Study files (YAML) to :class:`~fuzzyservo.tuning.spec.Study`, parsed once.

The rig, the controller template, the baseline and the warm-start controllers are read
here; the study then holds them as typed objects (nothing in ``tuning`` reads a file).
Each searched parameter keeps where it was declared (``file: parameters.<name>``) for
the messages of a trial whose sampled numbers make no controller.

name: dinca_flc
description: ...
rig: dinca_cylinder                 # a file (relative to this one) or a name under rigs/
scenarios: [pulses, steps]
controller: controllers/flc1_translated.yaml   # the template
baseline: controllers/p_k10.yaml               # default: p_k10
parameters:
  input.reshape: {low: 0.5, high: 4, log: true}
  gains.output: {low: 0.5, high: 3}
  output.translate: {low: 0, high: 0.5}
objective:
  weights: {settling_time_s: 1, sse_abs: 1000, saturation_time_s: 1}   # or metric: itae
  normalize: none                  # or baseline
  # pareto: [settling_time_s, saturation_time_s, sse_abs]
aggregate: worst                   # over scenarios: worst | mean
constraints: ["overshoot_pct <= 5"]
sampler: auto                      # auto (docs/samplers.md) | tpe | cmaes | nsga2 | gp | qmc | random
seed: 1
trials: 300
timeout_s: 600
storage: null                      # default: SQLite in the output folder
workers: 1                         # local worker processes (--workers overrides)
batch_size: 4                      # trials in flight; the result depends on it, not on workers
uncertainty:                       # optional: tune on sampled plants (tuning/uncertainty/sets.py)
  samples: 8                       # the same 8 plants and noise realisations for every trial
  seed: 1
  noise: true                      # a sensor-noise realisation per sample
  aggregate: worst                 # over the samples: worst | mean | cvar (with alpha: 0.25)
  margin_scenario: steps           # where gain_margin/delay_margin_s constraints are checked
  parameters:                      # rig-file keys, effect.parameter (SI), or io_delay
    bulk_modulus: {uniform: [12000, 18000], unit: bar}
    viscous_friction: {log-uniform: [2, 20], unit: N*s/m}
    bias_current: {normal: [2.83, 0.05], unit: mA}      # mean, std; cut at ±3 std
    supply_pressure: {interval: [65, 75], unit: bar}    # a fitted interval: uniform in it
  calibrated: my_rig_calibrated.yaml   # optional: every fitted value of a calibrated rig file,
                                       # uniform in its 95 % interval (parameters: above win)
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from fuzzyservo.controllers.base import parameter_path
from fuzzyservo.errors import ConfigError, did_you_mean, excerpt
from fuzzyservo.io._yaml import Node, read_yaml
from fuzzyservo.io.controllers import load_controller
from fuzzyservo.io.paths import find_file, shipped_or_path
from fuzzyservo.io.rigs import load_rig
from fuzzyservo.limits import plant_samples_problem
from fuzzyservo.metrics import METRIC_NAMES
from fuzzyservo.tuning.spec import (
    AGGREGATES,
    AUTO,
    BATCH_SIZE,
    MARGIN_METRICS,
    SAMPLERS,
    Constraint,
    Objective,
    Parameter,
    Study,
)

_TOP = (
    "name", "description", "source", "rig", "scenarios", "controller", "baseline", "parameters",
    "objective", "aggregate", "constraints", "sampler", "seed", "trials", "timeout_s", "storage", "penalty",
    "workers", "uncertainty", "patience", "warm_start", "batch_size",
)  # fmt: skip
DEFAULT_BASELINE = "p_k10"


def load_study(path: str | Path) -> Study:
    """Read and validate a study file (a path, or a shipped study's name such as
    ``"dinca_flc"``, as :func:`~fuzzyservo.io.rigs.load_rig` takes a rig's); every
    problem is one :class:`ConfigError` line."""
    path = shipped_or_path(path, "studies", "study")
    file = str(path)
    root = Node(read_yaml(path), file)
    root.only(_TOP)
    here = Path(file)
    files = {}
    for key, folder, default in (
        ("rig", "rigs", None),
        ("controller", "studies/controllers", None),
        ("baseline", "studies/controllers", DEFAULT_BASELINE),
    ):
        name = root.str(key, default=default)
        try:
            files[key] = str(find_file(name, folder, key, relative_to=here))
        except ConfigError as exc:
            root.fail(f"{exc.detail} (looked beside the study and under {folder}/)", key=key)
    scenarios = root.data.get("scenarios")
    if isinstance(scenarios, str):
        scenarios = [scenarios]
    if (
        not isinstance(scenarios, list)
        or not scenarios
        or not all(isinstance(s, str) for s in scenarios)
    ):
        root.fail(
            "must be a list of scenario names of the rig, e.g. [pulses, steps]", key="scenarios"
        )

    params = []
    pnode = root.child("parameters")
    if not pnode.data:
        root.fail("no parameters to search; add at least one under 'parameters:'", key="parameters")
    for path_key, spec in pnode.data.items():
        node = Node(spec, file, pnode.path(str(path_key)))
        node.only(("low", "high", "log", "int"))
        log = node.flag("log", False, "search on a logarithmic scale")
        integer = node.flag("int", False, "whole numbers only")
        try:
            params.append(
                Parameter(str(path_key), node.number("low"), node.number("high"), log, integer,
                          where=f"{file}: {pnode.path(str(path_key))}")
            )  # fmt: skip
        except ValueError as exc:
            node.fail(str(exc).split(": ", 1)[-1])

    objective = _objective(root.child("objective"))
    constraints = []
    raw_constraints = root.data.get("constraints", [])
    if not isinstance(raw_constraints, list):
        root.fail("must be a list like ['overshoot_pct <= 5']", key="constraints")
    for n, text in enumerate(raw_constraints):
        try:
            c = Constraint.parse(str(text))
        except ValueError as exc:
            root.fail(str(exc), key=f"constraints[{n}]")
        if c.metric not in (*METRIC_NAMES, *MARGIN_METRICS):
            root.fail(
                f"unknown metric {excerpt(c.metric)}; "
                f"{did_you_mean(c.metric, (*METRIC_NAMES, *MARGIN_METRICS))}choose one of "
                f"{', '.join((*METRIC_NAMES, *MARGIN_METRICS))}",
                key=f"constraints[{n}]",
            )
        constraints.append(c)
    sampler = root.str("sampler", default=AUTO)
    if sampler not in (AUTO, *SAMPLERS):
        root.fail(
            f"unknown sampler {excerpt(sampler)}; choose one of {[AUTO, *SAMPLERS]}", key="sampler"
        )
    aggregate = root.str("aggregate", default="worst")
    if aggregate not in AGGREGATES:
        root.fail(
            f"unknown aggregate {excerpt(aggregate)}; choose one of {list(AGGREGATES)}",
            key="aggregate",
        )
    seed = root.data.get("seed", 0)
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int)):
        root.fail(f"must be an integer or null, got {excerpt(seed)}", key="seed")
    trials = root.number("trials", default=100)
    if trials < 1 or trials != int(trials):
        root.fail(f"must be a whole number >= 1, got {trials}", key="trials")
    timeout = root.data.get("timeout_s")
    if timeout is not None:
        timeout = root.number("timeout_s")
        if timeout <= 0:
            root.fail(f"must be > 0 s or null, got {timeout}", key="timeout_s")
    storage = root.data.get("storage")
    if storage is not None and not isinstance(storage, str):
        root.fail("must be a storage URL (e.g. postgresql://user@host/db) or null", key="storage")
    if storage is not None:
        _check_storage(root, storage)
    workers = root.number("workers", default=1)
    if workers < 1 or workers != int(workers):
        root.fail(f"must be a whole number >= 1, got {workers}", key="workers")
    batch_size = root.number("batch_size", default=BATCH_SIZE)
    if batch_size < 1 or batch_size != int(batch_size):
        root.fail(f"must be a whole number of trials >= 1, got {batch_size}", key="batch_size")
    patience = root.data.get("patience")
    if patience is not None and (
        isinstance(patience, bool) or not isinstance(patience, int) or patience < 1
    ):
        root.fail(
            f"must be a whole number of trials >= 1 or null, got {excerpt(patience)}",
            key="patience",
        )
    warm = root.data.get("warm_start", [])
    if isinstance(warm, str):
        warm = [warm]
    if not isinstance(warm, list) or not all(isinstance(w, str) for w in warm):
        root.fail("must list controller files or names, e.g. [flc2_reshaped]", key="warm_start")
    warm_files = []
    for n, name in enumerate(warm):
        try:
            warm_files.append(
                str(find_file(name, "studies/controllers", "warm_start", relative_to=here))
            )
        except ConfigError as exc:
            root.fail(f"{exc.detail} (looked beside the study and under studies/controllers/)",
                      key=f"warm_start[{n}]")  # fmt: skip
    rig = load_rig(files["rig"])
    uncertainty = None
    if root.has("uncertainty"):
        uncertainty = _uncertainty(root.child("uncertainty"), rig, tuple(scenarios))
    try:
        return Study(
            name=root.name("name", default=here.stem),
            description=root.str("description", default=""),
            rig=rig,
            scenarios=tuple(scenarios),
            template=load_controller(files["controller"]),
            baseline=load_controller(files["baseline"]),
            parameters=tuple(params),
            objective=objective,
            constraints=tuple(constraints),
            aggregate=aggregate,
            sampler=sampler,
            seed=seed,
            trials=int(trials),
            timeout_s=timeout,
            storage=storage,
            penalty=root.number("penalty", default=1.0e6),
            path=file,
            uncertainty=uncertainty,
            workers=int(workers),
            batch_size=int(batch_size),
            patience=patience,
            warm_start=tuple(warm_start_point(params, w) for w in warm_files),
        )
    except ConfigError:
        raise
    except ValueError as exc:
        raise ConfigError(str(exc), file=file) from None


def _number_at(data: Any, path: str) -> float | None:
    """The number a controller file writes at ``path``, or None when it writes none."""
    node = data
    for part in parameter_path(path):
        try:
            node = node[part]
        except (KeyError, IndexError, TypeError):
            return None
    if isinstance(node, bool) or not isinstance(node, int | float):
        return None
    return float(node)


def warm_start_point(parameters: tuple[Parameter, ...] | list[Parameter], file: str) -> dict:
    """The searched numbers a controller file writes (a warm start of the study): one it
    leaves at its default (e.g. no ``gains:``) is left to the sampler; a file with none
    of them is no warm start of this study (:class:`ConfigError`)."""
    data = read_yaml(file)
    point = {p.path: v for p in parameters if (v := _number_at(data, p.path)) is not None}
    if not point:
        raise ConfigError(
            f"has none of the searched numbers ({', '.join(p.path for p in parameters)}); "
            "warm-start from a controller of the study's template's kind",
            file=file,
        )
    return point


def with_warm_start(study: Study, files: list[str], patience: int | None = None) -> Study:
    """``study`` with the controller ``files`` (paths, or names under studies/controllers)
    as further warm-start points, and ``patience`` when given (the command line's)."""
    import dataclasses

    from fuzzyservo.io.paths import find_file

    if patience is not None and patience < 1:
        raise ConfigError(f"must be >= 1, got {patience}", argument="patience")
    paths = [str(find_file(f, "studies/controllers", "controller")) for f in files]
    points = tuple(warm_start_point(study.parameters, f) for f in paths)
    study = dataclasses.replace(study, warm_start=(*study.warm_start, *points))
    return study if patience is None else dataclasses.replace(study, patience=patience)


_DIST_KEYS = ("uniform", "normal", "log-uniform", "interval")


def _uncertainty(node: Node, rig: Any, scenarios: tuple[str, ...]) -> Any:
    """The ``uncertainty:`` section: distributions of rig parameters (in the file's units,
    turned into SI here), samples, seed, noise, aggregate over the samples."""
    from fuzzyservo.params import fields_by_key
    from fuzzyservo.tuning.uncertainty import (
        SAMPLE_AGGREGATES,
        Distribution,
        Uncertainty,
        sample_rig,
    )

    node.only(("samples", "seed", "noise", "aggregate", "alpha", "margin_scenario", "parameters",
               "calibrated"))  # fmt: skip
    by_key = fields_by_key(type(rig.params))
    dists = []
    pnode = node.child("parameters", default={})
    for target, raw in (pnode.data or {}).items():
        target = str(target)
        d = Node(raw, node.file, pnode.path(target))
        d.only((*_DIST_KEYS, "unit", "source", "note"))
        given = [k for k in _DIST_KEYS if d.has(k)]
        if len(given) != 1:
            d.fail(
                "give exactly one of uniform: [low, high], log-uniform: [low, high], "
                "normal: [mean, std] or interval: [low, high] (a fitted interval, drawn uniformly)"
            )
        pair = d.data[given[0]]
        if not (isinstance(pair, list) and len(pair) == 2):
            d.fail(f"must be a list of two numbers, got {excerpt(pair)}", key=given[0])
        nums = [_num(d, given[0], v) for v in pair]
        effect, field_name, si = _target(pnode, target, rig, by_key)
        if effect and d.has("unit"):
            d.fail("effect parameters are given in SI (N, m/s, ...); delete 'unit'", key="unit")
        unit = d.str("unit", default=si) if si else ""
        scale = d.convert(1.0, unit, si) if si else 1.0
        a, b = (v * scale for v in nums)
        if given[0] == "normal":
            b = abs(nums[1]) * scale
        kind = "uniform" if given[0] == "interval" else given[0]
        try:
            dists.append(Distribution(target, kind, a, b, field_name, effect, unit, scale))
        except ValueError as exc:
            d.fail(str(exc).split(": ", 1)[-1], key=given[0])
    if node.has("calibrated"):
        dists += _calibrated(node, rig, by_key, {d.target for d in dists})
    aggregate = node.str("aggregate", default="worst")
    if aggregate not in SAMPLE_AGGREGATES:
        node.fail(
            f"unknown {excerpt(aggregate)}; choose one of {list(SAMPLE_AGGREGATES)}",
            key="aggregate",
        )
    seed = node.data.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int):
        node.fail(f"must be an integer, got {excerpt(seed)}", key="seed")
    noise = node.flag("noise", True, "sensor noise on or off")
    samples = node.number("samples", default=8)
    if samples < 1 or samples != int(samples):
        node.fail(f"must be a whole number >= 1, got {samples}", key="samples")
    if plant_samples_problem(int(samples)):
        node.fail(plant_samples_problem(int(samples)), key="samples")
    margin_scenario = node.str("margin_scenario", default=scenarios[0])
    if margin_scenario not in rig.scenarios:
        node.fail(f"unknown scenario {excerpt(margin_scenario)}; "
                  f"{did_you_mean(margin_scenario, rig.scenarios)}the rig has {', '.join(rig.scenarios)}",
                  key="margin_scenario")  # fmt: skip
    try:
        u = Uncertainty(
            parameters=tuple(dists), samples=int(samples), seed=seed, noise=noise,
            aggregate=aggregate, alpha=node.number("alpha", default=0.25),
            margin_scenario=margin_scenario,
        )  # fmt: skip
    except ValueError as exc:
        node.fail(str(exc))
    from fuzzyservo.tuning.uncertainty import Sample

    for d in u.parameters:  # both ends of every range must make a valid rig
        for end in d.bounds:
            try:
                sample_rig(rig, (d,), Sample(0, {d.target: end}, 0))
            except (ValueError, KeyError) as exc:
                pnode.fail(
                    f"{d.describe()} reaches {end / (d.scale or 1):.4g} {d.unit}, no valid rig: "
                    f"{exc}; narrow the range",
                    key=d.target,
                )
    for sample in u.draws:  # every drawn plant must be a valid rig (e.g. a normal's tail)
        try:
            sample_rig(rig, u.parameters, sample)
        except (ValueError, KeyError) as exc:
            node.fail(f"{sample.describe(u.parameters)} is no valid rig: {exc}; narrow the range",
                      key="parameters")  # fmt: skip
    return u


def _target(pnode: Node, target: str, rig: Any, by_key: dict) -> tuple[str, str, str]:
    """What an uncertain ``target`` names: (effect, parameter field, SI unit); effect
    parameters are SI with no unit to convert (``""``)."""
    from fuzzyservo.components.effects import LIBRARY
    from fuzzyservo.tuning.uncertainty import IO_DELAY

    if target == IO_DELAY:
        return "", "", "s"
    if target in by_key:
        return "", by_key[target].name, by_key[target].metadata["unit"]
    if "." in target:
        effect, _, key = target.partition(".")
        if effect not in LIBRARY or key not in {p.key for p in LIBRARY[effect].params}:
            pnode.fail(
                f"unknown effect parameter {excerpt(target)}; effects: {', '.join(sorted(LIBRARY))}",
                key=target,
            )
        return effect, "", ""
    pnode.fail(
        f"unknown rig parameter {excerpt(target)}; give a plant parameter of "
        f"{rig.name} ({', '.join(sorted(by_key))}), effect.parameter or io_delay",
        key=target,
    )


def _calibrated(node: Node, rig: Any, by_key: dict, given: set[str]) -> list[Any]:
    """``calibrated: FILE``: each fitted value of a calibrated rig file (``interval: [lo,
    hi]`` beside it, as ``fuzzyservo calibrate`` writes) drawn uniformly in its interval;
    a parameter also listed under ``parameters:`` keeps that distribution."""
    from fuzzyservo.io.rigs import fitted_intervals
    from fuzzyservo.tuning.uncertainty import Distribution

    name = node.str("calibrated")
    try:
        path = find_file(name, "rigs", "calibrated", relative_to=Path(node.file))
    except ConfigError as exc:
        node.fail(f"{exc.detail} (looked beside the study and under rigs/)", key="calibrated")
    fitted = [f for f in fitted_intervals(path) if f.key not in given]
    if not fitted and not given:
        node.fail(
            f"{path} carries no fitted interval (no 'interval: [lo, hi]' entry); name the "
            "<rig>_calibrated.yaml that `fuzzyservo calibrate` wrote",
            key="calibrated",
        )
    where = Node({f.key: {} for f in fitted}, str(path), "")
    out = []
    for f in fitted:
        effect, field_name, si = _target(where, f.key, rig, by_key)
        unit = f.unit if si else ""
        scale = where.convert(1.0, unit or si, si, key=f.key) if si else 1.0
        origin = "fitted, at a bound: one-sided" if f.at_bound else "fitted"
        try:
            out.append(Distribution(f.key, "uniform", f.low * scale, f.high * scale, field_name,
                                    effect, unit, scale, origin))  # fmt: skip
        except ValueError as exc:
            where.fail(f"interval: {str(exc).split(': ', 1)[-1]}", key=f.key)
    return out


def _num(node: Node, key: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        node.fail(f"must hold two finite numbers, got {excerpt(value)}", key=key)
    return float(value)


def _check_storage(root: Node, storage: str) -> None:
    """A study file names a database server only: SQLite lives in the output folder
    (the default), or where ``--storage`` puts it; nothing else is written elsewhere."""
    from fuzzyservo.tuning.spec import storage_problem

    if storage.startswith("sqlite"):
        root.fail(
            f"{excerpt(storage)}: a study file does not choose where SQLite files go (the output "
            "folder holds it by default); delete the key, or pass --storage sqlite:///PATH",
            key="storage",
        )
    problem = storage_problem(storage)
    if problem:
        root.fail(problem, key="storage")


def _objective(node: Node) -> Objective:
    node.only(("metric", "weights", "pareto", "normalize"))
    given = [k for k in ("metric", "weights", "pareto") if node.has(k)]
    if len(given) != 1:
        node.fail(
            "give exactly one of 'metric' (one), 'weights' (a weighted sum) or 'pareto' (a front)"
        )
    normalize = node.str("normalize", default="none")
    if normalize not in ("none", "baseline"):
        node.fail(f"must be 'none' or 'baseline', got {excerpt(normalize)}", key="normalize")
    if node.has("metric"):
        weights = {node.str("metric"): 1.0}
        pareto: tuple[str, ...] = ()
    elif node.has("weights"):
        w = node.child("weights")
        weights = {str(k): w.number(str(k)) for k in w.data}
        if not weights:
            node.fail("is empty; give metric: weight pairs", key="weights")
        pareto = ()
    else:
        raw = node.data["pareto"]
        if not isinstance(raw, list) or len(raw) < 2:
            node.fail("must list two or more metrics", key="pareto")
        pareto = tuple(str(m) for m in raw)
        weights = {}
    for m in (*weights, *pareto):
        if m not in METRIC_NAMES:
            node.fail(f"unknown metric {excerpt(m)}; choose one of {', '.join(METRIC_NAMES)}")
    return Objective(weights=weights, pareto=pareto, normalize=normalize)
