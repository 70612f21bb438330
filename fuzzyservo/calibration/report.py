"""The calibration report in Markdown, and the tables it and the figures share."""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from fuzzyservo.calibration.candidates import Candidate
from fuzzyservo.calibration.null import REQUIRED
from fuzzyservo.calibration.replay import Replay
from fuzzyservo.calibration.search import Round, SearchOutcome
from fuzzyservo.calibration.significance import SIGNAL_FLOOR, SIZE_FLOOR
from fuzzyservo.calibration.verdict import is_finite, judged_size, limit_words
from fuzzyservo.display import display_scale

if TYPE_CHECKING:
    pass

ZOOM_S = 5.0  # the detail overlay shows this much of the held-out part [s]


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
        limit = limit_words(j) if "size" in j else ""
        lines.append(
            f"| {j['name']} | {j['verdict']} | {judged_size(j)} | {j['z']:.2f} | "
            f"{100 * j['share_of_residual']:.1f} % | [{a:.3g}, {b:.3g}] | {j['limit_scale']:.3g} | "
            f"{limit.removeprefix('this record shows it from ')} | "
            + (f"{e['name']}: {e['description']} ({e['distance'] / e['distance_recorded']:.3g}× "
               "the recorded separation)" if e and is_finite(e["distance_recorded"]) and e["distance_recorded"] > 0 else "")
            + (f" {j['reason']}" if j.get("reason") else "")
            + " |"
        )  # fmt: skip
    return [*lines, ""]


def _pct(value: float | None) -> str:
    if value is None or not np.isfinite(value):
        return "failed" if value is not None and value == -np.inf else "n/a"
    return f"{value:.1f} %"


def report_markdown(
    outcome: SearchOutcome, replay: Replay, summary: dict, paths: dict[str, Path], data_path
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
    return sorted(
        r.candidates, key=lambda c: (c.score if math.isfinite(c.score) else math.inf, c.name)
    )


def signature_rows(
    outcome: SearchOutcome, r2: Mapping[str, float]
) -> list[tuple[str, float, str, str]]:
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
