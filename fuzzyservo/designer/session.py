"""One designer session: the controller being edited, the rig and scenario, and the runs.

No web code here: the page (:mod:`.app`) calls these methods and draws what they
return. The controller is kept as the mapping a controller file holds (``kind:
fuzzy``), so every edit is an edit of that mapping, every controller the page shows
is built by :func:`~fuzzyservo.io.controllers.controller_from_data` (and so checked
exactly as a file would be), and saving writes the mapping as it is.
"""

from __future__ import annotations

import copy
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from fuzzyservo.controllers.fuzzy import FuzzyController
from fuzzyservo.controllers.fuzzy.system import NO_TERM, term_index
from fuzzyservo.designer.files import Folders
from fuzzyservo.display import metric_units, trial_counts_text
from fuzzyservo.errors import ConfigError
from fuzzyservo.io.controllers import read_controller_data
from fuzzyservo.metrics import METRIC_NAMES, result_metrics
from fuzzyservo.simulation import SimResult, simulate

#: the controllers every run is compared with (seed 002: P K = 10 and FLC2)
BASELINES = ("p_k10", "flc2_reshaped")
#: the parts of a controller mapping that are variables, and their places in the system
ROLES = ("input", "rate", "output")
#: the seven-term design's numbers the sliders move, per variable
DESIGN_KEYS = ("increments", "reshape", "translate")
TOP_TRIALS = 10


@dataclass
class Run:
    """A simulated controller: its result, aggregate metrics and the time the run took."""

    name: str
    result: SimResult
    metrics: dict[str, float]
    seconds: float = 0.0


@dataclass
class Trial:
    """A complete trial of a study: number, objective values, parameters, status."""

    number: int
    values: list[float]
    params: dict[str, float]
    status: str


@dataclass
class StudyView:
    """A study opened from its storage: the spec, the URL and its best trials."""

    spec: Any
    url: str
    trials: list[Trial]
    complete: int
    counts: str = ""  # asked / complete / pruned / failed, as every output words them


