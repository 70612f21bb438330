"""A light base install: what the command line needs, the rest in extras (issue 30)."""

from __future__ import annotations

import sys
import tomllib
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
    from fuzzyservo.tuning.runner import _storage

    monkeypatch.setitem(sys.modules, "psycopg2", None)
    with pytest.raises(MissingExtraError, match=r"fuzzyservo\[postgres\]"):
        _storage("postgresql://nobody@127.0.0.1:1/none")
