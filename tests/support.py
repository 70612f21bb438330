"""Helpers the tests share: the shipped files by name, and bad-input sandboxes.

Imported as ``support`` (``tests/`` is on ``sys.path`` through pytest's rootdir
conftest), so ``python -m pytest`` works from any folder and against an installed
(non-editable) package.
"""

from __future__ import annotations

import os
import re
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
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


def run_cli(cwd: Path, *args: str) -> str:
    """``python -m fuzzyservo ARGS`` run in ``cwd``: its standard output; the test fails with
    its standard error when it does not exit 0."""
    done = subprocess.run([sys.executable, "-m", "fuzzyservo", *args], capture_output=True,
                          text=True, cwd=cwd)  # fmt: skip
    assert done.returncode == 0, done.stderr
    return done.stdout


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@contextmanager
def designer_process(work: Path, out: Path, timeout_s: float = 180) -> Iterator[str]:
    """``fuzzyservo designer`` as a user starts it, in the working folder ``work``, writing
    to ``out``; yields the address it printed (with its token) and stops it after."""
    import pytest

    log = work / "designer.log"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        p for p in (str(TESTS.parent), os.environ.get("PYTHONPATH")) if p)}  # fmt: skip
    with open(log, "w") as sink:
        proc = subprocess.Popen(
            [sys.executable, "-m", "fuzzyservo", "designer", "--port", str(free_port()),
             "--out", str(out)],
            cwd=work, env=env, stdout=sink, stderr=subprocess.STDOUT,
        )  # fmt: skip
    try:
        deadline = time.monotonic() + timeout_s
        while "designer on" not in log.read_text():  # printed once the server listens
            if proc.poll() is not None or time.monotonic() > deadline:
                pytest.fail(f"the designer did not start:\n{log.read_text()}")
            time.sleep(0.2)
        yield re.search(r"designer on (\S+)", log.read_text()).group(1)
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
