"""A fuzzy controller or inference system written for other tools: MATLAB ``.fis``,
IEC 61131-7 FCL, C99, IEC 61131-3 Structured Text and FMI co-simulation FMUs (what
``fuzzyservo export`` writes).

A controller (a YAML file, or a ``.fis``/FCL file with a fuzzyservo control-law
comment) is exported with its control law: ``.fis`` and FCL carry it in a comment, C,
ST and the FMU compute it. Any other ``.fis`` or FCL file is an inference system with
any number of inputs and outputs: its C and FMU compute what ``evaluate`` does.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fuzzyservo.atomic import write_files, write_text
from fuzzyservo.controllers.fuzzy.controller import FuzzyController
from fuzzyservo.controllers.fuzzy.system import FuzzySystem
from fuzzyservo.errors import ConfigError, excerpt
from fuzzyservo.limits import lut_problem
from fuzzyservo.results import Result

__all__ = [
    "ExportResult", "export", "export_file", "load_exportable",
]  # fmt: skip


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


def load_exportable(path: str | Path) -> FuzzyController | FuzzySystem:
    """What ``path`` holds for export: a controller (a fuzzy controller YAML file, or a
    ``.fis``/FCL file with a control-law comment) or an inference system (any other
    ``.fis``/FCL file)."""
    from fuzzyservo.io.evaluation import load_fuzzy_controller
    from fuzzyservo.io.fcl import read_fcl_law
    from fuzzyservo.io.fis import controller_from_law, read_fis_law

    p = Path(path)
    suffix = p.suffix.lower()
    if suffix not in (".fis", ".fcl"):
        return load_fuzzy_controller(p, other=", a .fis or a .fcl")
    system, law = (read_fis_law if suffix == ".fis" else read_fcl_law)(p)
    return controller_from_law(system, law, p, "[Rules]") if law else system


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
    checked first (:class:`ConfigError` naming the option)."""
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
    target = load_exportable(source)
    try:
        return export(target, fis=fis, fcl=fcl, c_dir=c_dir, st=st, fmu=fmu, fmi=fmi, lut=lut,
                      real=real, sample_time_s=sample_time_s)  # fmt: skip
    except ValueError as exc:
        if isinstance(exc, ConfigError):
            raise
        raise ConfigError(str(exc), file=str(source)) from None


def _fcl_names(system: FuzzySystem) -> tuple[FuzzySystem, list[str]]:
    """``system`` with term names FCL can refer to: a repeated name gets ``_2``, ``_3`` …
    (MATLAB refers to terms by number; juggler.fis names nine output terms alike)."""
    variables, notes = [], []
    for v in (*system.inputs, *system.outputs):
        seen: dict[str, int] = {}
        terms = []
        for t in v.terms:
            seen[t.name] = seen.get(t.name, 0) + 1
            name = t.name if seen[t.name] == 1 else f"{t.name}_{seen[t.name]}"
            terms.append(dataclasses.replace(t, name=name))
        if any(n > 1 for n in seen.values()):
            notes.append(f"note: FCL refers to terms by name; repeated term names of "
                         f"{excerpt(v.name)} written with _2, _3 … suffixes")  # fmt: skip
        variables.append(dataclasses.replace(v, terms=tuple(terms)))
    n = len(system.inputs)
    renamed = dataclasses.replace(system, inputs=tuple(variables[:n]), output=variables[n],
                                  other_outputs=tuple(variables[n + 1 :]))  # fmt: skip
    return renamed, notes


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
    from fuzzyservo.io.fcl import write_fcl
    from fuzzyservo.io.fis import law_text, write_fis

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
        named, renamed = _fcl_names(system)
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
