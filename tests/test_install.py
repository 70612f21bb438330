"""A light base install: what the command line needs, the rest in extras (issue 30)."""

from __future__ import annotations

import os
import shutil
import site
import subprocess
import sys
import tomllib
import venv
import zipfile
from pathlib import Path

import pytest

import fuzzyservo
from fuzzyservo.cli import main

ROOT = Path(__file__).resolve().parents[1]


def _project() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]


def test_the_base_install_carries_no_web_server_database_driver_or_dataframes() -> None:
    base = " ".join(_project()["dependencies"]).lower()
    for heavy in ("panel", "bokeh", "pandas", "psycopg", "playwright", "dask", "fmpy"):
        assert heavy not in base
    extras = _project()["optional-dependencies"]
    assert any("panel" in d for d in extras["designer"])
    assert any("psycopg2" in d for d in extras["postgres"])


def test_the_namespace_is_the_api() -> None:
    names = dir(fuzzyservo)
    assert names == sorted([*fuzzyservo.__all__, "__version__"])
    assert "Any" not in names and "annotations" not in names
    for name in fuzzyservo.__all__:
        assert getattr(fuzzyservo, name) is not None


def test_a_missing_extra_is_named_in_one_line(monkeypatch, capsys) -> None:
    monkeypatch.setitem(sys.modules, "panel", None)  # import panel raises ImportError
    code = main(["designer", "dinca_cylinder", "flc2_reshaped", "--port", "0"])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1
    assert "pip install 'fuzzyservo[designer]'" in err and "Traceback" not in err


def test_a_postgres_storage_without_its_driver_names_the_extra(monkeypatch) -> None:
    from fuzzyservo.errors import MissingExtraError
    from fuzzyservo.tuning.storage import _storage

    monkeypatch.setitem(sys.modules, "psycopg2", None)
    with pytest.raises(MissingExtraError, match=r"fuzzyservo\[postgres\]"):
        _storage("postgresql://nobody@127.0.0.1:1/none")


# --------------------------------------------------------------------------- the layout
def _setuptools() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"][
        "setuptools"
    ]


def _mapped_packages() -> dict[str, Path]:
    """Package name -> folder of the data packages pyproject.toml maps (rigs/, studies/ …)."""
    found = {}
    for package, folder in _setuptools()["package-dir"].items():
        top = ROOT / folder
        for sub in [top, *sorted(p for p in top.rglob("*") if p.is_dir())]:
            found[".".join([package, *sub.relative_to(top).parts])] = sub
    return found


def test_the_package_list_is_the_tree() -> None:
    """pyproject.toml lists the packages by name (a mapped folder must be): every package
    of the tree and every folder of rigs/ and studies/ is listed, and nothing else."""
    from setuptools import find_packages

    tree = set(find_packages(where=str(ROOT), include=["fuzzyservo", "fuzzyservo.*"]))
    assert set(_setuptools()["packages"]) == tree | {"fuzzyservo.data"} | set(_mapped_packages())


def test_every_shipped_rig_and_study_file_is_package_data() -> None:
    """A file under rigs/ or studies/ whose kind the package-data patterns miss would be
    found in a checkout and missing after ``pip install .``."""
    patterns = _setuptools()["package-data"]
    for package, folder in _mapped_packages().items():
        for file in (p for p in folder.iterdir() if p.is_file()):
            assert any(file.match(g) for g in patterns.get(package, ())), (file, package)
    assert (ROOT / "rigs").is_dir() and (ROOT / "studies" / "controllers").is_dir()
    assert not (ROOT / "fuzzyservo" / "data" / "rigs").exists()  # one copy


def _clean_env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    env["MPLBACKEND"] = "Agg"
    return env


@pytest.mark.slow
def test_a_wheel_finds_the_rigs_and_studies_by_name_from_any_folder(tmp_path: Path) -> None:
    """Build a wheel from a copy of the checkout, install it into a fresh virtual
    environment (its dependencies seen through a .pth on this interpreter's
    site-packages, so nothing is downloaded but the build backend) and run commands that
    name a rig, a study and a controller from a folder holding none of them."""
    src = tmp_path / "src"
    src.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy2(ROOT / name, src / name)
    for name in ("fuzzyservo", "rigs", "studies"):
        shutil.copytree(ROOT / name, src / name, ignore=shutil.ignore_patterns("__pycache__"))
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check"]
    build = subprocess.run(
        [*pip, "wheel", "--no-deps", "-q", "-w", str(tmp_path / "dist"), str(src)],
        capture_output=True, text=True, check=False, timeout=600,
    )  # fmt: skip
    if build.returncode != 0 and "No matching distribution" in build.stderr:
        pytest.skip(f"the build backend could not be fetched: {build.stderr.strip()[-300:]}")
    assert build.returncode == 0, build.stderr[-3000:]
    (wheel,) = (tmp_path / "dist").glob("fuzzyservo-*.whl")
    with zipfile.ZipFile(wheel) as zf:
        names = set(zf.namelist())
    assert "fuzzyservo/data/rigs/dinca_cylinder.yaml" in names
    assert "fuzzyservo/data/studies/controllers/p_k10.yaml" in names
    assert "fuzzyservo/data/reproduction.yaml" in names

    venv_dir = tmp_path / "venv"
    venv.create(venv_dir, with_pip=False)
    python = venv_dir / ("Scripts" if os.name == "nt" else "bin") / "python"
    purelib = subprocess.run(
        [str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        capture_output=True, text=True, check=True,
    ).stdout.strip()  # fmt: skip
    Path(purelib, "_fuzzyservo_test_deps.pth").write_text("\n".join(site.getsitepackages()))
    subprocess.run(
        [*pip, "--python", str(python), "install", "--no-deps", "--no-index", "-q", str(wheel)],
        capture_output=True, text=True, check=True, timeout=600,
    )  # fmt: skip

    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    found = subprocess.run(
        [str(python), "-c",
         "import fuzzyservo, fuzzyservo.io.paths as p, fuzzyservo.io.studies as s;"
         "print(fuzzyservo.__file__); print(p.data_root());"
         "print(s.load_study(p.find_file('dinca_flc', 'studies', 'study')).name)"],
        cwd=elsewhere, env=_clean_env(), capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert found.returncode == 0, found.stderr[-3000:]
    package, data, study = found.stdout.split()
    assert Path(package).is_relative_to(venv_dir) and Path(data).is_relative_to(venv_dir)
    assert study == "dinca_flc"
    script = python.parent / "fuzzyservo"
    for command in (
        ["show", "flc2_reshaped", "--out", "show"],
        ["simulate", "dinca_cylinder", "p_k10", "--duration", "1", "--out", "sim"],
    ):
        run = subprocess.run(
            [str(script), *command], cwd=elsewhere, env=_clean_env(),
            capture_output=True, text=True, check=False, timeout=900,
        )  # fmt: skip
        assert run.returncode == 0, (command, run.stderr[-3000:])
    assert (elsewhere / "sim").is_dir()
    assert sorted(p.name for p in elsewhere.iterdir()) == ["show", "sim"]
