"""Shared fixtures: the project's own rig and controller files (see ``support.py``)."""

from __future__ import annotations

import pytest
from support import controller_named, rig_named


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
