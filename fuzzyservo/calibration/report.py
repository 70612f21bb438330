"""Calibration outputs: the calibrated rig file, figures, a Markdown report and the summary JSON."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from fuzzyservo.calibration.decision import ALPHA
from fuzzyservo.calibration.identifiability import SWEEP_HZ, Separation
from fuzzyservo.calibration.joint import split_field
from fuzzyservo.calibration.null import REQUIRED, Assessment, Null
from fuzzyservo.calibration.replay import Replay
from fuzzyservo.calibration.residuals import (
    noise_floor,
    quantisation_step,
    signature_regression,
    whiteness,
)
from fuzzyservo.calibration.search import Candidate, Outcome, Round, fit_table
from fuzzyservo.calibration.signatures import mean_share, signatures
from fuzzyservo.calibration.significance import SIGNAL_FLOOR, SIZE_FLOOR
from fuzzyservo.components.effects import LIBRARY, owner
from fuzzyservo.display import display_scale, quantity_text
from fuzzyservo.metrics import format_value
from fuzzyservo.rig import Rig

if TYPE_CHECKING:
    from fuzzyservo.measured import Measured

ZOOM_S = 5.0  # the detail overlay shows this much of the held-out part [s]


def input_signal(replay: Replay) -> tuple[str, np.ndarray]:
    """The input the residual is cross-correlated with: the valve current or command if
    recorded, else the reference."""
    for name in ("i", "u", "ref"):
        if name in replay.data.signals:
            return name, replay.recorded(name)
    return "ref", np.zeros(replay.t.size)


def residual_analysis(replay: Replay, model: dict[str, np.ndarray]) -> dict[str, Any]:
    """Whiteness and independence of each channel's held-out residual (MATLAB ``resid``)."""
    part = slice(replay.split, None)
    name, u = input_signal(replay)
    out: dict[str, Any] = {"input": name, "channels": {}}
    for channel in replay.channels:
        e = (replay.measured(channel) - model[channel])[part]
        if not np.isfinite(e).all():
            out["channels"][channel] = None
            continue
        w = whiteness(e, u[part])
        out["channels"][channel] = dataclasses.asdict(w)
    return out


def signature_table(
    replay: Replay, rig: Rig, model: dict[str, np.ndarray], controller=None
) -> dict[str, float]:
    """R² of the held-out residual regressed on each effect's signature."""
    result = replay.simulate(rig, controller)
    regs = signatures(result, rig)
    part = slice(replay.split, None)
    t = replay.t
    regressors = {k: np.interp(t, result.t, v)[part] for k, v in regs.items()}
    residuals = {
        c: ((replay.measured(c) - model[c]) / replay.sigma[c])[part] for c in replay.channels
    }
    table = signature_regression(residuals, regressors)
    table["valve_bias"] = mean_share(residuals)
    delay_u = table.pop("transport_delay_u", 0.0)
    table["transport_delay"] = max(table.get("transport_delay", 0.0), delay_u)
    return table


def _key(outcome: Outcome, name: str) -> str:
    """The rig-file key of a fitted field; ``(record k)`` for a per-record one (joint.py)."""
    fields = type(outcome.calibrated.params).__dataclass_fields__
    parsed = split_field(name)
    if parsed:
        return f"{fields[parsed[0]].metadata['key']} (record {parsed[1] + 1})"
    return fields[name].metadata["key"]


