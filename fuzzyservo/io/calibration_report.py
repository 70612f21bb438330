"""A calibration's files: the calibrated rig, figures, ``report.md`` and ``summary.json``.

The numbers and the report's text come from :mod:`fuzzyservo.calibration.summary` and
:mod:`fuzzyservo.calibration.report`; this module only writes them (files are the edge of the package).
"""

from __future__ import annotations

import datetime as _dt
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from fuzzyservo.atomic import ensure_folder, write_text
from fuzzyservo.calibration.candidates import fit_table
from fuzzyservo.calibration.joint import split_field
from fuzzyservo.calibration.replay import Replay
from fuzzyservo.calibration.report import ZOOM_S, report_markdown
from fuzzyservo.calibration.residuals import (
    autocorrelation,
    confidence_band,
    cross_correlation,
)
from fuzzyservo.calibration.search import SearchOutcome
from fuzzyservo.calibration.summary import (
    calibration_summary,
    input_signal,
    residual_analysis,
    signature_table,
)
from fuzzyservo.components.effects import LIBRARY
from fuzzyservo.display import display_scale


def write_calibration_report(
    outcome: SearchOutcome,
    replay: Replay,
    data_path: str | Path,
    out_dir: Path,
    skipped: Mapping[str, str] | None = None,
) -> tuple[dict[str, Path], dict[str, Any]]:
    """Write the calibrated rig, figures, report and summary into ``out_dir``; return
    the paths and the summary (as written to ``summary.json``); ``skipped``: the
    effects asked for and not tried, with why (calibration/run.skipped_effects)."""
    from fuzzyservo.io.jsonfile import write_json
    from fuzzyservo.io.rigs import write_calibrated_rig
    from fuzzyservo.plots import candidates_figure, overlay_figure, residual_figure, save

    out_dir = ensure_folder(out_dir)
    rig = outcome.calibrated
    paths: dict[str, Path] = {}
    stamp = _dt.date.today().isoformat()
    origin = f"fuzzyservo calibrate on {Path(data_path).name} ({stamp})"
    parameters = {}
    for f in outcome.declared.unknowns:
        meta = type(rig.params).__dataclass_fields__[f].metadata
        if meta.get("effect") or f in outcome.per_record:
            continue  # a per-record value is the record's, not the rig's
        parameters[meta["key"]] = (
            float(getattr(rig.params, f)),
            meta["unit"],
            f"fitted by {origin}",
        )
    effects = {}
    for name in rig.effects:
        effect = LIBRARY[name]
        values = rig.effect_values(name)
        fitted = name in {c.name for c in outcome.added} or any(
            p.field in outcome.declared.unknowns for p in effect.params
        )
        how = f"fitted by {origin}" if fitted else "declared in the rig file"
        effects[name] = {
            p.key: (values[p.key], rig.plant.effect_unit(p.unit), how) for p in effect.params
        }
    header = (
        f"Calibrated by {origin}\n"
        f"from rig file {outcome.declared.path}; effects added: "
        f"{', '.join(c.name for c in outcome.added) or 'none'}"
    )
    intervals = {}
    for f, est in outcome.uncertainty.items():
        if split_field(f):
            continue
        meta = type(rig.params).__dataclass_fields__[f].metadata
        key = meta["key"]  # "effect.key" for an effect's parameter
        intervals[key] = (*est.interval, est.at_bound)
    if outcome.declared.path:
        paths["rig"] = write_calibrated_rig(
            outcome.declared.path,
            out_dir / f"{outcome.declared.name}_calibrated.yaml",
            parameters=parameters,
            effects=effects,
            header=header,
            intervals=intervals,
        )
    summary = calibration_summary(outcome, replay, skipped)
    if "rig" in paths:
        summary["calibrated_rig"] = str(paths["rig"])

    # figures
    t = replay.t
    units, measured, before, after = {}, {}, {}, {}
    for channel in replay.channels:
        unit, k = display_scale(replay.data.units[channel])
        units[channel] = unit
        measured[channel] = k * replay.measured(channel)
        before[channel] = k * outcome.models["nominal"][channel]
        after[channel] = k * outcome.models["calibrated"][channel]
    fit_before = fit_table(replay, outcome.models["nominal"])
    fit_after = summary["fit_after_pct"]
    title = f"{outcome.declared.name}: {replay.mode}"
    fig = overlay_figure(
        t, measured, before, after, units, replay.split_s, fit_before, fit_after, title
    )
    paths["overlay"] = save(fig, out_dir / "overlay.png")
    zoom = (replay.split_s, min(float(t[-1]), replay.split_s + ZOOM_S))
    fig = overlay_figure(
        t, measured, before, after, units, replay.split_s, fit_before, fit_after,
        f"{title} (held-out part, first {zoom[1] - zoom[0]:.3g} s)", window=zoom,
    )  # fmt: skip
    paths["overlay_zoom"] = save(fig, out_dir / "overlay_zoom.png")
    band = confidence_band(t.size - replay.split)
    input_name, u = input_signal(replay)
    part = slice(replay.split, None)
    analyses = {}
    for label, model in (
        ("before", outcome.models["nominal"]),
        ("after", outcome.models["calibrated"]),
    ):
        res, acf, xcf = {}, {}, {}
        for channel in replay.channels:
            e = measured[channel] - (before if label == "before" else after)[channel]
            res[channel] = e
            if np.isfinite(e[part]).all():
                acf[channel] = autocorrelation(e[part])
                xcf[channel] = cross_correlation(e[part], u[part])
        fig = residual_figure(
            t, res, units, acf, xcf, band, input_name, title=f"residuals {label}: {title}"
        )
        paths[f"residuals_{label}"] = save(fig, out_dir / f"residuals_{label}.png")
        analyses[label] = residual_analysis(replay, model)
    summary["residual_analysis"] = analyses
    sig_replay, sig_model = replay, outcome.models["nominal"]
    if hasattr(replay, "records"):  # several records: the signatures of the first
        sig_replay = replay.records[0]
        sig_model = {c: replay.unjoin(v)[0] for c, v in sig_model.items()}
    summary["signature_r2"] = signature_table(
        sig_replay, outcome.nominal, sig_model, outcome.controller
    )
    for k, r in enumerate(outcome.rounds, start=1):
        fig = candidates_figure(
            [c.name for c in r.candidates],
            [c.score for c in r.candidates],
            r.start_cost_val,
            outcome.noise_cost,
            [r.added] if r.added else [],
            title=f"round {k}: held-out score (noise-variance units, lower is better)",
        )
        paths[f"candidates_{k}"] = save(fig, out_dir / f"candidates_{k}.png")
    paths["summary"] = write_json(out_dir / "summary.json", summary)
    paths["report"] = out_dir / "report.md"
    write_text(paths["report"], report_markdown(outcome, replay, summary, paths, data_path))
    return paths, summary


def write_calibration(result: Any, out_dir: str | Path, data_label: str) -> dict[str, Path]:
    """Write a :class:`~fuzzyservo.calibration.CalibrationResult` into ``out_dir``
    (``data_label`` names the data in the files); returns the files by role."""
    paths, _ = write_calibration_report(
        result.outcome, result.replay, data_label, Path(out_dir), result.skipped
    )
    return paths


__all__ = ["write_calibration", "write_calibration_report"]
