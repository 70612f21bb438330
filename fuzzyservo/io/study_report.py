"""What a finished study leaves in its output folder: the best controller, a summary, figures, a report.

:func:`write_best_controller` and :func:`write_study_files` write (the workflow that
scores the written controller between them is :func:`fuzzyservo.workflows.write_study_report`)

- ``best_controller.yaml``: the template with the best parameters, a controller file
  ``fuzzyservo simulate``/``compare`` take as it is (and ``best_controller.fis`` for a
  fuzzy controller, for MATLAB's Fuzzy Logic Designer);
- ``summary.json``: the numbers (NaN and infinities as ``null``);
- PNG figures: responses of baseline and best per scenario, trial history,
  importances, Pareto front, control curve and membership functions before/after;
- ``report.md``: all of it on one page, figures linked relatively.

The best controller file is read back and scored again (:mod:`fuzzyservo.tuning.report`,
where every number is computed; this module only renders and writes) before the report
claims it reproduces the study's objective. matplotlib is imported only inside
:func:`write_study_files`.
"""

from __future__ import annotations

import math
from pathlib import Path

from fuzzyservo.atomic import ensure_folder, write_text
from fuzzyservo.controllers.base import Controller
from fuzzyservo.display import (
    MetricUnits,
    metric_units,
)
from fuzzyservo.io.jsonfile import write_json
from fuzzyservo.tuning.outcome import (
    StudyOutcome,
    best_trial_number,
)
from fuzzyservo.tuning.report import (
    StudyReport,
    best_description,
)
from fuzzyservo.tuning.report_markdown import file_part, report_markdown
from fuzzyservo.tuning.uncertainty.robust import Comparison
from fuzzyservo.tuning.uncertainty.robustness import SUMMARY_METRICS

CONTROLLER_FILE = "best_controller.yaml"
FIS_FILE = "best_controller.fis"
SUMMARY_FILE = "summary.json"
REPORT_FILE = "report.md"


def write_best_controller(best: Controller, outcome: StudyOutcome, out_dir: Path) -> Path:
    """The best trial's controller as a file users run (``best_controller.yaml``), its
    description saying where it comes from and what it scored."""
    from fuzzyservo.io.controllers import controller_data, write_controller_file

    data = controller_data(best)
    data["description"] = best_description(outcome, best_trial_number(outcome))
    return write_controller_file(data, ensure_folder(out_dir) / CONTROLLER_FILE)


def write_study_files(report: StudyReport, out_dir: Path, controller: Path) -> dict[str, Path]:
    """Write the rest of a study's report beside its best controller's file
    ``controller``: the ``.fis`` (fuzzy controllers), the figures, ``summary.json``
    (``report.to_dict()``) and ``report.md``. Returns the files by role: ``controller``,
    ``fis``, ``summary``, ``report``, ``history``, ``importances`` (when computed),
    ``pareto`` (Pareto studies), ``curve``, ``membership_before``, ``membership_after``
    (fuzzy), ``response_<scenario>`` per scenario and ``check`` (a robust study compared
    on fresh plants: the Monte Carlo distributions)."""
    from fuzzyservo.controllers.fuzzy.controller import FuzzyController

    out_dir = ensure_folder(out_dir)
    outcome, best = report.outcome, report.best_controller
    paths: dict[str, Path] = {"controller": controller}
    fuzzy = isinstance(best, FuzzyController)
    if fuzzy:
        from fuzzyservo.io.fuzzy_files import write_fis

        paths["fis"] = write_fis(best.system, out_dir / FIS_FILE)
    paths.update(_figures(outcome, out_dir, best, fuzzy))
    units = metric_units(outcome.spec.rig)
    if report.comparison is not None:
        paths["check"] = _check_figure(report.comparison, out_dir, units)
    paths["summary"] = write_json(out_dir / SUMMARY_FILE, report.to_dict())
    paths["report"] = out_dir / REPORT_FILE
    links = {role: path.relative_to(out_dir).as_posix() for role, path in paths.items()}
    write_text(paths["report"], report_markdown(report, links))
    return paths


def _check_figure(comparison: Comparison, out_dir: Path, units: MetricUnits) -> Path:
    from fuzzyservo import plots

    values = {
        m: {mc.controller: mc.values(m) * units.factor(m) for mc in comparison.monte_carlo}
        for m in SUMMARY_METRICS
    }
    fig = plots.distribution_figure(values, {m: units.unit(m) for m in SUMMARY_METRICS})
    return plots.save(fig, out_dir / "check.png")


# -- figures ---------------------------------------------------------------------------


def _figures(outcome: StudyOutcome, out_dir: Path, best_controller, fuzzy: bool) -> dict[str, Path]:
    from fuzzyservo import plots

    spec = outcome.spec
    paths: dict[str, Path] = {}
    for scenario in spec.scenarios:
        runs = [
            r
            for r in (outcome.baseline.results.get(scenario), outcome.best.results.get(scenario))
            if r is not None
        ]
        if runs:
            key = f"response_{file_part(scenario)}"
            paths[key] = plots.save(plots.response_figure(runs), out_dir / f"{key}.png")
    if fuzzy:
        from fuzzyservo.controllers.fuzzy.controller import FuzzyController

        template = spec.template
        one_input = len(best_controller.system.inputs) == 1
        compare = (
            [template]
            if isinstance(template, FuzzyController)
            and one_input
            and len(template.system.inputs) == 1
            and template.form == best_controller.form
            else []
        )
        fig = plots.control_curve_figure(best_controller, compare=compare)
        paths["curve"] = plots.save(fig, out_dir / "curve.png")
        if isinstance(template, FuzzyController):
            fig = plots.membership_figure(template)
            paths["membership_before"] = plots.save(fig, out_dir / "membership_before.png")
        fig = plots.membership_figure(best_controller)
        paths["membership_after"] = plots.save(fig, out_dir / "membership_after.png")
    names = list(spec.objective.pareto) or ["objective"]
    if outcome.history:
        fig = plots.history_figure(
            outcome.history, names, title=f"{spec.name}: {spec.objective.describe()}"
        )
        paths["history"] = plots.save(fig, out_dir / "history.png")
    if outcome.importances:
        target = f" (of {names[0]})" if spec.objective.pareto else ""
        fig = plots.importance_figure(
            outcome.importances, title=f"{spec.name}: parameter importances{target}"
        )
        paths["importances"] = plots.save(fig, out_dir / "importances.png")
    if spec.objective.pareto and outcome.pareto:
        measured = [
            h["values"]
            for h in outcome.history
            if h["status"] == "ok" and all(math.isfinite(v) for v in h["values"])
        ]
        fig = plots.pareto_figure(
            measured,
            [p["values"] for p in outcome.pareto],
            names,
            baseline=outcome.baseline.values if outcome.baseline.status == "ok" else None,
            best=outcome.best.values,
            title=f"{spec.name}: objectives of every trial, Pareto front in red",
        )
        paths["pareto"] = plots.save(fig, out_dir / "pareto.png")
    return paths