@dataclass
class Session:
    """State of one browser session (see the module docstring)."""

    folders: Folders
    rig_path: Path
    data: dict[str, Any]
    source: str
    scenario: str | None = None
    rig: Any = None
    controller: FuzzyController | None = None
    baselines: dict[str, FuzzyController] = field(default_factory=dict)
    compared: dict[str, Any] = field(default_factory=dict)
    #: seven-term designs of variables whose breakpoints were edited since (to go back to)
    designs: dict[str, dict[str, Any]] = field(default_factory=dict)
    _baseline_runs: dict[tuple[str, str], list[Run]] = field(default_factory=dict)
    _compared_runs: dict[tuple, list[Run]] = field(default_factory=dict)

    # ------------------------------------------------------------------ building
    @classmethod
    def open(cls, folders: Folders, rig_path: Path, controller_path: Path) -> Session:
        """A session on a rig file and a controller file (YAML or .fis)."""
        session = cls(folders, Path(rig_path), {}, "")
        session.set_rig(rig_path)
        session.data = read_controller_data(controller_path)
        session.source = str(controller_path)
        session.controller = build(session.data, session.source)
        session.baselines = load_baselines(folders)
        return session

    def set_rig(self, rig_path: Path, scenario: str | None = None) -> None:
        from fuzzyservo.io.rigs import load_rig

        rig = load_rig(rig_path)
        if scenario is not None and scenario not in rig.scenarios:
            raise ConfigError(
                f"unknown scenario {scenario!r}; this rig has {', '.join(rig.scenarios)}",
                file=str(rig_path),
                key="scenarios",
            )
        self.rig, self.rig_path = rig, Path(rig_path)
        self.scenario = scenario or next(iter(rig.scenarios))

    def set_scenario(self, scenario: str) -> None:
        self.set_rig(self.rig_path, scenario)

    def apply(self, data: dict[str, Any]) -> FuzzyController:
        """Make ``data`` the edited controller; on a ``ConfigError`` nothing changes."""
        controller = build(data, self.source)
        self.data, self.controller = data, controller
        return controller

    def edited(self) -> dict[str, Any]:
        """A deep copy of the mapping, to change and :meth:`apply`."""
        return copy.deepcopy(self.data)

    # ------------------------------------------------------------------ variables
    def roles(self) -> list[str]:
        return [r for r in ROLES if r in self.data]

    def variable(self, role: str):
        system = self.controller.system
        if role == "output":
            return system.output
        return system.inputs[0 if role == "input" else 1]

    def design(self, role: str) -> dict[str, Any] | None:
        """The seven-term design numbers of a variable, or ``None`` when it has explicit terms."""
        node = self.data.get(role, {})
        if "terms" in node:
            return None
        from fuzzyservo.controllers.fuzzy.design import UNIFORM_INCREMENTS

        return {
            "range": list(node["range"]),
            "increments": list(node.get("increments", UNIFORM_INCREMENTS)),
            "reshape": float(node.get("reshape", 1.0)),
            "translate": float(node.get("translate", 0.0)),
        }

    def set_design(self, role: str, key: str, value: float, index: int | None = None) -> None:
        """Move one seven-term number: ``increments[index]``, ``reshape`` or ``translate``."""
        if key not in DESIGN_KEYS:
            raise ConfigError(f"unknown design number {key!r}; choose one of {list(DESIGN_KEYS)}")
        if self.design(role) is None:
            raise ConfigError(
                f"{role} has explicit terms; edit its breakpoints, or go back to the seven-term design"
            )
        self.set_number(f"{role}.{key}" + (f"[{index}]" if key == "increments" else ""), value)

    def set_gain(self, which: str, value: float) -> None:
        self.set_number(f"gains.{which}", value)

    def set_number(self, path: str, value: float) -> None:
        """Change one searchable number by its parameter path (``input.increments[3]``,
        ``gains.output``: the names a study searches, :meth:`FuzzyDesign.params`) through
        the design itself (:meth:`FuzzyDesign.with_params`): no mapping is copied and
        parsed again. On a bad value nothing changes (a ``ConfigError``)."""
        from fuzzyservo.io.fuzzy import design_data

        if self.controller.design is None:
            raise ConfigError(f"{self.controller.name} has no design whose {path} to move")
        try:
            controller = self.controller.with_params(**{path: float(value)})
        except ValueError as exc:
            raise ConfigError(str(exc)) from None
        self.data, self.controller = design_data(controller.design), controller

    def set_breakpoints(self, role: str, term: str, params: list[float]) -> None:
        """Give one term new parameters; the variable is written with explicit terms from then on."""
        var = self.variable(role)
        data = self.edited()
        terms = {t.name: [t.shape, [float(p) for p in t.params]] for t in var.terms}
        if term not in terms:
            raise ConfigError(f"{role} has no term {term!r}; its terms are {list(terms)}")
        terms[term][1] = [float(p) for p in params]
        data[role] = {"name": var.name, "range": [var.low, var.high], "terms": terms}
        design = self.data[role] if "terms" not in self.data[role] else None
        self.apply(data)
        if design is not None:
            self.designs[role] = design

    def restore_design(self, role: str) -> None:
        """Undo breakpoint edits: the variable's seven-term design as it was before them."""
        if role not in self.designs:
            raise ConfigError(f"{role} had no seven-term design in this session")
        data = self.edited()
        data[role] = copy.deepcopy(self.designs[role])
        self.apply(data)
        del self.designs[role]

    def set_rules(self, lines: list[str]) -> None:
        data = self.edited()
        data["rules"] = [str(line) for line in lines if str(line).strip()]
        self.apply(data)

    def rule_lines(self) -> list[str]:
        from fuzzyservo.io.fuzzy import rule_text

        system = self.controller.system
        return [rule_text(system, r) for r in system.rules]

    def rule_grid(self) -> list[list[str]] | None:
        """Output term per input term (one input: one column; two: error rows × rate columns).

        ``""`` where no rule has that antecedent; ``None`` when the rule base is not such
        a grid (OR, NOT, "no condition", weights or two rules on one cell): edit the lines.
        """
        system = self.controller.system
        shape = [len(v.terms) for v in system.inputs] + [1]
        grid = [["" for _ in range(shape[1])] for _ in range(shape[0])]
        for rule in system.rules:
            ant = rule.antecedent
            if rule.weight != 1.0 or any(i == NO_TERM or term_index(i)[1] for i in ant):
                return None
            if len(ant) == 2 and rule.connective != "and":
                return None
            i, j = ant[0], ant[1] if len(ant) == 2 else 0
            k, negated = term_index(rule.consequent)
            if grid[i][j] or negated or rule.consequent == NO_TERM:
                return None
            grid[i][j] = system.output.terms[k].name
        return grid

    def set_rule_cell(self, row: int, column: int, term: str) -> None:
        """Set one cell of :meth:`rule_grid` (``""`` removes the rule) and rebuild the rules."""
        grid = self.rule_grid()
        if grid is None:
            raise ConfigError(
                "the rule base is not a table (OR, NOT or weights); edit the rule lines"
            )
        grid[row][column] = term
        system = self.controller.system
        names = [[t.name for t in v.terms] for v in system.inputs]
        lines = []
        for i, row_terms in enumerate(grid):
            for j, out in enumerate(row_terms):
                if not out:
                    continue
                ant = names[0][i] if len(names) == 1 else f"{names[0][i]} and {names[1][j]}"
                lines.append(f"{ant} -> {out}")
        self.set_rules(lines)

    # ------------------------------------------------------------------ static maps
    def input_span(self) -> list[tuple[float, float]]:
        """The loop error (and rate) ranges the controller sees: variable range / input gain."""
        c = self.controller
        gains = (c.input_gain, c.rate_gain)
        spans = []
        for var, g in zip(c.system.inputs, gains, strict=False):
            a, b = sorted((var.low / g, var.high / g))
            spans.append((a, b))
        return spans

    def curve(self, n: int = 401) -> tuple[np.ndarray, ...]:
        """``(e, u)`` for one input, ``(e, de, U)`` on a grid for two (loop units, before limits)."""
        spans = self.input_span()
        e = np.linspace(*spans[0], n)
        if len(spans) == 1:
            return e, self.controller.curve(e)
        m = 81
        e = np.linspace(*spans[0], m)
        de = np.linspace(*spans[1], m)
        E, D = np.meshgrid(e, de, indexing="xy")
        return e, de, self.controller.curve(E, D)

    def firing(self, e: float, de: float = 0.0) -> tuple[list[str], np.ndarray, float]:
        """Rule labels, firing strengths (weights included) and the command at loop error ``e``."""
        from fuzzyservo.controllers.fuzzy.system import reference_firing

        c = self.controller
        point = [c.input_gain * e]
        if len(c.system.inputs) == 2:
            point.append(c.rate_gain * de)
        strengths = reference_firing(c.system, np.array([point]))[0]
        u = float(c.curve(np.array([e]), np.array([de]))[0])
        return self.rule_lines(), strengths, u

    # ------------------------------------------------------------------ runs
    def run(self, controller=None, name: str | None = None) -> Run:
        """Simulate a controller (default: the edited one) on the rig and scenario."""
        controller = self.controller if controller is None else controller
        t0 = time.perf_counter()
        result = simulate(self.rig, controller, self.scenario)
        seconds = time.perf_counter() - t0
        return Run(name or controller.name, result, result_metrics(result).aggregate, seconds)

    def baseline_runs(self) -> list[Run]:
        key = (str(self.rig_path), self.scenario)
        if key not in self._baseline_runs:
            self._baseline_runs[key] = [self.run(c, label) for label, c in self.baselines.items()]
        return self._baseline_runs[key]

    def compared_runs(self) -> list[Run]:
        """The study trials shown next to the edited controller (run once per rig and scenario)."""
        key = (str(self.rig_path), self.scenario, *((k, id(c)) for k, c in self.compared.items()))
        if key not in self._compared_runs:
            self._compared_runs = {key: [self.run(c, label) for label, c in self.compared.items()]}
        return self._compared_runs[key]

    # ------------------------------------------------------------------ files
    def open_file(self, name: str) -> None:
        """Open a controller file (YAML or .fis) inside the designer's folders."""
        path = self.folders.controller_path(name)
        data = read_controller_data(path)
        controller = build(data, str(path))
        self.data, self.controller, self.source = data, controller, str(path)
        self.designs = {}

    def open_upload(self, filename: str, content: bytes) -> None:
        """Open a controller file the browser sent (read from memory; nothing is written)."""
        from fuzzyservo.io.controllers import controller_data_from_text

        text = content.decode("utf-8", errors="replace")
        data = controller_data_from_text(text, filename)
        controller = build(data, filename)
        self.data, self.controller, self.source = data, controller, filename
        self.designs = {}

    def save_yaml(self, name: str) -> Path:
        """Write the mapping as a controller file inside the output folder."""
        from fuzzyservo.io.controllers import write_controller_file

        path = self.folders.controller_path(name, write=True)
        if path.suffix.lower() == ".fis":
            raise ConfigError("use 'Save .fis' for a .fis file", file=name)
        return write_controller_file(self.data, path)

    def save_fis(self, name: str) -> Path:
        """Write the inference system as a MATLAB .fis file inside the output folder."""
        from fuzzyservo.io.fuzzy_files import write_fis

        path = self.folders.controller_path(name, write=True)
        if path.suffix.lower() != ".fis":
            raise ConfigError("a .fis file name ends in .fis", file=name)
        return write_fis(self.controller.system, path)

    def yaml_text(self) -> str:
        from fuzzyservo.io.controllers import controller_yaml

        return controller_yaml(self.data)

    # ------------------------------------------------------------------ studies
    def study_files(self) -> list[str]:
        return self.folders.names("studies")

    def default_storage(self, study: str) -> str:
        """Where ``fuzzyservo tune`` keeps the study: its ``storage``, else
        out/<name>/<name>.db of the working folder (where ``tune`` run there writes it; never
        the shipped files' folder, whose ``out/`` is another run's)."""
        spec = self._study_spec(study)
        if spec.storage:
            return spec.storage
        base = self.folders.work or self.folders.project
        return f"sqlite:///{base / 'out' / spec.name / f'{spec.name}.db'}"

    def _study_spec(self, study: str):
        from fuzzyservo.io.studies import load_study

        path = self.folders.find("studies", study)
        if path is None:
            raise ConfigError(f"no study named {study!r}; known: {', '.join(self.study_files())}")
        return load_study(path)

    def open_study(self, study: str, url: str | None = None, top: int = TOP_TRIALS) -> StudyView:
        """The best complete trials of a study's storage (read only: an absent database is an error)."""
        spec = self._study_spec(study)
        given = (url or self.default_storage(study)).strip()
        named = (spec.storage,) if spec.storage else ()
        url, path = self.folders.storage_url(given, named, study=study)
        from fuzzyservo.tuning.storage import read_trials

        stored = read_trials(spec.name, url, sqlite_file=path, top=top)
        best = [Trial(t.number, list(t.values), t.params, t.status) for t in stored.best]
        return StudyView(spec, url, best, stored.complete, trial_counts_text(**stored.counts))

    def trial_data(self, view: StudyView, trial: Trial) -> dict[str, Any]:
        """The controller mapping of a trial: the study's template with the trial's numbers."""
        from fuzzyservo.io.controllers import controller_data

        name = f"{view.spec.name}_trial{trial.number}"
        return controller_data(view.spec.trial_controller(trial.params, name))

    def compare_trials(self, view: StudyView, trials: list[Trial]) -> None:
        """Show these trials' controllers next to the edited one (replaces earlier ones)."""
        self.compared = {
            f"#{t.number}": view.spec.trial_controller(
                t.params, f"{view.spec.name}_trial{t.number}"
            )
            for t in trials
        }

    def load_trial(self, view: StudyView, trial: Trial) -> None:
        data = self.trial_data(view, trial)
        self.apply(data)
        self.source = f"{view.spec.name} trial {trial.number}"
        self.designs = {}


