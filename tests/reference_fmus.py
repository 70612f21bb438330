"""The Modelica Association's Reference FMUs, built from the sources on the team's shelf.

``../shared/reference-fmus/`` holds them as C sources (BSD licence; its SOURCE.txt says how
to build them). :func:`build` compiles one model for FMI 2.0 or 3.0 into a folder of the
test's own and zips it as an FMU; tests skip with a reason when the sources or a C
compiler are absent. Nothing is copied into the repository.
"""

from __future__ import annotations

import shutil
import subprocess
import zipfile
from pathlib import Path

import pytest
from support import SHARED

SOURCES = SHARED / "reference-fmus"


def build(model: str, version: int, folder: Path) -> Path:
    """``<folder>/<model>_fmi<version>.fmu``, compiled for this machine (x86-64 Linux)."""
    if not (SOURCES / model / "model.c").is_file():
        pytest.skip(f"the Reference FMU sources are not on the shelf ({SOURCES})")
    compiler = shutil.which("gcc") or shutil.which("cc")
    if compiler is None:
        pytest.skip("no C compiler (gcc) to build the Reference FMUs")
    fmu = folder / f"{model}_fmi{version}.fmu"
    if fmu.exists():
        return fmu
    tree = folder / f"{model}_fmi{version}"
    platform = "linux64" if version == 2 else "x86_64-linux"  # FMI 2.0's and 3.0's names
    binaries = tree / "binaries" / platform
    binaries.mkdir(parents=True, exist_ok=True)
    subprocess.run(
        [compiler, "-shared", "-fPIC", "-O2", f"-DFMI_VERSION={version}", "-DDISABLE_PREFIX",
         "-I", str(SOURCES / "include"), "-I", str(SOURCES / model),
         str(SOURCES / model / "model.c"), str(SOURCES / "src" / f"fmi{version}Functions.c"),
         str(SOURCES / "src" / "cosimulation.c"), "-o", str(binaries / f"{model}.so"), "-lm"],
        check=True,
    )  # fmt: skip
    shutil.copy(SOURCES / model / f"FMI{version}.xml", tree / "modelDescription.xml")
    with zipfile.ZipFile(fmu, "w") as zf:
        for path in sorted(tree.rglob("*")):
            zf.write(path, path.relative_to(tree).as_posix())
    return fmu