def summary_data(
    outcome: Outcome, replay: Replay, skipped: Mapping[str, str] | None = None
) -> dict[str, Any]:
    """The ``--json`` payload: effects added, fit before/after, the ranking, and more;
    ``skipped``: effects asked for that were not tried, with why (run.skipped_effects)."""
    models = outcome.models
    first = outcome.rounds[0].candidates if outcome.rounds else ()
    data: dict[str, Any] = {
        "effects_added": [
            {
                "name": c.name,
                "params": dict(c.params),
                "units": effect_units(outcome.declared, c.name),
                "ambiguous_with": list(_round_of(outcome, c.name).ambiguous_with),
                "z": c.evidence.z if c.evidence else None,
                "lookalike": LIBRARY[c.name].lookalike,
            }
            for c in outcome.added
        ],
        "fit_before_pct": fit_table(replay, models["declared"]),
        "fit_after_pct": fit_table(replay, models["calibrated"]),
        "candidates": [
            {"name": c.name, "score": c.score, "z": c.evidence.z if c.evidence else None}
            for c in first
        ],
    }
    if outcome.declared.unknowns:
        data["fit_nominal_pct"] = fit_table(replay, models["nominal"])
        data["fitted_parameters"] = {
            f: float(getattr(outcome.calibrated.params, f))
            for f in outcome.declared.unknowns
            if owner(f) is None and f not in outcome.per_record
        }
    bounds = outcome.controller.gain_bounds() if outcome.controller is not None else {}
    if bounds:
        data.setdefault("fit_nominal_pct", fit_table(replay, models["nominal"]))
        data["fitted_gains"] = {
            k: float(getattr(outcome.controller, k)) for k in bounds
        }  # the controller's gains declared unknown, fitted in the closed-loop replay
    if replay.logged_gains:
        data["gains_from_log"] = {k: v[0] for k, v in replay.logged_gains.items()}
        data["gains_from_log_fit_u_pct"] = replay.logged_fit
    data["decision"] = "none" if not outcome.added else ", ".join(c.name for c in outcome.added)
    data["rounds"] = [
        {
            "start_cost": r.start_cost_val,
            "start_cost_train": r.start_cost_train,
            "added": r.added,
            "threshold_z": r.threshold,
            "ambiguous_with": list(r.ambiguous_with),
            "separating_experiments": [
                {"name": e.name, "description": e.description, "distance": e.distance}
                for e in r.experiments
            ],
            "null": _null_data(r.null),
            "judged": [_judged(outcome, replay, r, a) for a in r.assessments],
            "candidates": [
                {
                    "name": c.name,
                    "score": c.score,
                    "cost_train": c.cost_train,
                    "cost_val": c.cost_val,
                    "n_params": c.n_params,
                    "z": c.evidence.z if c.evidence else None,
                    "log_lr": c.evidence.log_lr if c.evidence else None,
                    "n_eff": c.evidence.n_eff if c.evidence else None,
                    "params": dict(c.params),
                    "fit_val_pct": c.fit_val,
                    "status": c.status,
                    "evaluations": c.evaluations,
                    "seconds": c.seconds,
                }
                for c in r.candidates
            ],
        }
        for r in outcome.rounds
    ]
    if outcome.per_record:
        data["per_record"] = {
            _key(outcome, f): list(v) for f, v in outcome.per_record.items()
        }  # several records (joint.py): each record's fitted value
        data["records"] = [str(r.data.source) for r in replay.records]
    data["uncertainty"] = {
        _key(outcome, f): {
            "value": e.value,
            "interval": list(e.interval),
            "bounds": list(e.bounds),
            "at_bound": e.at_bound,
        }
        for f, e in outcome.uncertainty.items()
    }
    records = getattr(replay, "records", (replay,))
    data["warnings"] = warnings(outcome) + [
        w for r in records for w in data_warnings(r.data, r.channels)
    ]
    if still := replay.still_channels():  # not all of them: calibration/run.py refuses that
        data["warnings"].append(
            f"{replay.sources()}: the held-out part ({replay.held_out_words()}) does not move "
            f"in {replay.still_words(still)}: its held-out fit % is undefined and left out "
            "(n/a); a record whose held-out part moves there would validate it"
        )
    data["noise_cost"] = outcome.noise_cost
    data["noise_floor"] = {c: replay.sigma[c] for c in replay.channels}
    data["cost_val"] = {
        "declared": outcome.cost_declared,
        "nominal": outcome.cost_nominal,
        "calibrated": outcome.cost_final,
    }
    data["replay"] = {
        "mode": replay.mode,
        "samples": int(replay.t.size),
        "held_out_from_s": replay.split_s,
        "channels": dict(replay.channels),
    }
    data["seconds"] = outcome.seconds
    data["false_positive_rate"] = _false_positive_rate(outcome)
    data["skipped_effects"] = dict(skipped or {})
    # the last round's judgements (an earlier round's are against a model without the
    # effects added since), but the added one
    last = data["rounds"][-1]["judged"] if data["rounds"] else []
    data["judged"] = [j for j in last if j["verdict"] != "added"]
    data["negligible"] = [j for j in last if j["verdict"] == "negligible"]
    data["not_established"] = [j for j in last if j["verdict"] == "not established" and j["z"] > 0]
    data["verdict"] = verdict_lines(data)
    return data


def effect_units(rig: Rig, effect: str) -> dict[str, str]:
    """The SI unit of each parameter of ``effect`` on ``rig``'s plant (force N or N·m ...)."""
    return {p.key: rig.plant.effect_unit(p.unit) for p in LIBRARY[effect].params}


def _false_positive_rate(outcome: Outcome) -> float | None:
    """The first round's rate on its record's null (what adding any effect risks)."""
    nulls = [r.null for r in outcome.rounds if r.null is not None and r.null.draws]
    return nulls[0].false_positive_rate if nulls else None


