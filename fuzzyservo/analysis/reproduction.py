"""The seeds' observations, run on the model: one row per observation, with its status.

An observation (declared in ``data/reproduction.yaml``, read by
:mod:`fuzzyservo.io.reproduction`) names what a seed reports (figure, quantity, value,
how well the figure can be read), which runs of the shipped rigs give the model's value
and how that value is measured from them (:data:`MEASURES`). Its status is
``reproduced`` when |model − seed| ≤ tolerance (or, for a seed that gives only a shape,
the model lies within the declared bounds), else ``differs`` with the declared reason.

Assumptions are rig values the seeds do not give (``source: assumption`` in the rig
file); each one declared with a range is varied over it and the rows it touches are
re-measured (how the conclusions move if the guess is wrong). Explanations are the runs
that test a stated cause of a difference (e.g. seed 002's dry friction and line
resistance): the same rows with the rig changed. Validity rows give each scenario's
lowest absolute chamber pressure (``simulation/validity.py``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from fuzzyservo.controllers.base import Controller
from fuzzyservo.errors import ConfigError
from fuzzyservo.metrics import heave_metrics, result_metrics
from fuzzyservo.params import fields_by_key
from fuzzyservo.results import Result
from fuzzyservo.rig import Rig
from fuzzyservo.simulation import SimResult, simulate
from fuzzyservo.simulation.validity import (
    ATMOSPHERE_PA,
    air_note,
    entrained_air,
    lowest_pressure,
)

STATUS_REPRODUCED = "reproduced"
STATUS_DIFFERS = "differs"
STATUS_VALIDITY = "validity"
SEEDS = ("000", "001", "002", "003")


@dataclass(frozen=True)
class Run:
    """One simulation: a shipped rig, controller and scenario; ``params``: plant
    parameters changed by field name (SI), e.g. seed 003's ``valve_model``."""

    rig: str
    controller: str
    scenario: str
    params: tuple[tuple[str, float], ...] = ()

    @property
    def label(self) -> str:
        extra = "".join(f", {k} = {v:g}" for k, v in self.params)
        return f"{self.rig} · {self.controller} · {self.scenario}{extra}"


_RIG_TARGETS = ("controller.io_delay", "actuator.upper", "actuator.gain")


@dataclass(frozen=True)
class Change:
    """A rig value changed, by its rig-file key (SI value): ``controller.io_delay``,
    ``actuator.upper`` (the limits become ±value), ``actuator.gain``,
    ``plant.<instance>.<parameter>``,
    ``effects.<effect>.<parameter>`` (declares the effect when the rig lacks it)."""

    target: str
    value: float

    def __post_init__(self) -> None:
        head = self.target.split(".", 1)[0]
        if self.target not in _RIG_TARGETS and head not in (
            "plant",
            "effects",
        ):
            raise ValueError(
                f"change {self.target!r}: the target must be one of {', '.join(_RIG_TARGETS)}, "
                "plant.<instance>.<parameter> or effects.<effect>.<parameter>"
            )


