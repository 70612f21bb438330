"""A fuzzy controller written for other tools: MATLAB ``.fis``, IEC 61131-7 FCL, C99
and IEC 61131-3 Structured Text (what ``fuzzyservo export`` writes)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fuzzyservo.results import Result

if TYPE_CHECKING:
    from fuzzyservo.controllers.fuzzy import FuzzyController


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


def export(
    controller: FuzzyController,
    *,
    fis: str | Path | None = None,
    fcl: str | Path | None = None,
    c_dir: str | Path | None = None,
    st: str | Path | None = None,
    lut: int | None = None,
    real: str = "double",
    sample_time_s: float = 0.01,
) -> ExportResult:
    """Write ``controller`` to each target given: ``fis`` and ``fcl`` files (the inference
    system only), C99 sources into ``c_dir`` (``real``: double or float) and a Structured
    Text file ``st``; the code with a lookup table of ``lut`` points per input instead of
    the evaluator, its largest error reported."""
    from fuzzyservo.codegen import lut_error, write_c, write_st
    from fuzzyservo.io.fcl import write_fcl
    from fuzzyservo.io.fis import law_text, write_fis

    name, lines, notes, paths = controller.name, [], [], []
    for file in (fis, fcl, st):  # a file in a folder not made yet: make it
        if file:
            Path(file).parent.mkdir(parents=True, exist_ok=True)
    law = law_text(controller)
    if fis or fcl:
        notes.append(f"note: MATLAB and other FCL tools read the inference system; the control "
                     f"law ({law}) is in a fuzzyservo comment that fuzzyservo reads back")  # fmt: skip
    if fis:
        paths.append(write_fis(controller.system, fis, law))
        lines.append(f"{name} written to {fis}")
    if fcl:
        paths.append(write_fcl(controller.system, fcl, law))
        lines.append(f"{name} written to {fcl} (IEC 61131-7 FCL)")

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
    return ExportResult(name, tuple(paths), tuple(lines), tuple(notes))
