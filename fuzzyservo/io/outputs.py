"""Result objects to files: signals as CSV, figures as PNG (drawn by :mod:`fuzzyservo.plots`).

JSON is :func:`fuzzyservo.io.jsonfile.write_json` (a result object or a dict). Every file
is written whole or not at all (:mod:`fuzzyservo.atomic`).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fuzzyservo.atomic import atomic_write, ensure_folder

if TYPE_CHECKING:
    from fuzzyservo.analysis.compare import ComparisonResult
    from fuzzyservo.analysis.frequency import FrequencyResponse
    from fuzzyservo.controllers.fuzzy import FuzzyController
    from fuzzyservo.simulation import SimResult
    from fuzzyservo.tuning.uncertainty.montecarlo import RobustnessResult


def write_signals_csv(path: str | Path, result: SimResult) -> Path:
    """Every signal of a run, one column each (:meth:`SimResult.columns`), 9 digits."""
    cols = result.columns()
    data = np.column_stack(list(cols.values()))
    with atomic_write(path) as fh:
        np.savetxt(fh, data, delimiter=",", header=",".join(cols), comments="", fmt="%.9g")
    return Path(path)


def save_comparison(comparison: ComparisonResult, out: str | Path) -> list[Path]:
    """The runs' response figure and each run's signals (CSV) into the folder ``out``.

    Files are named after the rig, the scenario and the controllers
    (``dinca_cylinder_pulses_p_k10+flc2_reshaped_response.png``), so comparing other
    controllers on the same scenario writes beside an earlier comparison, not over it."""
    from fuzzyservo import plots

    out = ensure_folder(out)
    stem = f"{comparison.rig}_{comparison.scenario}"
    fig = plots.response_figure(list(comparison.values()))
    paths = [plots.save(fig, out / f"{stem}_{'+'.join(comparison)}_response.png")]
    for name, r in comparison.items():
        paths.append(write_signals_csv(out / f"{stem}_{name}.csv", r))
    return paths


def save_bode(response: FrequencyResponse, out: str | Path) -> Path:
    """The Bode plot of a closed-loop frequency response into the folder ``out``."""
    from fuzzyservo.plots import bode_figure, save

    return save(bode_figure(response), Path(out) / f"bode_{response.rig}_{response.controller}.png")


def save_fuzzy_figures(
    controller: FuzzyController, out: str | Path, source: str | None = None
) -> list[Path]:
    """Overview, membership functions and control curve (or surface) of a Mamdani system;
    ``source`` names it in the error a Sugeno system raises (default: its name)."""
    from fuzzyservo import plots
    from fuzzyservo.errors import ConfigError

    if controller.system.type == "sugeno":
        raise ConfigError(
            "is a Sugeno system: its output terms are functions, not sets, so there are no "
            "membership plots to draw; use `fuzzyservo evaluate` for its values",
            file=source or controller.name,
        )
    figures = {
        "overview": plots.fuzzy_overview_figure(controller),
        "membership": plots.membership_figure(controller),
        "curve": plots.control_curve_figure(controller),
    }
    return [plots.save(f, Path(out) / f"{controller.name}_{k}.png") for k, f in figures.items()]


def save_robustness(result: RobustnessResult, out: str | Path) -> list[Path]:
    """The metric distributions and, per controller, its worst sample's responses."""
    from fuzzyservo import plots
    from fuzzyservo.tuning.uncertainty.robustness import SUMMARY_METRICS

    out = ensure_folder(out)
    units = {m: result.units.unit(m) for m in SUMMARY_METRICS}
    fig = plots.distribution_figure(result.distributions(), units)
    paths = [plots.save(fig, out / f"{result.rig}_robustness.png")]
    for controller, (label, runs) in result.worst_runs().items():
        for scenario, r in runs.items():
            fig = plots.response_figure([r])
            fig.suptitle(f"{controller}: worst {label}", fontsize=8)
            paths.append(plots.save(fig, out / f"{result.rig}_{controller}_worst_{scenario}.png"))
    return paths