@dataclass(frozen=True)
class Observation:
    """What a seed reports and how the model's value is measured (:data:`MEASURES`).

    ``scale``: the measure's SI value per ``unit`` (1e-3 for mm). Either ``seed_value``
    and ``tolerance`` (reproduced when |model − seed| ≤ tolerance), or ``bounds``
    (lower, upper; None: open) for a seed that gives a shape or a limit.
    """

    id: str
    seed: str
    figure: str
    quantity: str
    unit: str
    measure: str
    runs: tuple[Run, ...]
    metric: str = ""
    scale: float = 1.0
    seed_value: float | None = None
    tolerance: float | None = None
    bounds: tuple[float | None, float | None] | None = None
    options: tuple[tuple[str, float], ...] = ()
    reason: str = ""
    note: str = ""

    def __post_init__(self) -> None:
        if self.seed not in SEEDS:
            raise ValueError(
                f"observation {self.id}: seed must be one of {SEEDS}, got {self.seed!r}"
            )
        if self.measure not in MEASURES:
            raise ValueError(
                f"observation {self.id}: unknown measure {self.measure!r}; "
                f"choose one of {sorted(MEASURES)}"
            )
        if len(self.runs) != MEASURES[self.measure].runs:
            raise ValueError(
                f"observation {self.id}: measure {self.measure!r} takes "
                f"{MEASURES[self.measure].runs} run(s), got {len(self.runs)}"
            )
        numeric = self.seed_value is not None and self.tolerance is not None
        if numeric == (self.bounds is not None):
            raise ValueError(
                f"observation {self.id}: give either seed_value and tolerance, or bounds "
                "(a shape or a limit), not both or neither"
            )
        if self.tolerance is not None and not self.tolerance >= 0:
            raise ValueError(f"observation {self.id}: tolerance must be >= 0, got {self.tolerance}")

    def option(self, name: str, default: float) -> float:
        return dict(self.options).get(name, default)

    def status(self, model: float) -> str:
        """``reproduced`` or ``differs`` for the model's value (in ``unit``)."""
        if not math.isfinite(model):
            return STATUS_DIFFERS
        if self.bounds is None:
            assert self.seed_value is not None and self.tolerance is not None
            close = abs(model - self.seed_value) <= self.tolerance * (1 + 1e-12)
            return STATUS_REPRODUCED if close else STATUS_DIFFERS
        lo, hi = self.bounds
        inside = (lo is None or model >= lo) and (hi is None or model <= hi)
        return STATUS_REPRODUCED if inside else STATUS_DIFFERS

    def tolerance_text(self) -> str:
        if self.bounds is None:
            return f"±{self.tolerance:g}"
        lo, hi = self.bounds
        if lo is None:
            return f"≤ {hi:g}"
        if hi is None:
            return f"≥ {lo:g}"
        return f"{lo:g} … {hi:g}"


@dataclass(frozen=True)
class Assumption:
    """A rig value no seed gives, its plausible range, and the observations it may move.

    ``value`` (the rig's, SI), ``scale`` (SI per ``unit``) and ``reason`` (the rig file's
    ``note``: how it was chosen) come from the rig file.
    """

    id: str
    rig: str
    target: str
    unit: str
    scale: float
    values: tuple[float, ...]
    rows: tuple[str, ...]
    value: float = math.nan
    reason: str = ""


@dataclass(frozen=True)
class Variant:
    """The rig of an explanation run: ``changes`` applied to every run of the rows."""

    label: str
    changes: tuple[Change, ...] = ()


@dataclass(frozen=True)
class Explanation:
    """Runs that test a stated cause of a difference: ``rows`` re-measured per variant."""

    id: str
    seed: str
    gap: str
    rows: tuple[str, ...]
    variants: tuple[Variant, ...]
    conclusion: str = ""


@dataclass(frozen=True)
class ReproductionSpec:
    observations: tuple[Observation, ...]
    assumptions: tuple[Assumption, ...] = ()
    explanations: tuple[Explanation, ...] = ()

    def __post_init__(self) -> None:
        ids = [o.id for o in self.observations]
        if len(set(ids)) != len(ids):
            raise ValueError(
                f"observation ids repeat: {sorted({i for i in ids if ids.count(i) > 1})}"
            )
        for owner, rows in [(a.id, a.rows) for a in self.assumptions] + [
            (e.id, e.rows) for e in self.explanations
        ]:
            unknown = set(rows) - set(ids)
            if unknown:
                raise ValueError(f"{owner}: unknown observation {sorted(unknown)[0]!r}")

    def observation(self, ident: str) -> Observation:
        return next(o for o in self.observations if o.id == ident)

    def rigs(self) -> set[str]:
        return {r.rig for o in self.observations for r in o.runs}

    def controllers(self) -> set[str]:
        return {r.controller for o in self.observations for r in o.runs}