# ---------------------------------------------------------------------- helpers
def build(data: dict[str, Any], source: str) -> FuzzyController:
    """The fuzzy controller a mapping describes (checked as a file would be).

    The kind is checked first: the designer builds fuzzy controllers only, so no other
    kind's files (an FMU's native library above all) are opened for a page."""
    from fuzzyservo.io.controllers import controller_from_data

    kind = data.get("kind") if isinstance(data, dict) else None
    if kind != "fuzzy":
        raise ConfigError(
            f"is a {str(kind)[:40]} controller; the designer edits 'kind: fuzzy' files "
            "and opens no other kind's files",
            file=source,
        )
    return controller_from_data(data, source)  # kind: fuzzy builds a FuzzyController


def load_baselines(folders: Folders) -> dict[str, Any]:
    """P K=10 and FLC2 from the project's studies/controllers (those found)."""
    from fuzzyservo.io.controllers import load_controller

    found = {}
    for name in BASELINES:
        path = folders.find("studies/controllers", name)
        if path is not None:
            controller = load_controller(path)
            found[controller.name] = controller
    return found


def fmt(value: float | None) -> str:
    """A metric for the table: 4 significant digits, n/a for NaN, 0 for rounding noise."""
    if value is None or not math.isfinite(value):
        return "n/a"
    if abs(value) < 1e-9:
        return "0"
    return f"{value:.4g}" if 1e-3 <= abs(value) < 1e5 else f"{value:.3e}"


def metrics_rows(runs: list[Run]) -> list[list[str]]:
    """One row per metric (name, then one value per run in its display unit, formatted)."""
    units = metric_units(runs[0].result)
    return [[m, *(fmt(units.value(m, r.metrics.get(m))) for r in runs)] for m in METRIC_NAMES]
