"""A calibration's files: the calibrated rig, figures, ``report.md`` and ``summary.json``.

The numbers and the report's text come from :mod:`fuzzyservo.calibration.summary` and
:mod:`fuzzyservo.calibration.report`; this module only draws and writes them (files are
the edge of the package).
"""

from __future__ import annotations

import datetime as _dt
from pathlib import Path

from fuzzyservo.atomic import ensure_folder, write_text
from fuzzyservo.calibration import CalibrationResult
from fuzzyservo.calibration.joint import split_field
from fuzzyservo.calibration.report import ZOOM_S, report_markdown
from fuzzyservo.components.effects import LIBRARY
from fuzzyservo.display import display_scale


def write_calibration(
    result: CalibrationResult, out_dir: str | Path, data_label: str
) -> dict[str, Path]:
    """Write a :class:`~fuzzyservo.calibration.CalibrationResult` into ``out_dir``: the
    calibrated rig, figures, ``report.md`` and ``summary.json`` (``result.to_dict()`` and
    the calibrated rig's path); ``data_label`` names the data in the files. Returns the
    files by role."""
    from fuzzyservo.io.jsonfile import write_json
    from fuzzyservo.io.rigs import write_calibrated_rig
    from fuzzyservo.plots import candidates_figure, overlay_figure, residual_figure, save

    outcome, replay = result.outcome, result.replay
    out_dir = ensure_folder(Path(out_dir))
    rig = outcome.calibrated
    paths: dict[str, Path] = {}
    stamp = _dt.date.today().isoformat()
    origin = f"fuzzyservo calibrate on {Path(data_label).name} ({stamp})"
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
    summary = result.to_dict()
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
    fit_before = summary.get("fit_nominal_pct", summary["fit_before_pct"])
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
    for label, fitted in (("before", before), ("after", after)):
        input_name, band, found = result.correlations[label]
        res = {channel: measured[channel] - fitted[channel] for channel in replay.channels}
        fig = residual_figure(t, res, units, {c: k.acf for c, k in found.items()},
                              {c: k.xcf for c, k in found.items()}, band, input_name,
                              title=f"residuals {label}: {title}")  # fmt: skip
        paths[f"residuals_{label}"] = save(fig, out_dir / f"residuals_{label}.png")
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
    write_text(paths["report"], report_markdown(outcome, replay, summary, paths, data_label))
    return paths


__all__ = ["write_calibration"]
