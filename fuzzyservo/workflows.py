"""The workflows that read files, compute and write files, one function each, so that
:mod:`fuzzyservo.io` only reads and writes and the command line only parses and prints:
a tuned study's report (:func:`write_study_report`), a fuzzy system evaluated on a table
of inputs (:func:`evaluate`, what ``evalfis`` does), the seed-003 valve network trained
on valve data (:func:`fit_valve`) and a fuzzy controller or inference system written for
other tools (:func:`export`, what ``fuzzyservo export`` writes): MATLAB ``.fis``,
IEC 61131-7 FCL, C99, IEC 61131-3 Structured Text and FMI co-simulation FMUs, with the
lookup table's and single precision's errors measured. A controller (a YAML file, or a
``.fis``/FCL file with a fuzzyservo control-law comment) is exported with its control
law: ``.fis`` and FCL carry it in a comment, C, ST and the FMU compute it. Any other
``.fis`` or FCL file is an inference system with any number of inputs and outputs: its
C and FMU compute what ``evaluate`` does."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from fuzzyservo.atomic import write_files, write_text
from fuzzyservo.components.nn_fit import NetworkFit, fit_valve_network
from fuzzyservo.controllers.fuzzy.controller import FuzzyController
from fuzzyservo.controllers.fuzzy.evaluate import evaluate_inputs
from fuzzyservo.controllers.fuzzy.fcl import fcl_names
from fuzzyservo.controllers.fuzzy.fis import law_text
from fuzzyservo.controllers.fuzzy.system import FuzzySystem
from fuzzyservo.errors import ConfigError, DataError, excerpt
from fuzzyservo.io.evaluation import (
    load_exportable,
    load_system,
    read_input_table,
    write_output_table,
)
from fuzzyservo.io.fuzzy_files import write_fcl, write_fis
from fuzzyservo.io.paths import find_file
from fuzzyservo.io.valve_data import read_valve_csv, write_valve_network
from fuzzyservo.limits import lut_problem
from fuzzyservo.results import Result
from fuzzyservo.rig import Rig
from fuzzyservo.tuning.outcome import StudyOutcome
from fuzzyservo.tuning.report import StudyReport, best_controller, study_report


def write_study_report(
    outcome: StudyOutcome,
    out_dir: str | Path,
    *,
    check_samples: int | None = None,
    progress: Callable[[int], object] | None = None,
) -> tuple[StudyReport, dict[str, Path]]:
    """Write a finished study's report into ``out_dir``: the best controller's file,
    read back and scored again (the file, not the in-memory mapping, is what users run;
    :func:`~fuzzyservo.tuning.report.study_report`, with a robust study's comparison on
    ``check_samples`` fresh plants, ``progress(1)`` per plant and controller), then its
    ``.fis``, the figures, ``summary.json`` and ``report.md``
    (:func:`~fuzzyservo.io.study_report.write_study_files`). Returns the report and the
    files by role."""
    from fuzzyservo.io.controllers import load_controller
    from fuzzyservo.io.study_report import write_best_controller, write_study_files

    path = write_best_controller(best_controller(outcome), outcome, Path(out_dir))
    report = study_report(outcome, load_controller(path), check_samples=check_samples,
                          progress=progress)  # fmt: skip
    return report, write_study_files(report, Path(out_dir), path)


@dataclass(frozen=True)
class FuzzyEvaluation(Result):
    """A fuzzy system's outputs for a table of inputs; ``text()`` is the output CSV."""

    system: FuzzySystem
    inputs: np.ndarray
    outputs: np.ndarray
    ignored: tuple[str, ...] = ()
    silent: int = 0

    @property
    def output_names(self) -> list[str]:
        return [v.name for v in self.system.outputs]

    @property
    def notes(self) -> list[str]:
        """Input columns ignored, and outputs where no rule fired (the CLI's stderr lines)."""
        s, out = self.system, []
        if self.ignored:
            out.append(
                f"note: column(s) {list(self.ignored)} are not inputs of {excerpt(s.name)}; ignored"
            )
        if self.silent:
            fallback = "the middle of its range" if s.semantics == "matlab" else "NaN"
            out.append(f"warning: no rule fired for {self.silent} output value(s); each is "
                       f"{fallback} ({s.semantics} semantics)")  # fmt: skip
        return out

    def text(self) -> str:
        rows = (",".join(repr(float(v)) for v in row) for row in self.outputs)
        return "\n".join([",".join(self.output_names), *rows])

    def to_dict(self) -> dict[str, Any]:
        return {"system": self.system.name, "semantics": self.system.semantics,
                "outputs": {n: self.outputs[:, k].tolist() for k, n in enumerate(self.output_names)}}  # fmt: skip

    def write(self, path: str | Path) -> Path:
        """The outputs as a CSV file (:func:`write_output_table`)."""
        return write_output_table(path, self.output_names, self.outputs)


