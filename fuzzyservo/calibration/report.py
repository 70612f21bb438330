"""Calibration outputs: the calibrated rig file, figures, a Markdown report and the summary JSON."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from fuzzyservo.calibration.joint import split_field
from fuzzyservo.calibration.null import REQUIRED, Assessment, Null
from fuzzyservo.calibration.replay import Replay
from fuzzyservo.calibration.residuals import (
    noise_floor,
    quantisation_step,
    signature_regression,
    whiteness,
)
from fuzzyservo.calibration.search import Outcome, Round, fit_table
from fuzzyservo.calibration.signatures import mean_share, signatures
from fuzzyservo.calibration.significance import SIGNAL_FLOOR, SIZE_FLOOR
from fuzzyservo.components.effects import LIBRARY, owner
from fuzzyservo.display import display_scale
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


def summary_data(outcome: Outcome, replay: Replay) -> dict[str, Any]:
    """The ``--json`` payload: effects added, fit before/after, the ranking, and more."""
    models = outcome.models
    first = outcome.rounds[0].candidates if outcome.rounds else ()
    data: dict[str, Any] = {
        "effects_added": [
            {
                "name": c.name,
                "params": dict(c.params),
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
            "judged": [_judged(outcome, r, a) for a in r.assessments],
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
    data["negligible"] = [
        j for r in data["rounds"] for j in r["judged"] if j["verdict"] == "negligible"
    ]
    last = data["rounds"][-1]["judged"] if data["rounds"] else []
    data["not_established"] = [j for j in last if j["verdict"] == "not established" and j["z"] > 0]
    data["verdict"] = verdict_lines(data)
    return data


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


def _judged(outcome: Outcome, r: Round, a: Assessment) -> dict[str, Any]:
    """A judged candidate: its fitted size, z, share of the residual, the 95 % interval
    and detection limit of its size (as scales of the fitted contribution, and in SI
    for the effect's first parameter when it is off at 0) and the experiment that would
    establish it."""
    candidate = next(c for c in r.candidates if c.name == a.name)
    out: dict[str, Any] = {
        "name": a.name,
        "verdict": a.verdict,
        "params": dict(candidate.params),
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
            "range": list(param.value_bounds(outcome.declared.scales())),  # the fit's box
        }
    for name, experiment, recorded in r.establish:
        if name == a.name:
            out["experiment"] = {
                "name": experiment.name,
                "description": experiment.description,
                "distance": experiment.distance,
                "distance_recorded": recorded,
            }
    return out


def _size_param(rig: Rig, effect: str) -> str | None:
    """The key of an effect's size: its first fitted parameter, if the effect is off at 0
    (a bulk modulus or a pump flow is not a size)."""
    fitted = LIBRARY[effect].fitted
    if not fitted:
        return None
    lo, _ = fitted[0].value_bounds(rig.scales())
    return fitted[0].key if lo <= 0.0 or fitted[0].signed else None


def verdict_lines(summary: dict[str, Any]) -> list[str]:
    """The verdict in words: what was added, what is negligible, what is likely but not
    established on this record and the experiment that would establish it."""
    lines = []
    fpr = summary.get("false_positive_rate")
    rate = f"{100 * fpr:.1f} %" if fpr is not None else "n/a"
    added = summary["effects_added"]
    if added:
        lines.append(
            "added: "
            + "; ".join(f"{e['name']} ({_sizes(e['params'])}, z {e['z']:.1f})" for e in added)
        )
    else:
        lines.append("added: no effect")
    for e in added:
        if e["lookalike"]:
            lines.append(f"{e['name']} may also be {e['lookalike']}")
    lines.append(
        f"false-positive rate of the decision on this record's null (bootstrap of its "
        f"residual): {rate}"
    )
    for j in summary["negligible"]:
        lines.append(
            f"negligible: {j['name']} ({_sizes(j['params'])}, z {j['z']:.1f}): {j['reason']}"
        )
    for j in summary["not_established"]:
        line = (
            f"not established: {j['name']} of about {_sizes(j['params'])} (z "
            f"{j['z']:.2f}, limit on this record {_limit(j)})"
        )
        if "experiment" in j:
            e = j["experiment"]
            ratio = (
                e["distance"] / e["distance_recorded"] if e["distance_recorded"] else float("inf")
            )
            line += f"; would need {e['name']}: {e['description']} ({ratio:.3g}× the recorded separation)"
        lines.append(line)
    return lines


def _sizes(params: dict[str, float]) -> str:
    return ", ".join(f"{k} = {v:.3g}" for k, v in params.items())


def _limit(j: dict[str, Any]) -> str:
    """The detection limit in words: the size (its magnitude for a signed one found
    below 0), and whether the fit's range reaches it at all."""
    if "size" not in j:
        return f"{j['limit_scale']:.3g}× the fitted contribution"
    size = j["size"]
    limit, name = size["limit"], size["param"]
    text = f"|{name}| ≥ {-limit:.3g}" if limit < 0 else f"{name} ≥ {limit:.3g}"
    lo, hi = size["range"]
    reach = hi if limit >= 0 else -lo
    if abs(limit) > reach:
        text += f", beyond its range (up to {reach:.3g}): this record cannot detect it"
    return text


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
        f"(Bonferroni {null['bonferroni_z']:.2f}, bootstrap 95 % {null['bootstrap_quantile_z']:.2f}); "
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
        "| effect | verdict | z | share of residual | size 95 % (× fitted) | limit (× fitted) | "
        "experiment that would establish it |",
        "|---|---|---|---|---|---|---|",
    ]
    for j in r["judged"]:
        a, b = j["interval_scale"]
        e = j.get("experiment")
        lines.append(
            f"| {j['name']} | {j['verdict']} | {j['z']:.2f} | {100 * j['share_of_residual']:.1f} % | "
            f"[{a:.3g}, {b:.3g}] | {j['limit_scale']:.3g} | "
            + (f"{e['name']}: {e['description']}" if e else "")
            + " |"
        )
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
            "| rank | effect | score | z | parameters | runs | s |",
            "|---|---|---|---|---|---|---|",
        ]
        for i, c in enumerate(r.candidates, start=1):
            params = ", ".join(f"{key} = {v:.4g}" for key, v in c.params.items())
            z = f"{c.evidence.z:.2f}" if c.evidence else "n/a"
            lines.append(
                f"| {i} | {c.name} | {c.score:.4g} | {z} | {params} | "
                f"{c.evaluations} | {c.seconds:.1f} |"
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
        "(docs/modelling.md table; share of residual variance explained):",
        "",
        "| effect | R² |",
        "|---|---|",
    ]
    for name, r2 in sorted(summary["signature_r2"].items(), key=lambda kv: -kv[1]):
        lines.append(f"| {name} | {r2:.3f} |")
    lines.append("")
    return "\n".join(lines)
