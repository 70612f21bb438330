"""fuzzyservo: design, simulate and tune fuzzy controllers for electro-hydraulic servo systems.

The public API is small and imported lazily, so ``import fuzzyservo`` pulls in neither
YAML, matplotlib nor optuna::

    from fuzzyservo import load_rig, load_controller, simulate

    rig = load_rig("dinca_cylinder")   # a shipped rig by name, or a path
    p_k10 = load_controller("p_k10")
    result = simulate(rig, p_k10, "pulses")

Rigs, controllers and studies can also be built in code (``compose_rig``, ``P``,
``PI``, ``FuzzyDesign``, ``Study``), then simulated, compared, tuned and calibrated
(``simulate``, ``compare``, ``tune``, ``calibrate``). Every command of the command line
is one function here (``compare``, ``margins``, ``frequency``, ``robustness``,
``calibrate``, ``benchmark``, ``export``, ``evaluate``, ``fit_valve``) returning a result
object: ``print(result)`` shows what the command prints, ``result.to_json()`` what its
``--json`` writes. JSON numbers are SI; ``METRIC_UNITS`` is the units schema of the
metrics (``{y}``: the rig's output unit), and each JSON file names its units.
"""

from __future__ import annotations

from typing import Any

__version__ = "0.1.0"

_LAZY = {
    "load_rig": ("fuzzyservo.io.rigs", "load_rig"),
    "load_controller": ("fuzzyservo.io.controllers", "load_controller"),
    "load_study": ("fuzzyservo.io.studies", "load_study"),
    "read_measured": ("fuzzyservo.io.measured", "read_measured"),
    "read_rig_data": ("fuzzyservo.io.measured", "read_rig_data"),
    "Rig": ("fuzzyservo.rig", "Rig"),
    "Scenario": ("fuzzyservo.rig", "Scenario"),
    "LinearSensor": ("fuzzyservo.rig", "LinearSensor"),
    "Actuator": ("fuzzyservo.rig", "Actuator"),
    "compose_rig": ("fuzzyservo.rig", "compose_rig"),
    "component_types": ("fuzzyservo.rig", "component_types"),
    "Controller": ("fuzzyservo.controllers.base", "Controller"),
    "P": ("fuzzyservo.controllers.classical", "P"),
    "PI": ("fuzzyservo.controllers.classical", "PI"),
    "PIDF": ("fuzzyservo.controllers.classical", "PIDF"),
    "FuzzyController": ("fuzzyservo.controllers.fuzzy", "FuzzyController"),
    "FuzzyDesign": ("fuzzyservo.controllers.fuzzy.design", "FuzzyDesign"),
    "Study": ("fuzzyservo.tuning.spec", "Study"),
    "Parameter": ("fuzzyservo.tuning.spec", "Parameter"),
    "Objective": ("fuzzyservo.tuning.spec", "Objective"),
    "simulate": ("fuzzyservo.simulation", "simulate"),
    "compare": ("fuzzyservo.analysis.compare", "compare"),
    "ComparisonResult": ("fuzzyservo.analysis.compare", "ComparisonResult"),
    "margins": ("fuzzyservo.analysis.margins", "margins"),
    "Margins": ("fuzzyservo.analysis.margins", "Margins"),
    "frequency": ("fuzzyservo.analysis.frequency", "frequency_response"),
    "FrequencyResponse": ("fuzzyservo.analysis.frequency", "FrequencyResponse"),
    "robustness": ("fuzzyservo.tuning.uncertainty.montecarlo", "robustness"),
    "RobustnessResult": ("fuzzyservo.tuning.uncertainty.montecarlo", "RobustnessResult"),
    "tune": ("fuzzyservo.tuning", "tune"),
    "study_report": ("fuzzyservo.tuning.report", "study_report"),
    "StudyReport": ("fuzzyservo.tuning.report", "StudyReport"),
    "write_study_report": ("fuzzyservo.workflows", "write_study_report"),
    "calibrate": ("fuzzyservo.calibration", "calibrate"),
    "CalibrationResult": ("fuzzyservo.calibration", "CalibrationResult"),
    "write_calibration": ("fuzzyservo.io.calibration_report", "write_calibration"),
    "benchmark": ("fuzzyservo.bench", "benchmark"),
    "BenchReport": ("fuzzyservo.bench", "BenchReport"),
    "describe_fuzzy": ("fuzzyservo.controllers.fuzzy.describe", "describe_fuzzy"),
    "evaluate": ("fuzzyservo.workflows", "evaluate"),
    "load_reproduction": ("fuzzyservo.io.reproduction", "load_reproduction"),
    "Reproduction": ("fuzzyservo.analysis.reproduction", "Reproduction"),
    "export": ("fuzzyservo.workflows", "export"),
    "fit_valve": ("fuzzyservo.workflows", "fit_valve"),
    "SimResult": ("fuzzyservo.simulation", "SimResult"),
    "simulate_reference": ("fuzzyservo.simulation.reference", "simulate_reference"),
    "result_metrics": ("fuzzyservo.metrics", "result_metrics"),
    "METRIC_UNITS": ("fuzzyservo.metrics", "METRIC_UNITS"),
    "ConfigError": ("fuzzyservo.errors", "ConfigError"),
}

__all__ = sorted(_LAZY)


def __dir__() -> list[str]:
    """The API only (what ``from fuzzyservo import *`` gives), and the version."""
    return [*__all__, "__version__"]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        module, attr = _LAZY[name]
        return getattr(importlib.import_module(module), attr)
    raise AttributeError(f"module 'fuzzyservo' has no attribute {name!r}")