def _null_data(null: Null | None) -> dict[str, Any] | None:
    if null is None:
        return None
    return {
        "draws": null.draws,
        "threshold_z": null.threshold,
        "bonferroni_z": null.bonferroni,
        "bootstrap_quantile_z": null.quantile,
        "false_positive_rate": null.false_positive_rate,
        "false_positive_rate_bonferroni": null.bonferroni_rate,
        "prediction_band_share": null.band,
        "residual": {
            c: {"rms_over_noise": lv.rms_sigma, "correlation_s": lv.correlation_s}
            for c, lv in null.levels.items()
        },
    }


def _judged(outcome: Outcome, replay: Replay, r: Round, a: Assessment) -> dict[str, Any]:
    """A judged candidate: its fitted size, z, share of the residual, the 95 % interval
    and detection limit of its size (as scales of the fitted contribution, and in SI
    for the effect's first parameter when it is off at 0), the experiment that would
    establish it (``plain``: in a test engineer's words, :func:`experiment_words`),
    the candidate ranked first in its round and the verdict's ``reason`` when it gives one."""
    candidate = next(c for c in r.candidates if c.name == a.name)
    out: dict[str, Any] = {
        "name": a.name,
        "verdict": a.verdict,
        "params": dict(candidate.params),
        "units": effect_units(outcome.declared, a.name),
        "first_in_round": r.candidates[0].name,
        "z": a.z,
        "share_of_residual": a.share,
        "share_needed": r.null.band if r.null is not None else 0.0,
        "reason": a.reason,
        "practical": None
        if a.practical is None
        else {
            "fraction": a.practical.fraction,
            "floor": a.practical.floor,
            "matters": a.practical.matters,
        },
        "interval_scale": list(a.interval),
        "limit_scale": a.limit,
    }
    size = _size_param(outcome.declared, a.name)
    if size is not None and size in candidate.params:
        value = candidate.params[size]
        param = LIBRARY[a.name].param(size)
        out["size"] = {
            "param": size,
            "value": value,
            "interval": [value * a.interval[0], value * a.interval[1]],
            "limit": value * a.limit,
            "range": list(candidate.bounds[param.field]),  # the fit's box
        }
    for name, experiment, recorded in r.establish:
        if name == a.name:
            out["experiment"] = {
                "name": experiment.name,
                "description": experiment.description,
                "plain": experiment_words(experiment, replay, outcome.declared),
                "distance": experiment.distance,
                "distance_recorded": recorded,
            }
    return out


def experiment_words(experiment: Separation, replay: Replay, rig: Rig) -> str:
    """The experiment (identifiability.excitations) as a test engineer would ask for
    it, in the rig's units: "a run of the same reference under a constant 990 N load
    pulling in the + direction" (a positive load resists motion in the + direction)."""
    record = getattr(replay, "records", (replay,))[0]  # the one the experiment varies
    fb = rig.feedback
    position_unit = rig.plant.signal_units.get(fb.signal, "")
    recorded = np.asarray(record.scenario.reference.sample(record.t), dtype=float)
    varied = np.asarray(experiment.scenario.reference.sample(record.t), dtype=float)
    name = experiment.name
    if name == "recorded":
        return "repeating the same run (more records of it, calibrated together)"
    if name.startswith("positions_"):
        (shift,), unit = quantity_text(
            [float(np.mean(varied - recorded)) / fb.slope], position_unit
        )
        sign = "+" if not shift.startswith("-") else ""
        return f"a run of the same reference shifted by {sign}{shift} {unit}".rstrip()
    if name.startswith("load_"):
        load = float(np.mean(experiment.scenario.load.sample(record.t)))
        (size,), unit = quantity_text([abs(load)], rig.plant.load[1])
        way = "resisting motion in" if load > 0 else "pulling in"
        return (
            f"a run of the same reference under a constant {size} {unit} load {way} the + direction"
        )
    if name == "sine_sweep":
        (amplitude,), unit = quantity_text(
            [float(np.ptp(varied)) / 2.0 / abs(fb.slope)], position_unit
        )
        return (
            f"a sine sweep from {SWEEP_HZ[0]:g} to {SWEEP_HZ[1]:g} Hz of ±{amplitude} {unit} about "
            "the recorded mid position"
        )
    return experiment.description


def _size_param(rig: Rig, effect: str) -> str | None:
    """The key of an effect's size: its first fitted parameter, if the effect is off at 0
    (a bulk modulus or a pump flow is not a size)."""
    fitted = LIBRARY[effect].fitted
    if not fitted:
        return None
    lo, _ = fitted[0].value_bounds(rig.scales())
    return fitted[0].key if lo <= 0.0 or fitted[0].signed else None