def evaluate(
    system: FuzzySystem | str | Path, inputs: np.ndarray | str | Path, semantics: str | None = None
) -> FuzzyEvaluation:
    """What ``evalfis`` does: ``system`` (or its ``.fis``, ``.fcl`` or controller file) on
    ``inputs`` (an (m, n_inputs) array, or a CSV with a column per input named like it),
    in ``semantics`` (``skfuzzy`` or ``matlab``; default: the system's)."""
    if not isinstance(system, FuzzySystem):
        system = load_system(Path(system))
    if semantics:
        system = dataclasses.replace(system, semantics=semantics)
    ignored: list[str] = []
    if not isinstance(inputs, np.ndarray):
        inputs, ignored = read_input_table(inputs, [v.name for v in system.inputs])
    outputs, silent = evaluate_inputs(system, inputs)
    return FuzzyEvaluation(system, inputs, outputs, tuple(ignored), silent)


@dataclass(frozen=True)
class ValveFitResult(Result):
    """A valve network trained on a valve-data CSV and the file it was written to."""

    fit: NetworkFit
    path: Path

    def text(self) -> str:
        lines = []
        for label, values in (
            ("training", self.fit.train_rms),
            ("validation", self.fit.validation_rms),
        ):
            q_a, q_b = (v * 60e3 for v in values)
            lines.append(f"{label:<10} RMS  Q_A {q_a:.4g} l/min  Q_B {q_b:.4g} l/min")
        return "\n".join([*lines, f"wrote {self.path}"])

    def to_dict(self) -> dict[str, Any]:
        f = self.fit
        return {"file": str(self.path), "train_rms_m3_s": list(f.train_rms),
                "validation_rms_m3_s": list(f.validation_rms), "seed": f.seed,
                "restarts": f.restarts}  # fmt: skip


def fit_valve(
    data: str | Path,
    out: str | Path,
    *,
    seed: int = 0,
    restarts: int = 6,
    progress: Callable[[int], object] | None = None,
) -> ValveFitResult:
    """Train the seed-003 valve network on the valve-data CSV ``data`` (Levenberg-Marquardt,
    best of ``restarts`` seeded ``seed``) and write it to ``out`` as JSON;
    ``progress(k)`` as restarts finish."""
    rows = read_valve_csv(data)
    try:
        fit = fit_valve_network(rows, seed=seed, restarts=restarts, progress=progress)
    except ValueError as exc:
        raise DataError(f"{data}: {exc}") from None
    training = {
        "data": str(data),
        "method": "Levenberg-Marquardt (scipy least_squares, method=lm), best of restarts",
        "seed": fit.seed,
        "restarts": fit.restarts,
        "samples_train": fit.n_train,
        "samples_validation": fit.n_validation,
    }
    write_valve_network(out, fit.weights, fit.train_rms, fit.validation_rms, training)
    return ValveFitResult(fit, Path(out))


@dataclass(frozen=True)
class ExportResult(Result):
    """The files written, a line for each (``text()``), and ``notes`` on what a file
    format leaves out (the command line prints them on stderr)."""

    controller: str
    paths: tuple[Path, ...]
    lines: tuple[str, ...]
    notes: tuple[str, ...] = ()

    def text(self) -> str:
        return "\n".join(self.lines)

    def to_dict(self) -> dict[str, Any]:
        return {"controller": self.controller, "files": [str(p) for p in self.paths],
                "notes": list(self.notes)}  # fmt: skip


