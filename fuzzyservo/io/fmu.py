"""FMU files: the archives :func:`fuzzyservo.codegen.fmu_build` makes (a fuzzy controller
or inference system as a co-simulation FMU) and :func:`fuzzyservo.codegen.plant_fmu_build`
(a rig's plant, model exchange and co-simulation), each with a binary for this platform,
zipped and written. Without a C compiler the FMU is written with its sources only and
:class:`~fuzzyservo.errors.ConfigError` says so.
"""

from __future__ import annotations

import zipfile
from pathlib import Path

from fuzzyservo.atomic import atomic_write
from fuzzyservo.codegen import FmuBuild, fmu_build
from fuzzyservo.controllers.fuzzy.controller import FuzzyController
from fuzzyservo.controllers.fuzzy.system import FuzzySystem
from fuzzyservo.errors import ConfigError

__all__ = ["write_fmu", "write_fmu_build"]


def write_fmu(
    target: FuzzyController | FuzzySystem,
    path: str | Path,
    *,
    fmi: int = 3,
    sample_time_s: float = 0.01,
) -> tuple[Path, str]:
    """Write the FMU of ``target`` to ``path``; returns the path and a line saying what
    it holds. Raises :class:`ConfigError` (after writing a source-only FMU) when no C
    compiler is found or the build fails."""
    build = fmu_build(target, fmi=fmi, sample_time_s=sample_time_s)
    out = write_fmu_build(build, path)
    return out, f"FMI {fmi}.0 co-simulation, sources and {build.binary[0]}"  # type: ignore[index]


def write_fmu_build(build: FmuBuild, path: str | Path) -> Path:
    """Zip ``build`` into ``path``; raises :class:`ConfigError` (after writing a
    source-only FMU) when it has no binary."""
    out = Path(path)
    with atomic_write(out, "wb") as fh, zipfile.ZipFile(fh, "w", zipfile.ZIP_DEFLATED) as z:
        for file, text in build.files.items():
            z.writestr(file, text)
        if build.binary:
            z.writestr(*build.binary)
    if build.binary is None:
        raise ConfigError(f"{build.problem}; wrote a source-only FMU (rebuild it from sources/)",
                          file=str(out))  # fmt: skip
    return out