def verdict_lines(summary: dict[str, Any]) -> list[str]:
    """The verdict an engineer reads in ten seconds (the console's last lines): each
    effect added with its size in the rig's units and its 95 % interval, the held-out
    fit before -> after, the decision's error rate, then one line for each other effect
    judged (out-ranked, negligible, failed fit, failed, likely but not established:
    its size and the experiment that would settle it) and for each effect skipped."""
    added = summary["effects_added"]
    uncertainty = summary.get("uncertainty") or {}
    lines = []
    for e in added:
        lines.append(f"added: {e['name']}: {_added_size(e, uncertainty)}")
        if e["lookalike"]:
            lines.append(f"{e['name']} may also be {e['lookalike']}")
    if not added:
        tried = summary.get("rounds", True)
        lines.append("added: no effect" + ("" if tried else " (no candidate effect to try)"))
    before, after = summary.get("fit_before_pct"), summary.get("fit_after_pct")
    if before and after:
        lines.append(
            "held-out fit % (100 = perfect), before -> after: "
            + ", ".join(f"{c} {format_value(before[c])} -> {format_value(after[c])}" for c in after)
        )
    rate = error_rate_words(summary)
    if rate:
        lines.append(rate)
    judged = summary.get("judged", [])
    for j in judged:
        if j["verdict"] == "out-ranked":
            lines.append(
                f"out-ranked: {j['name']}, {_judged_size(j)}: passes the test too, but "
                f"{j.get('first_in_round', 'another')} ranks first"
                + (f" ({j['reason']})" if j.get("reason") else "")
            )
    for j in summary["negligible"]:
        lines.append(f"negligible: {j['name']}, {_judged_size(j)}: {j.get('reason') or _small(j)}")
    failed_fits = {j["name"]: j.get("reason", "") for j in judged if j["verdict"] == "failed fit"}
    last = summary["rounds"][-1]["candidates"] if summary.get("rounds") else []
    failed_fits.update(
        {c["name"]: "" for c in last if _failed_fit(c) and c["name"] not in failed_fits}
    )
    for name, reason in failed_fits.items():
        lines.append(
            f"failed fit: {name}: "
            + (
                reason
                or "its fit ended above the starting model's cost on the fitting part, which "
                "it contains: the search failed, and this record neither shows nor rules it out"
            )
        )
    for j in judged:
        if j["verdict"] == "failed":
            lines.append(
                f"failed: {j['name']}: "
                + (j.get("reason") or "its replay diverged at the fitted values: not judged")
            )
    for j in summary["not_established"]:
        e = j.get("experiment")
        if e:
            settle = f"{e.get('plain') or e['description']} would settle it"
        elif _beyond_range(j):
            settle = "this record cannot show it within the range the fit may take"
        else:
            settle = "too weak on this record to tell"
        lines.append(f"not established: {j['name']} may be present, {_judged_size(j)}; {settle}")
    for name, why in summary.get("skipped_effects", {}).items():
        lines.append(f"skipped: {name}: {why}")
    return lines


def ranking_line(summary: dict[str, Any], shown: int = 5) -> str:
    """The first round's best candidates by fitted improvement (held-out cost, lowest
    first), with the cost of the model they start from ("" when no round ran)."""
    if not summary.get("rounds"):
        return ""
    first = summary["rounds"][0]
    ranked = sorted(first["candidates"], key=_score_key)
    shown_text = ", ".join(
        f"{c['name']} "
        + (
            "failed fit"
            if _failed_fit(c)
            else "failed"
            if not _finite(c["score"])
            else format_value(c["score"])
        )
        for c in ranked[:shown]
    )
    return (
        "candidates, best fit first (held-out cost in noise units, lower is better: the "
        f"starting model {format_value(first['start_cost'])}, a perfect one 1): {shown_text}"
    )


def error_rate_words(summary: dict[str, Any]) -> str:
    """The decision's error rate on this record, worded as the decision's (how often it
    would add an effect to a record like this one that lacks it), not the finding's."""
    if not summary.get("rounds", True):
        return ""
    rate = summary.get("false_positive_rate")
    null = (summary.get("rounds") or [{}])[0].get("null") or {}
    draws = null.get("draws") or 0
    if rate is None or not draws:
        return (
            "error rate: no records like this one were drawn to measure it; where the "
            "model reproduces the data up to noise, this decision adds an effect the "
            f"record lacks in at most {100 * ALPHA:.0f} % of cases"
        )
    if rate == 0.0:
        how_often = f"under {100 / draws:.2g} % of cases (none of the {draws} tried)"
    else:
        how_often = (
            f"about {100 * rate:.2g} % of cases ({round(rate * draws)} of the {draws} tried)"
        )
    return (
        "error rate: on records like this one without a missing effect, this decision "
        f"would add one in {how_often}"
    )


