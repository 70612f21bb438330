"""A calibration's summary: the JSON-ready record of what it concluded (``summary.json``,
:meth:`~fuzzyservo.calibration.run.CalibrationResult.to_dict`), its warnings and the
residual analysis it reports."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from fuzzyservo.calibration.candidates import fit_table
from fuzzyservo.calibration.joint import split_field
from fuzzyservo.calibration.null import Assessment, Null
from fuzzyservo.calibration.replay import Replay
from fuzzyservo.calibration.residuals import (
    autocorrelation,
    confidence_band,
    cross_correlation,
    noise_floor,
    quantisation_step,
    signature_regression,
    whiteness,
)
from fuzzyservo.calibration.search import Round, SearchOutcome
from fuzzyservo.calibration.signatures import mean_share, signatures
from fuzzyservo.calibration.verdict import experiment_words, verdict_lines
from fuzzyservo.components.effects import LIBRARY, owner
from fuzzyservo.rig import Rig

if TYPE_CHECKING:
    from fuzzyservo.measured import Measured


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


#: the residuals a calibration analyses: (label, the model of SearchOutcome.models)
RESIDUAL_MODELS = (("before", "nominal"), ("after", "calibrated"))


def diagnostics(outcome: SearchOutcome, replay: Replay) -> dict[str, Any]:
    """The parts of ``summary.json`` that analyse the residual: its whiteness and
    independence before and after (``residual_analysis``, MATLAB ``resid``) and each
    effect's signature R² on the nominal model's residual (``signature_r2``, a run of
    the nominal rig)."""
    models = outcome.models
    analyses = {label: residual_analysis(replay, models[key]) for label, key in RESIDUAL_MODELS}
    sig_replay, sig_model = replay, models["nominal"]
    if hasattr(replay, "records"):  # several records: the signatures of the first
        sig_replay = replay.records[0]
        sig_model = {c: replay.unjoin(v)[0] for c, v in sig_model.items()}
    signature = signature_table(sig_replay, outcome.nominal, sig_model, outcome.controller)
    return {"residual_analysis": analyses, "signature_r2": signature}


@dataclass(frozen=True)
class Correlations:
    """A channel's held-out residual correlations as ``resid`` plots them: lags and
    values of its autocorrelation and of its cross-correlation with the input."""

    acf: tuple[np.ndarray, np.ndarray]
    xcf: tuple[np.ndarray, np.ndarray]


def residual_correlations(
    replay: Replay, model: dict[str, np.ndarray]
) -> tuple[str, float, dict[str, Correlations]]:
    """The input the residuals are correlated with, the band a white residual stays
    inside, and each channel's correlations on the held-out part (channels whose
    residual is not finite there left out)."""
    name, u = input_signal(replay)
    part = slice(replay.split, None)
    out = {}
    for channel in replay.channels:
        e = (replay.measured(channel) - model[channel])[part]
        if np.isfinite(e).all():
            out[channel] = Correlations(autocorrelation(e), cross_correlation(e, u[part]))
    return name, confidence_band(replay.t.size - replay.split), out


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


def _key(outcome: SearchOutcome, name: str) -> str:
    """The rig-file key of a fitted field; ``(record k)`` for a per-record one (joint.py)."""
    fields = type(outcome.calibrated.params).__dataclass_fields__
    parsed = split_field(name)
    if parsed:
        return f"{fields[parsed[0]].metadata['key']} (record {parsed[1] + 1})"
    return fields[name].metadata["key"] if name in fields else name  # a controller gain


def calibration_summary(
    outcome: SearchOutcome, replay: Replay, skipped: Mapping[str, str] | None = None
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
                # no parameter on its bound: the size is a measurement (verdict.py)
                "size_resolved": not any(
                    outcome.uncertainty[p.field].at_bound
                    for p in LIBRARY[c.name].fitted
                    if p.field in outcome.uncertainty
                    and not (p.optional and not c.params.get(p.key))
                ),
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
            **(
                {"trades_with": _key(outcome, e.trades_with), "correlation": e.correlation}
                if e.trades_with
                else {}
            ),
        }
        for f, e in outcome.uncertainty.items()
    }
    records = getattr(replay, "records", (replay,))
    data["warnings"] = (
        warnings(outcome)
        + loop_warnings(outcome, records)
        + [w for r in records for w in data_warnings(r.data, r.channels)]
    )
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


def _false_positive_rate(outcome: SearchOutcome) -> float | None:
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


def _judged(outcome: SearchOutcome, replay: Replay, r: Round, a: Assessment) -> dict[str, Any]:
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


def _size_param(rig: Rig, effect: str) -> str | None:
    """The key of an effect's size: its first fitted parameter, if the effect is off at 0
    (a bulk modulus or a pump flow is not a size)."""
    fitted = LIBRARY[effect].fitted
    if not fitted:
        return None
    lo, _ = fitted[0].value_bounds(rig.scales())
    return fitted[0].key if lo <= 0.0 or fitted[0].signed else None


def warnings(outcome: SearchOutcome) -> list[str]:
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


def loop_warnings(outcome: SearchOutcome, records: Iterable[Replay]) -> list[str]:
    """Friction added on a replay through the controller of a record that has its valve
    input: in a quantised loop friction sticks and slips where single converter codes
    put it, so the replay is chaotic in friction's values (a millionth more moves the
    cost several-fold; tests/replay_sensitivity.py) and its intervals need not hold the
    true values; replayed from the recorded input the cost is smooth
    (docs/calibration-intervals.md, "Where the replay is chaotic")."""
    through = {r.data.source: input_signal(r)[0] for r in records if r.drive == "ref"}
    inputs = {source: name for source, name in through.items() if name != "ref"}
    if not inputs:
        return []
    which = "; ".join(
        f"{source} has the valve {'current i' if name == 'i' else 'command u'}"
        for source, name in inputs.items()
    )
    return [
        f"{c.name} was fitted through the controller: in a quantised loop friction sticks "
        "and slips where single converter codes put it, so the replay is chaotic in it "
        "and its 95 % intervals need not hold the true values; "
        f"{which}: leave out --controller to fit it from that input, where the cost is "
        "smooth (docs/calibration-intervals.md)"
        for c in outcome.added
        if LIBRARY[c.name].stick_slip
    ]


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


def _round_of(outcome: SearchOutcome, name: str):
    """The round in which effect ``name`` was added."""
    return next(r for r in outcome.rounds if r.added == name)