def export_file(
    source: str | Path,
    *,
    fis: str | None = None,
    fcl: str | None = None,
    c_dir: str | None = None,
    st: str | None = None,
    fmu: str | None = None,
    fmi: int = 3,
    lut: int | None = None,
    real: str = "double",
    sample_time_s: float = 0.01,
) -> ExportResult:
    """:func:`export` of the controller or system in the file ``source``, the options
    checked first (:class:`ConfigError` naming the option); a rig file or a shipped rig's
    name exports the rig's plant (:func:`export_plant`, ``fmu`` only)."""
    from fuzzyservo.io.rigs import load_rig, rig_file

    if not any([fis, fcl, c_dir, st, fmu]):
        raise ConfigError(
            "give at least one of --fis FILE, --fcl FILE, --c DIR, --st FILE, --fmu FILE"
        )
    if (lut is not None and not (c_dir or st)) or (real == "float" and not c_dir):
        raise ConfigError("--lut shapes the code of --c DIR or --st FILE, --float that of --c")
    if not (math.isfinite(sample_time_s) and sample_time_s > 0):
        raise ConfigError(f"must be > 0 s, got {sample_time_s}", argument="sample_time_s")
    if fmi not in (2, 3):
        raise ConfigError(f"must be 2 or 3, got {fmi}", argument="fmi")
    for option, value in (("fis", fis), ("fcl", fcl), ("st", st), ("fmu", fmu)):
        if value is not None and Path(value).is_dir():
            raise ConfigError(f"--{option} {value}: is a folder; give a file name")
    if c_dir is not None and Path(c_dir).exists() and not Path(c_dir).is_dir():
        raise ConfigError(f"--c {c_dir}: is a file, not a folder; name a folder")
    if fmu is not None and Path(fmu).suffix.lower() != ".fmu":
        raise ConfigError(f"--fmu {fmu}: an FMU file ends in .fmu; e.g. {Path(fmu).stem}.fmu")
    rig = rig_file(source)
    if rig is not None:
        if any([fis, fcl, c_dir, st]) or not fmu:
            raise ConfigError(
                f"{rig}: a rig exports its plant as an FMU; give --fmu FILE.fmu (and --fmi), "
                "and no --fis, --fcl, --c, --st or --lut"
            )
        return export_plant(load_rig(rig), fmu, fmi=fmi)
    target = load_exportable(find_file(str(source), "studies/controllers", "controller"))
    try:
        return export(target, fis=fis, fcl=fcl, c_dir=c_dir, st=st, fmu=fmu, fmi=fmi, lut=lut,
                      real=real, sample_time_s=sample_time_s)  # fmt: skip
    except ValueError as exc:
        if isinstance(exc, ConfigError):
            raise
        raise ConfigError(str(exc), file=str(source)) from None


def export(
    controller: FuzzyController | FuzzySystem,
    *,
    fis: str | Path | None = None,
    fcl: str | Path | None = None,
    c_dir: str | Path | None = None,
    st: str | Path | None = None,
    fmu: str | Path | None = None,
    fmi: int = 3,
    lut: int | None = None,
    real: str = "double",
    sample_time_s: float = 0.01,
) -> ExportResult:
    """Write ``controller`` (or an inference system) to each target given: ``fis`` and
    ``fcl`` files (a controller's control law in a comment), C99 sources into ``c_dir``
    (``real``: double or float), a Structured Text file ``st`` and an FMU ``fmu`` (FMI
    ``fmi`` 3 or 2); a controller's code with a lookup table of ``lut`` points per input
    instead of the evaluator, its largest error reported."""
    from fuzzyservo.codegen import single_precision_error, system_c_sources

    system = controller.system if isinstance(controller, FuzzyController) else controller
    if lut is not None and isinstance(controller, FuzzyController):
        problem = lut_problem(lut, len(system.inputs))
        if problem:
            raise ConfigError(f"--lut: {problem}")
    name, lines, notes, paths = system.name, [], [], []
    law = law_text(controller) if isinstance(controller, FuzzyController) else ""
    if isinstance(controller, FuzzyController):
        name = controller.name
        if fis or fcl:
            notes.append(f"note: MATLAB and other FCL tools read the inference system; the "
                         f"control law ({law}) is in a fuzzyservo comment that fuzzyservo "
                         "reads back")  # fmt: skip
    elif lut is not None:
        raise ConfigError(f"{excerpt(name)} is an inference system, not a controller: --lut tables "
                          "a controller's map; export it without --lut")  # fmt: skip
    if fis:
        paths.append(write_fis(system, fis, law))
        lines.append(f"{name} written to {fis}")
    if fcl:
        named, renamed = fcl_names(system)
        notes += renamed
        paths.append(write_fcl(named, fcl, law))
        lines.append(f"{name} written to {fcl} (IEC 61131-7 FCL)")
    if isinstance(controller, FuzzyController):
        _controller_code(controller, c_dir, st, lut, real, sample_time_s, lines, paths)
    else:
        if c_dir:
            written = write_files(system_c_sources(system, real), c_dir)
            paths += written
            lines.append(f"{name}: C99 ({real}, {len(system.inputs)} input(s), "
                         f"{len(system.outputs)} output(s)) written to "
                         + ", ".join(str(p) for p in written))  # fmt: skip
        if st:
            path = write_text(st, _system_st(system))
            how = "exact" if system.type == "sugeno" else "lookup tables"
            paths.append(path)
            lines.append(f"{name}: IEC 61131-3 Structured Text ({how}) written to {path}")
    if c_dir and real == "float":
        lines.append(single_precision_error(controller))
    if fmu:
        from fuzzyservo.io.fmu import write_fmu

        path, what = write_fmu(controller, fmu, fmi=fmi, sample_time_s=sample_time_s)
        paths.append(path)
        lines.append(f"{name}: FMU ({what}) written to {path}")
    return ExportResult(name, tuple(paths), tuple(lines), tuple(notes))