def _failed_fit(c: dict[str, Any]) -> bool:
    """A summary candidate whose fit ended above the starting model (its status reads
    ``failed fit: <cause>``, search.fit)."""
    return str(c.get("status", "")).startswith("failed fit")


def _score_key(c: dict[str, Any]) -> float:
    return c["score"] if _finite(c["score"]) else math.inf


def _finite(value: float | None) -> bool:
    return value is not None and math.isfinite(value)


def _added_size(e: dict[str, Any], uncertainty: dict[str, Any]) -> str:
    """Each fitted parameter of an added effect in its unit with its 95 % interval."""
    parts = []
    for param in LIBRARY[e["name"]].fitted:
        value = e["params"].get(param.key, 0.0)
        if param.optional and not value:
            continue  # an optional part left off (friction that does not stick)
        unit = e.get("units", {}).get(param.key, "")
        u = uncertainty.get(f"{e['name']}.{param.key}")
        if u is None or not all(_finite(v) for v in u["interval"]):
            (text,), shown = quantity_text([value], unit)
            parts.append(f"{param.key} {text} {shown}".rstrip())
            continue
        lo, hi = u["interval"]
        (text, a, b), shown = quantity_text([value, lo, hi], unit, _digits(value, lo, hi))
        shown = f" {shown}" if shown else ""
        parts.append(
            f"{param.key} {text}{shown} (95 % interval {a} to {b}{shown}"
            + (", on its bound: the data want it further out)" if u["at_bound"] else ")")
        )
    return "; ".join(parts)


def _digits(value: float, lo: float, hi: float) -> int:
    """Significant digits that show an interval's half-width to two."""
    half = (hi - lo) / 2.0
    if not (half > 0.0 and value != 0.0):
        return 3
    return min(max(math.floor(math.log10(abs(value))) - math.floor(math.log10(half)) + 2, 3), 6)


def _judged_size(j: dict[str, Any]) -> str:
    """A judged candidate's approximate size in its unit: its size parameter (report
    ``size``) or every fitted parameter."""
    units = j.get("units", {})
    if "size" in j:
        keys = [j["size"]["param"]]
    else:
        fitted = {p.key for p in LIBRARY[j["name"]].fitted} if j["name"] in LIBRARY else set()
        keys = [k for k in j["params"] if k in fitted] or list(j["params"])
    parts = []
    for key in keys:
        (text,), unit = quantity_text([j["params"][key]], units.get(key, ""))
        parts.append(f"{key} about {text} {unit}".rstrip())
    return ", ".join(parts)


def _small(j: dict[str, Any]) -> str:
    """Why a candidate that passes the test is negligible (a summary without ``reason``):
    within the starting model's prediction band, or below what matters on this record."""
    share = 100 * j["share_of_residual"]
    if j["share_needed"] > 0.0 and j["share_of_residual"] < j["share_needed"]:
        return (
            f"it moves the outputs by {share:.1f} % of the residual level, less than the "
            "starting model's fitted effects move them within their 95 % intervals "
            f"({100 * j['share_needed']:.1f} %)"
        )
    return "too small to matter" + (f" ({_limit(j)})" if "size" in j else "")


def _beyond_range(j: dict[str, Any]) -> bool:
    """The detection limit lies beyond the range the fit may take."""
    if "size" not in j:
        return False
    size = j["size"]
    if not _finite(size["limit"]):
        return True
    lo, hi = size["range"]
    return abs(size["limit"]) > (hi if size["limit"] >= 0 else -lo)


def _limit(j: dict[str, Any]) -> str:
    """The detection limit in words and in the parameter's unit: the size (its
    magnitude for a signed one found below 0) from which this record shows it, and
    whether the fit's range reaches it at all."""
    size = j["size"]
    limit, name = size["limit"], size["param"]
    if not _finite(limit):
        return "this record cannot show it at any size"
    unit = j.get("units", {}).get(name, "")
    (text,), shown = quantity_text([abs(limit)], unit)
    words = f"this record shows it from {'|' + name + '|' if limit < 0 else name} {text} {shown}"
    if _beyond_range(j):
        lo, hi = size["range"]
        (reach,), shown = quantity_text([hi if limit >= 0 else -lo], unit)
        words += f", beyond the {reach} {shown} the fit may take"
    return words.replace("  ", " ").rstrip()