# --------------------------------------------------------------------------- changes
def apply_changes(rig: Rig, changes: Iterable[Change]) -> Rig:
    """``rig`` with ``changes`` applied (effects declared with the values given)."""
    effects: dict[str, dict[str, float]] = {}
    plant: dict[str, float] = {}
    keyed = fields_by_key(type(rig.params))
    for change in changes:
        head, _, rest = change.target.partition(".")
        if change.target == "controller.io_delay":
            rig = dataclasses.replace(rig, io_delay_s=change.value)
        elif change.target == "actuator.upper":
            act = dataclasses.replace(rig.actuator, lower=-change.value, upper=change.value)
            rig = dataclasses.replace(rig, actuator=act)
        elif change.target == "actuator.gain":
            act = dataclasses.replace(rig.actuator, gain=change.value)
            rig = dataclasses.replace(rig, actuator=act)
        elif head == "effects":
            name, _, key = rest.partition(".")
            effects.setdefault(name, {})[key] = change.value
        else:
            if rest not in keyed:
                raise ValueError(f"{change.target}: {rig.name} has no plant parameter {rest!r}")
            plant[keyed[rest].name] = change.value
    if plant:
        rig = rig.with_params(**plant)
    for name, values in effects.items():
        declared = rig.effect_values(name) if name in rig.effects else {}
        rig = rig.with_effect(name, **{**declared, **values})
    return rig


# --------------------------------------------------------------------------- measures
class _Runner:
    """Simulates runs once (cached by rig variant, controller, scenario, parameters)."""

    def __init__(self, rigs: Mapping[str, Rig], controllers: Mapping[str, Controller]):
        self.rigs, self.controllers = rigs, controllers
        self._cache: dict[Any, SimResult] = {}

    def rig(self, run: Run, changes: tuple[Change, ...]) -> Rig:
        rig = apply_changes(self.rigs[run.rig], changes)
        return rig.with_params(**dict(run.params)) if run.params else rig

    def result(
        self, run: Run, changes: tuple[Change, ...], controller: Controller | None = None
    ) -> SimResult:
        ctl = controller or self.controllers[run.controller]
        key = (run, changes, ctl)
        if key not in self._cache:
            self._cache[key] = simulate(self.rig(run, changes), ctl, run.scenario)
        return self._cache[key]


@dataclass(frozen=True)
class Measure:
    runs: int
    doc: str
    fn: Callable[[Observation, _Runner, tuple[Change, ...]], float]


def _metric(result: SimResult, name: str) -> float:
    """A metric of ``result`` in SI (``*_pct`` metrics as fractions)."""
    if name == "compensation_pct":
        value = heave_metrics(result).get(name, math.nan)
    else:
        value = float(result_metrics(result).aggregate[name])
    return value / 100.0 if name.endswith("_pct") else value


def _value(obs: Observation, runner: _Runner, changes: tuple[Change, ...]) -> float:
    return _metric(runner.result(obs.runs[0], changes), obs.metric)


def _reading(obs: Observation, runner: _Runner, changes: tuple[Change, ...]) -> float:
    slope = runner.rig(obs.runs[0], changes).feedback.slope
    return slope * _value(obs, runner, changes)


def _reduction(obs: Observation, runner: _Runner, changes: tuple[Change, ...]) -> float:
    base = _metric(runner.result(obs.runs[0], changes), obs.metric)
    new = _metric(runner.result(obs.runs[1], changes), obs.metric)
    return 1.0 - new / base


def _ratio(obs: Observation, runner: _Runner, changes: tuple[Change, ...]) -> float:
    a = _metric(runner.result(obs.runs[0], changes), obs.metric)
    b = _metric(runner.result(obs.runs[1], changes), obs.metric)
    return a / b if b else math.inf


def _saturated_fraction(obs: Observation, runner: _Runner, changes: tuple[Change, ...]) -> float:
    steps = result_metrics(runner.result(obs.runs[0], changes)).steps
    return min(s.saturation_time_s / s.settling_time_s for s in steps)