def export_plant(rig: Rig, fmu: str | Path, *, fmi: int = 3) -> ExportResult:
    """Write ``rig``'s plant as an FMU ``fmu`` (FMI ``fmi`` 3 or 2; model exchange and
    co-simulation, from C generated from the components' equations, binary built for this
    platform); FMPy's validation of it (when the ``fmi`` extra is installed) is one of
    the lines. Raises :class:`ConfigError` for a plant that cannot be written as C."""
    from fuzzyservo.codegen import TranslationError, fmu_signals, plant_fmu
    from fuzzyservo.io.fmu import write_fmu_build
    from fuzzyservo.io.rigs import write_fmu_rig

    try:
        build = plant_fmu(rig, fmi=fmi)
    except TranslationError as exc:
        raise ConfigError(str(exc), file=rig.path or rig.name) from None
    path = write_fmu_build(build, fmu)
    paths = [path]
    plant = rig.plant.for_params(rig.params_for(rig.scenario()))  # the form plant_fmu wrote
    lines = [f"{rig.name}: plant FMU (FMI {fmi}.0 model exchange and co-simulation, "
             f"{len(plant.states)} states, sources and {build.binary[0]}) written to {path}"]  # type: ignore[index]  # fmt: skip
    if rig.path:  # a rig that runs the FMU as its plant, with this rig's loop and scenarios
        paths.append(write_fmu_rig(
            rig.path, path.with_suffix(".yaml"), fmu=path, input=plant.input[0],
            load=plant.load[0], signals=fmu_signals(plant),
            header=f"{rig.name} with its plant from {path.name} (fuzzyservo export --fmu): the "
            "same loop, stages and scenarios; the FMU's parameters start at this rig's values",
        ))  # fmt: skip
        lines.append(f"a rig that runs it as its plant written to {paths[-1]}")
    notes = ["note: the FMU holds the plant only; the loop's stages (delay, valve lag, sensor, "
             "converter) stay in the rig that runs it"]  # fmt: skip
    try:
        from fmpy.validation import validate_fmu
    except ImportError:
        notes.append("note: not validated: FMPy is missing (pip install 'fuzzyservo[fmi]')")
    else:
        problems = validate_fmu(str(path))
        lines.append("FMPy validation: " + ("no problems" if not problems else "; ".join(problems)))
    return ExportResult(rig.name, tuple(paths), tuple(lines), tuple(notes))


def _system_st(system: FuzzySystem) -> str:
    from fuzzyservo.codegen import identifier, system_st_source

    return system_st_source(system, identifier(system.name))


def _controller_code(
    controller: FuzzyController,
    c_dir: str | Path | None,
    st: str | Path | None,
    lut: int | None,
    real: str,
    sample_time_s: float,
    lines: list[str],
    paths: list[Path],
) -> None:
    """The C and Structured Text of a controller (the lookup table's error reported)."""
    from fuzzyservo.codegen import lut_error, write_c, write_st

    name = controller.name

    def table(n: int) -> str:
        err = lut_error(controller, n)
        return (f"lookup table {n} point(s) per input: largest error {err.found:.3g} "
                f"({err.found / err.span:.2e} of the output range {err.span:g}; bound "
                f"{err.bound:.3g}), found on a grid {err.refine}x finer, before the output gain")  # fmt: skip

    if lut is not None and c_dir:
        lines.append(table(lut))
    if c_dir:
        written = write_c(controller, c_dir, sample_time_s, real, lut)
        paths += written
        lines.append(f"{name}: C99 ({real}, sample time {sample_time_s:g} s"
                     f"{', lookup table' if lut else ''}) written to "
                     + ", ".join(str(p) for p in written))  # fmt: skip
    if st:
        path, n = write_st(controller, st, sample_time_s, lut)
        if not c_dir or lut is None:
            lines.append(table(n))
        paths.append(path)
        lines.append(f"{name}: IEC 61131-3 Structured Text written to {path}")