def warnings(outcome: Outcome) -> list[str]:
    """What the user must know before trusting the result: ambiguities (with the
    experiment that would separate them) and fitted values on a bound."""
    out = []
    for r in outcome.rounds:
        if r.added and r.ambiguous_with:
            line = (
                f"{r.added} cannot be told apart from {', '.join(r.ambiguous_with)} on this "
                "data (the best does not beat them on the held-out part)"
            )
            if r.experiments:
                e = r.experiments[0]
                line += f"; an experiment that separates them: {e.name}, {e.description}"
            out.append(line)
    for f, e in outcome.uncertainty.items():
        if e.at_bound:
            lo, hi = e.bounds
            out.append(
                f"{_key(outcome, f)} = {e.value:.4g} sits on its bound [{lo:.4g}, "
                f"{hi:.4g}]: the data want it further out; widen the bound (fit: [...]) or "
                "look for another effect"
            )
    return out


def data_warnings(data: Measured, channels: Iterable[str]) -> list[str]:
    """Logger habits that weaken every score (residuals.noise_floor handles them, the
    user should still know): held samples and a quantisation that sets the noise level."""
    out = []
    for channel in channels:
        y = np.asarray(data.signals[channel], dtype=float)
        dy = np.diff(y)
        held = float(np.mean(dy == 0.0)) if dy.size else 0.0
        q = quantisation_step(dy)
        if held > 0.5 and q == 0.0:  # a quantised signal repeats for another reason
            out.append(
                f"{data.source}: {100 * held:.0f} % of the {channel} samples repeat the previous one "
                "(a logger holding its last value between sensor updates): the noise level "
                "is estimated on the updates alone; log at the sensor's rate if you can"
            )
        sigma = noise_floor(y)
        if q > 0.0 and q / np.sqrt(12.0) >= 0.5 * sigma:
            out.append(
                f"{data.source}: {channel} is quantised in steps of {q:.3g} "
                f"({data.units.get(channel, '')}), as large as its noise: residuals below "
                "one step cannot be resolved"
            )
    return out