def _force_imbalance(obs: Observation, runner: _Runner, changes: tuple[Change, ...]) -> float:
    """What the chamber pressures push beyond the no-friction equilibrium p_a·A_a = p_b·A_b
    (seed 002 eq. 20) [N]: the force some unmodelled resistance (dry friction) holds."""
    rig, r = runner.rig(obs.runs[0], changes), runner.result(obs.runs[0], changes)
    keyed = fields_by_key(type(rig.params))
    bore = getattr(rig.params, keyed["cylinder.piston_diameter"].name)
    rod = getattr(rig.params, keyed["cylinder.rod_diameter"].name)
    area_a, area_b = math.pi / 4 * bore**2, math.pi / 4 * (bore**2 - rod**2)
    keep = (r.t >= obs.option("from_s", 0.0)) & (r.t <= obs.option("to_s", r.t[-1]))
    push = r.signals["p_a"][keep] * area_a - r.signals["p_b"][keep] * area_b
    return abs(float(np.mean(push)))


def oscillates(result: SimResult, from_s: float, to_s: float, peak_to_peak: float) -> bool:
    """Does the output swing by more than ``peak_to_peak`` (SI) between the two times?"""
    keep = (result.t >= from_s) & (result.t <= to_s)
    return not (result.ok and float(np.ptp(result.output[keep])) <= peak_to_peak)


def _onset_gain(obs: Observation, runner: _Runner, changes: tuple[Change, ...]) -> float:
    """The smallest P gain at which the loop oscillates (bisection, to ``resolution``)."""
    template = runner.controllers[obs.runs[0].controller]
    lo, hi = obs.option("gain_low", 1.0), obs.option("gain_high", 100.0)
    window = (obs.option("from_s", 0.0), obs.option("to_s", math.inf))
    limit = obs.option("peak_to_peak", 1e-3)

    def swings(gain: float) -> bool:
        ctl = dataclasses.replace(template, gain=gain, name=f"{template.name}_K{gain:g}")
        return oscillates(runner.result(obs.runs[0], changes, ctl), *window, limit)

    if swings(lo) or not swings(hi):
        return math.nan
    while hi - lo > obs.option("resolution", 0.5):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if swings(mid) else (mid, hi)
    return hi


MEASURES: dict[str, Measure] = {
    "metric": Measure(1, "a metric of the run (``metric``: compare's names)", _value),
    "reading": Measure(1, "a metric of the run in the feedback sensor's volts", _reading),
    "reduction": Measure(2, "1 − metric(second)/metric(first)", _reduction),
    "ratio": Measure(2, "metric(first)/metric(second)", _ratio),
    "saturated_fraction": Measure(
        1, "least over the steps of saturated time / settling time", _saturated_fraction
    ),
    "force_imbalance": Measure(
        1,
        "|mean p_a·A_a − p_b·A_b| between ``from_s`` and ``to_s`` (cylinder at rest)",
        _force_imbalance,
    ),
    "onset_gain": Measure(1, "smallest P gain whose loop oscillates", _onset_gain),
}


def measure(obs: Observation, runner: _Runner, changes: tuple[Change, ...] = ()) -> float:
    """The model's value of ``obs`` (in its unit) on the rigs changed by ``changes``."""
    return MEASURES[obs.measure].fn(obs, runner, changes) / obs.scale


