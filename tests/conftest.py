"""Shared fixtures: the project's own rig and controller files."""

from __future__ import annotations

from pathlib import Path

import pytest

from fuzzyservo.io.controllers import load_controller
from fuzzyservo.io.rigs import load_rig

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="session")
def dinca():
    return load_rig(ROOT / "rigs" / "dinca_cylinder.yaml")


@pytest.fixture(scope="session")
def ehs160():
    return load_rig(ROOT / "rigs" / "ehs160_motor.yaml")


@pytest.fixture(scope="session")
def p_k10():
    return load_controller(ROOT / "studies" / "controllers" / "p_k10.yaml")


@pytest.fixture(scope="session")
def p_kb0105():
    return load_controller(ROOT / "studies" / "controllers" / "p_kb0105.yaml")


@pytest.fixture(scope="session")
def open_loop():
    return load_controller(ROOT / "studies" / "controllers" / "open_loop.yaml")


@pytest.fixture(scope="session")
def flc1():
    return load_controller(ROOT / "studies" / "controllers" / "flc1_translated.yaml")


@pytest.fixture(scope="session")
def flc2():
    return load_controller(ROOT / "studies" / "controllers" / "flc2_reshaped.yaml")