def _null_lines(r: dict[str, Any]) -> list[str]:
    """A round's null (threshold, false-positive rate, residual) and judged candidates."""
    null = r["null"]
    if not null or not null["draws"]:
        return []
    lines = [
        f"Null: {null['draws']} surrogate records; threshold z > {null['threshold_z']:.2f} "
        f"(the 95 % quantile of the largest z on them {null['bootstrap_quantile_z']:.2f}, at least "
        f"1.64; Bonferroni's {null['bonferroni_z']:.2f} for comparison); "
        f"false-positive rate {100 * null['false_positive_rate']:.1f} % "
        f"(Bonferroni alone: {100 * null['false_positive_rate_bonferroni']:.1f} %). "
        + (
            f"The effects added before move the outputs by {100 * null['prediction_band_share']:.1f} % "
            "of the residual level within their 95 % intervals: an effect must move them more. "
            if null["prediction_band_share"] > 0.0
            else ""
        )
        + "Residual: "
        + ", ".join(
            f"{c} {v['rms_over_noise']:.3g} σ over {1e3 * v['correlation_s']:.3g} ms"
            for c, v in null["residual"].items()
        )
        + ".",
        "",
        "| effect | verdict | size | z | share of residual | size 95 % (× fitted) | "
        "limit (× fitted) | detection limit | experiment that would establish it |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for j in r["judged"]:
        a, b = j["interval_scale"]
        e = j.get("experiment")
        limit = _limit(j) if "size" in j else ""
        lines.append(
            f"| {j['name']} | {j['verdict']} | {_judged_size(j)} | {j['z']:.2f} | "
            f"{100 * j['share_of_residual']:.1f} % | [{a:.3g}, {b:.3g}] | {j['limit_scale']:.3g} | "
            f"{limit.removeprefix('this record shows it from ')} | "
            + (f"{e['name']}: {e['description']} ({e['distance'] / e['distance_recorded']:.3g}× "
               "the recorded separation)" if e and _finite(e["distance_recorded"]) and e["distance_recorded"] > 0 else "")
            + (f" {j['reason']}" if j.get("reason") else "")
            + " |"
        )  # fmt: skip
    return [*lines, ""]


def _round_of(outcome: Outcome, name: str):
    """The round in which effect ``name`` was added."""
    return next(r for r in outcome.rounds if r.added == name)


def _pct(value: float | None) -> str:
    if value is None or not np.isfinite(value):
        return "failed" if value is not None and value == -np.inf else "n/a"
    return f"{value:.1f} %"


def report_markdown(
    outcome: Outcome, replay: Replay, summary: dict, paths: dict[str, Path], data_path
) -> str:
    def rel(key: str) -> str:
        return paths[key].name

    lines = [
        f"# Calibration of {outcome.declared.name} on {Path(data_path).name}",
        "",
        f"Replay: {replay.mode}; {replay.t.size} samples at {replay.data.sample_period_s * 1e3:.4g} ms; "
        f"the last {100 * (1 - replay.split / replay.t.size):.0f} % (from {replay.split_s:.2f} s) "
        "is held out: fits are fitted on the first part and reported on it.",
        "",
        *[f"> **Warning:** {w}" + "\n" for w in summary["warnings"]],
        f"**Effects added: {summary['decision']}**"
        + (f" → calibrated rig `{rel('rig')}`" if "rig" in paths else ""),
        "",
        "## Verdict",
        "",
        *[f"- {line}" for line in summary["verdict"]],
        "",
        "## Fit on held-out data (MATLAB `compare`: 100·(1 − ‖y − ŷ‖/‖y − ȳ‖))",
        "",
    ]
    cols = ["declared rig"]
    tables = [summary["fit_before_pct"]]
    if "fit_nominal_pct" in summary:
        cols.append("unknowns fitted")
        tables.append(summary["fit_nominal_pct"])
    cols.append("calibrated")
    tables.append(summary["fit_after_pct"])
    lines.append("| channel | noise σ | " + " | ".join(cols) + " |")
    lines.append("|---|---|" + "---|" * len(cols))
    for channel in replay.channels:
        unit, k = display_scale(replay.data.units[channel])
        sigma = f"{k * replay.sigma[channel]:.3g} {unit}"
        lines.append(
            f"| {channel} | {sigma} | " + " | ".join(_pct(t[channel]) for t in tables) + " |"
        )
    lines += ["", f"![overlay]({rel('overlay')})", f"![held-out detail]({rel('overlay_zoom')})", ""]
    if "per_record" in summary:
        records = summary["records"]
        lines += [
            f"## {len(records)} records calibrated together",
            "",
            "The figures show them end to end: every record's training part, then every "
            "record's held-out part. Shared: every effect and the other unknowns; fitted "
            "per record (SI):",
            "",
            "| parameter | " + " | ".join(f"record {k + 1}" for k in range(len(records))) + " |",
            "|---|" + "---|" * len(records),
        ]
        for key, values in summary["per_record"].items():
            lines.append(f"| {key} | " + " | ".join(f"{v:.6g}" for v in values) + " |")
        lines += [""] + [f"{k + 1}. {src}" for k, src in enumerate(records)] + [""]
    if summary["uncertainty"]:
        lines += [
            "## Fitted values (SI) with 95 % intervals",
            "",
            "Linearised from the Jacobian with the effective sample size (uncertainty.py); "
            "the calibrated rig carries them as `interval` and `at_bound`.",
            "",
            "| parameter | bounds | value | 95 % interval | at bound |",
            "|---|---|---|---|---|",
        ]
        for key, u in summary["uncertainty"].items():
            lo, hi = u["bounds"]
            a, b = u["interval"]
            lines.append(
                f"| {key} | [{lo:.4g}, {hi:.4g}] | {u['value']:.6g} | [{a:.4g}, {b:.4g}] | "
                f"{'**yes**' if u['at_bound'] else 'no'} |"
            )
        lines.append("")
    if replay.logged_gains:
        lines += [
            "## Controller gains fitted on the logged command u",
            "",
            f"Held-out fit of u: {replay.logged_fit:.1f} %.",
            "",
            "| gain | bounds | value |",
            "|---|---|---|",
        ]
        for k, (v, lo, hi) in replay.logged_gains.items():
            lines.append(f"| {k} | [{lo:.4g}, {hi:.4g}] | {v:.6g} |")
        lines.append("")
    if "fitted_gains" in summary:
        gain_bounds = outcome.controller.gain_bounds()
        lines += ["## Fitted controller gains", "", "| gain | bounds | value |", "|---|---|---|"]
        for k, v in summary["fitted_gains"].items():
            lo, hi = gain_bounds[k]
            lines.append(f"| {k} | [{lo:.4g}, {hi:.4g}] | {v:.6g} |")
        lines.append("")
    lines += [
        "## Candidates",
        "",
        "Score: held-out mean squared residual in units of each channel's noise variance "
        "(1 = a perfect model). z: the held-out log-likelihood ratio over the round's "
        "starting model divided by its noise-driven spread (effective sample size from the "
        "residual's autocorrelation). The best is added when its z exceeds the round's "
        "threshold: the larger of Φ⁻¹(1 − 0.05/K) for K candidates and the 95 % quantile "
        "of the largest z on surrogate records of this one without a missing effect (the "
        "round's residual with its spectrum kept and its phases randomised, added to the "
        "starting model's replay; null.py), and when it matters physically (significance.py): "
        f"its size at least {SIZE_FLOOR:.0%} of the smallest a real rig typically shows, or, "
        f"for an effect without a size, a change of at least {SIGNAL_FLOOR:.0%} of a recorded "
        f"signal's own variation (its detection limit on this record: found in "
        f"{REQUIRED:.0%} of the surrogates and mattering); "
        "from the second round on, also more than the effects added before move them "
        "within their 95 % intervals (the starting model's own prediction uncertainty). "
        "Else it is negligible.",
        "",
    ]
    for k, r in enumerate(outcome.rounds, start=1):
        lines += [
            f"### Round {k}: starting cost {r.start_cost_val:.4g}, threshold z > "
            f"{r.threshold:.2f}, added: {r.added or 'none'}"
            + (f" (ambiguous with {', '.join(r.ambiguous_with)})" if r.ambiguous_with else ""),
            "",
            *_null_lines(summary["rounds"][k - 1]),
            "| rank | effect | score | improvement | z | parameters | status | runs | s |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for i, c in enumerate(by_improvement(r), start=1):
            params = ", ".join(f"{key} = {v:.4g}" for key, v in c.params.items())
            z = f"{c.evidence.z:.2f}" if c.evidence else "n/a"
            lines.append(
                f"| {i} | {c.name} | {c.score:.4g} | {r.start_cost_val - c.score:.4g} | {z} | "
                f"{params} | {c.status} | {c.evaluations} | {c.seconds:.1f} |"
            )
        lines += ["", f"![candidates]({rel(f'candidates_{k}')})", ""]
    lines += [
        "## Residual analysis (held-out part, lags ±25, 99 % band ±2.58/√N)",
        "",
        "| channel | before: autocorr. lags outside | before: cross-corr. outside (peak lag) | "
        "after: autocorr. outside | after: cross-corr. outside (peak lag) |",
        "|---|---|---|---|---|",
    ]
    ra = summary["residual_analysis"]
    for channel in replay.channels:
        b, a = ra["before"]["channels"][channel], ra["after"]["channels"][channel]

        def cell(w):
            if w is None:
                return "n/a", "n/a"
            return (
                f"{w['autocorr_outside']}/25",
                f"{w['crosscorr_outside']}/51 ({w['peak_crosscorr_lag']:+d})",
            )

        lines.append(f"| {channel} | " + " | ".join([*cell(b), *cell(a)]) + " |")
    lines += [
        "",
        f"Cross-correlation with `{ra['before']['input']}`.",
        "",
        f"![residuals before]({rel('residuals_before')})",
        f"![residuals after]({rel('residuals_after')})",
        "",
        "Residual of the model before calibration regressed on each effect's signature "
        "(docs/modelling.md table; R²: share of residual variance explained), ranked by "
        "what the effect's fit improves the held-out cost in round 1 (a signature is a "
        "linear guess; the fit is the evidence):",
        "",
        "| effect | round 1 held-out cost | improvement | R² |",
        "|---|---|---|---|",
    ]
    for name, r2, cost, gain in signature_rows(outcome, summary["signature_r2"]):
        lines.append(f"| {name} | {cost} | {gain} | {r2:.3f} |")
    lines.append("")
    return "\n".join(lines)


def by_improvement(r: Round) -> list[Candidate]:
    """A round's candidates by fitted improvement, the held-out cost reduction against
    the round's start (lowest score first; a failed run last), ties in the round's order."""
    return sorted(r.candidates, key=lambda c: c.score if math.isfinite(c.score) else math.inf)


def signature_rows(outcome: Outcome, r2: Mapping[str, float]) -> list[tuple[str, float, str, str]]:
    """(effect, signature R², round-1 held-out cost, its improvement on the start) by
    fitted improvement; the effects without a round-1 candidate after, by R²."""
    first = outcome.rounds[0] if outcome.rounds else None
    ranked = by_improvement(first) if first else []
    rows = [
        (c.name, r2[c.name], f"{c.score:.4g}", f"{first.start_cost_val - c.score:.4g}")
        for c in ranked
        if c.name in r2
    ]
    fitted = {c.name for c in ranked}
    rest = sorted((kv for kv in r2.items() if kv[0] not in fitted), key=lambda kv: -kv[1])
    return rows + [(name, value, "not fitted", "") for name, value in rest]