# --------------------------------------------------------------------------- result
@dataclass(frozen=True)
class ReproductionResult(Result):
    """Rows (observations and validity), assumptions with their sensitivity, explanations."""

    rows: list[dict[str, Any]]
    assumptions: list[dict[str, Any]] = field(default_factory=list)
    explanations: list[dict[str, Any]] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return {
            "rows": self.rows,
            "assumptions": self.assumptions,
            "explanations": self.explanations,
        }

    def counts(self) -> dict[str, int]:
        out: dict[str, int] = {}
        for row in self.rows:
            out[row["status"]] = out.get(row["status"], 0) + 1
        return out

    def text(self) -> str:
        lines = [
            f"{r['seed']}  {r['figure']:<10} {r['quantity'][:58]:<58} "
            f"{_num(r['seed_value']):>9} {_num(r['model_value']):>9} {r['unit']:<5} {r['status']}"
            for r in self.rows
        ]
        counts = ", ".join(f"{n} {s}" for s, n in self.counts().items())
        return "\n".join([*lines, f"{len(self.rows)} rows: {counts}"])

    def to_markdown(self) -> str:
        """The reproduction table, the assumptions' sensitivity and the explanation runs."""
        out = [
            "# Seed reproduction",
            "",
            "Generated by `fuzzyservo reproduce --markdown docs/reproduction.md` "
            "(`fuzzyservo.load_reproduction().run()`); do not edit by hand. Observations, tolerances and "
            "reasons are declared in `fuzzyservo/data/reproduction.yaml`; every model value "
            "is a run of the shipped rigs. Status `reproduced`: |model − seed| ≤ tolerance "
            "(or within the bounds where the seed gives a shape or a limit).",
            "",
            "| seed | figure | quantity | unit | seed | model | tolerance | status | reason |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for r in self.rows:
            why = r["reason"] or r.get("note", "")
            out.append(
                f"| {r['seed']} | {r['figure']} | {r['quantity']} | {r['unit']} | "
                f"{_num(r['seed_value'])} | {_num(r['model_value'])} | {r['tolerance_text']} | "
                f"{r['status']} | {_cell(why)} |"
            )
        if self.assumptions:
            out += ["", "## Assumptions and their sensitivity", ""]
            out.append(
                "Rig values no seed gives (`source: assumption` in the rig file or a variant "
                "of `reproduction.yaml`), each varied over a plausible range; the rows it "
                "moves, re-measured at each value, and the lowest absolute chamber pressure "
                "of their runs."
            )
        for a in (a for a in self.assumptions if a["sensitivity"]):
            out += ["", f"### {a['rig']}: `{a['target']}` = {_num(a['value'])} {a['unit']}", ""]
            out += [_cell(a["reason"]), ""]
            ids = list(a["sensitivity"][0]["rows"])
            out.append(f"| {a['unit']} | " + " | ".join(ids) + " | lowest p [bar abs] |")
            out.append("|---" * (len(ids) + 2) + "|")
            for s in a["sensitivity"]:
                mark = " (rig)" if s["value"] == a["value"] else ""
                cells = " | ".join(_num(s["rows"][i]) for i in ids)
                out.append(
                    f"| {_num(s['value'])}{mark} | {cells} | {_num(s['lowest_pressure_bar'])} |"
                )
        others = [a for a in self.assumptions if not a["sensitivity"]]
        if others:
            out += ["", "### The other assumptions of these rigs (no sensitivity run)", ""]
            out += ["| rig | key | value | unit | how it was chosen |", "|---|---|---|---|---|"]
            out += [f"| {a['rig']} | `{a['target']}` | {_num(a['value'])} | {a['unit']} | "
                    f"{_cell(a['reason'])} |" for a in others]  # fmt: skip
        if self.explanations:
            out += ["", "## Explanation runs", ""]
        for e in self.explanations:
            out += [f"### {e['id']} (seed {e['seed']}): {e['gap']}", ""]
            ids = list(e["variants"][0]["rows"])
            out.append("| rig variant | " + " | ".join(ids) + " |")
            out.append("|---" * (len(ids) + 1) + "|")
            for v in e["variants"]:
                cells = " | ".join(_num(v["rows"][i]) for i in ids)
                out.append(f"| {_cell(v['label'])} | {cells} |")
            if e["conclusion"]:
                out += ["", _cell(e["conclusion"])]
            out.append("")
        if self.rows:
            units = {r["id"]: f"{r['quantity']} [{r['unit']}]" for r in self.rows if "id" in r}
            used = sorted({i for a in self.assumptions for s in a["sensitivity"][:1] for i in s["rows"]}
                          | {i for e in self.explanations for i in e["variants"][0]["rows"]})  # fmt: skip
            if used:
                out += ["", "Row ids:", ""]
                out += [f"- `{i}`: {units[i]}" for i in used if i in units]
        return "\n".join(out).rstrip() + "\n"


def _num(value: float | str | None) -> str:
    if isinstance(value, str):
        return value
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "—"
    return f"{value:.3g}"


def _cell(text: str) -> str:
    return " ".join(str(text).split()).replace("|", "\\|")


# --------------------------------------------------------------------------- running
def _row(obs: Observation, model: float) -> dict[str, Any]:
    return {
        "id": obs.id,
        "seed": obs.seed,
        "figure": obs.figure,
        "quantity": obs.quantity,
        "unit": obs.unit,
        "seed_value": obs.seed_value,
        "model_value": model,
        "tolerance": obs.tolerance,
        "bounds": list(obs.bounds) if obs.bounds is not None else None,
        "tolerance_text": obs.tolerance_text(),
        "status": obs.status(model),
        "reason": obs.reason if obs.status(model) == STATUS_DIFFERS else "",
        "note": obs.note,
        "runs": [r.label for r in obs.runs],
    }


def _lowest(rig: Rig, result: SimResult) -> tuple[str, float, float]:
    """A run's lowest chamber pressure (name, gauge Pa, time), the boundary pressures a
    run holds constant (tank, ideal supply) left out."""
    moving = [n for n in rig.plant.pressures if np.ptp(result.signals[n]) > 0]
    return lowest_pressure(result.t, result.signals, moving)


def _lowest_bar(runner: _Runner, runs: Iterable[Run], changes: tuple[Change, ...]) -> float:
    """The lowest absolute chamber pressure [bar] over ``runs`` with ``changes``."""
    found = [_lowest(runner.rig(r, changes), runner.result(r, changes))[1] for r in runs]
    return (min(found, default=math.inf) + ATMOSPHERE_PA) / 1e5


def _validity_rows(runner: _Runner, chosen: Sequence[Observation]) -> list[dict[str, Any]]:
    """Each rig scenario's lowest absolute chamber pressure [bar] over its runs (the
    boundary pressures a run holds constant, tank and ideal supply, left out), with what
    entrained air would do there."""
    lowest: dict[tuple[str, str], tuple[float, str, float, Run, SimResult]] = {}
    for obs in chosen:
        for run in obs.runs:
            rig, result = runner.rig(run, ()), runner.result(run, ())
            name, p, at = _lowest(rig, result)
            key = (obs.seed, f"{run.rig} · {run.scenario}")
            if name and (key not in lowest or p < lowest[key][0]):
                lowest[key] = (p, name, at, run, result)
    rows = []
    for (seed, where), (p, name, at, run, result) in lowest.items():
        rig = runner.rig(run, ())
        oil = getattr(rig.params, fields_by_key(type(rig.params))["oil.bulk_modulus"].name)
        rows.append({
            "seed": seed, "figure": "validity",
            "quantity": f"lowest absolute chamber pressure, {where}",
            "unit": "bar", "seed_value": None, "model_value": (p + ATMOSPHERE_PA) / 1e5,
            "tolerance": None, "bounds": None, "tolerance_text": "—",
            "status": STATUS_VALIDITY,
            "reason": f"{name} at t = {at:.2f} s under {run.controller} (run status "
                      f"{result.status}); {air_note(p, oil, entrained_air(rig.params))}",
            "note": "", "runs": [run.label],
        })  # fmt: skip
    return rows


@dataclass(frozen=True)
class Reproduction:
    """What a reproduction runs on: the observation file's ``spec``, its ``rigs`` and
    ``controllers`` by the names it uses, and each rig's other ``source: assumption``
    values (``other_assumptions``); read by
    :func:`fuzzyservo.io.reproduction.load_reproduction`."""

    spec: ReproductionSpec
    rigs: Mapping[str, Rig]
    controllers: Mapping[str, Controller]
    other_assumptions: Mapping[str, Sequence[Mapping[str, Any]]] = field(default_factory=dict)

    def run(self, seeds: Sequence[str] | None = None, *, sensitivity: bool = True
            ) -> ReproductionResult:  # fmt: skip
        """Every observation of ``seeds`` ("000" … "003"; default all), with the
        assumptions' sensitivity and the explanation runs (``sensitivity=False``: the
        rows only): :func:`run_reproduction`."""
        try:
            return run_reproduction(self.spec, self.rigs, self.controllers, seeds,
                                    sensitivity=sensitivity,
                                    other_assumptions=self.other_assumptions)  # fmt: skip
        except ConfigError:
            raise
        except ValueError as exc:  # an unknown seed, a target the rig lacks: one line
            raise ConfigError(str(exc)) from None


def run_reproduction(
    spec: ReproductionSpec,
    rigs: Mapping[str, Rig],
    controllers: Mapping[str, Controller],
    seeds: Sequence[str] | None = None,
    *,
    sensitivity: bool = True,
    other_assumptions: Mapping[str, Sequence[Mapping[str, Any]]] | None = None,
) -> ReproductionResult:
    """Measure every observation of ``seeds`` (default: all) on ``rigs``/``controllers``
    (by the names the spec uses), then the assumptions' sensitivity and the explanation
    runs of those seeds (``sensitivity=False`` leaves both out). ``other_assumptions``:
    rig name -> the rig file's other ``source: assumption`` values ({key, value, unit,
    note}), listed without a sensitivity run."""
    wanted = set(seeds or SEEDS)
    unknown = wanted - set(SEEDS)
    if unknown:
        raise ValueError(f"unknown seed {sorted(unknown)[0]!r}; choose from {', '.join(SEEDS)}")
    runner = _Runner(rigs, controllers)
    chosen = [o for o in spec.observations if o.seed in wanted]
    rows = [_row(o, measure(o, runner)) for o in chosen]
    rows += _validity_rows(runner, chosen)
    assumptions, explanations = [], []
    ids = {o.id for o in chosen}
    for a in spec.assumptions if sensitivity else ():
        touched = [spec.observation(i) for i in a.rows if i in ids]
        if not touched:
            continue
        runs = [r for o in touched for r in o.runs]
        sens = [
            {"value": v / a.scale,
             "rows": {o.id: measure(o, runner, (Change(a.target, v),)) for o in touched},
             "lowest_pressure_bar": _lowest_bar(runner, runs, (Change(a.target, v),))}
            for v in a.values
        ]  # fmt: skip
        assumptions.append({
            "id": a.id, "rig": a.rig, "target": a.target, "unit": a.unit,
            "value": a.value / a.scale, "reason": a.reason,
            "range": [min(a.values) / a.scale, max(a.values) / a.scale], "sensitivity": sens,
        })  # fmt: skip
    for e in spec.explanations if sensitivity else ():
        if e.seed not in wanted:
            continue
        rows_of = [spec.observation(i) for i in e.rows]
        variants = [
            {"label": v.label, "rows": {o.id: measure(o, runner, v.changes) for o in rows_of}}
            for v in e.variants
        ]
        explanations.append(
            {"id": e.id, "seed": e.seed, "gap": e.gap, "variants": variants,
             "conclusion": e.conclusion}
        )  # fmt: skip
    used = {r.rig for o in chosen for r in o.runs}
    for rig_name, entries in (other_assumptions or {}).items() if sensitivity else ():
        assumptions += [
            {"id": f"{rig_name}:{e['key']}", "rig": rig_name, "target": e["key"],
             "unit": e["unit"], "value": e["value"], "reason": e["note"], "range": None,
             "sensitivity": []}
            for e in entries if rig_name in used
        ]  # fmt: skip
    return ReproductionResult(rows, assumptions, explanations)
