"""Helpers the tests share: the shipped files by name, and bad-input sandboxes.

Imported as ``support`` (``tests/`` is on ``sys.path`` through pytest's rootdir
conftest), so ``python -m pytest`` works from any folder and against an installed
(non-editable) package.
"""

from __future__ import annotations

from pathlib import Path

from fuzzyservo.io.controllers import load_controller
from fuzzyservo.io.paths import find_file
from fuzzyservo.io.rigs import load_rig

TESTS = Path(__file__).resolve().parent
SHARED = TESTS.parent.parent / "shared"  # the reference shelf beside the checkout, if any


def shipped(name: str, folder: str = "rigs") -> Path:
    """The path of a shipped file: ``shipped("dinca_cylinder")``,
    ``shipped("p_k10", "studies/controllers")``, ``shipped("dinca_flc", "studies")``."""
    return find_file(name, folder, folder.rsplit("/", 1)[-1].rstrip("s"))


def rig_named(name: str):
    """The shipped rig ``<name>``."""
    return load_rig(shipped(name, "rigs"))


def controller_named(name: str):
    """The shipped controller ``<name>``."""
    return load_controller(shipped(name, "studies/controllers"))


#: the folder holding the shipped ``rigs/`` and ``studies/`` (package data once installed)
DATA = shipped("dinca_cylinder").parent.parent


def ideal_sensor(rig):
    """``rig`` with a noise-free feedback sensor without ADC (issue 11 gave the shipped
    seed-002 rig both): for tests that pin the plant or the integrator, where a
    quantised reading turns µm-level differences into whole ADC codes of 16 µm."""
    import dataclasses

    fb = dataclasses.replace(rig.feedback, noise_std=0.0, adc_bits=0, adc_lower=0.0, adc_upper=0.0)
    return dataclasses.replace(rig, feedback=fb)
