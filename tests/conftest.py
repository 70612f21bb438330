"""Shared fixtures: the project's own rig and controller files."""

from __future__ import annotations

from pathlib import Path

import pytest

from fuzzyservo.io.controllers import load_controller
from fuzzyservo.io.rigs import load_rig

ROOT = Path(__file__).resolve().parent.parent


def rig_named(name: str):
    """The shipped rig ``rigs/<name>.yaml``."""
    return load_rig(ROOT / "rigs" / f"{name}.yaml")


def controller_named(name: str):
    """The shipped controller ``studies/controllers/<name>.yaml``."""
    return load_controller(ROOT / "studies" / "controllers" / f"{name}.yaml")


@pytest.fixture(scope="session")
def dinca():
    return rig_named("dinca_cylinder")


@pytest.fixture(scope="session")
def ehs160():
    return rig_named("ehs160_motor")


@pytest.fixture(scope="session")
def p_k10():
    return controller_named("p_k10")


@pytest.fixture(scope="session")
def p_kb0105():
    return controller_named("p_kb0105")


@pytest.fixture(scope="session")
def open_loop():
    return controller_named("open_loop")


@pytest.fixture(scope="session")
def flc1():
    return controller_named("flc1_translated")


@pytest.fixture(scope="session")
def flc2():
    return controller_named("flc2_reshaped")
