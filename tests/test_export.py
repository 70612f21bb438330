"""Exports that run in the controller's place: ``.fis`` and FCL carry the control law
(form, gains, output limits) beside the inference system, so seed 002's FLC2 read back
from either gives the metrics of the YAML controller, the command's included (issue 27:
the command's peak was 2.0 V instead of 2.238 V when the limits were dropped and the
rig's actuator range applied instead)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from support import controller_named, rig_named

from fuzzyservo.analysis.compare import compare
from fuzzyservo.io.controllers import load_controller
from fuzzyservo.io.export import export


def test_flc2_from_its_fis_and_fcl_gives_identical_metrics(tmp_path):
    flc2 = controller_named("flc2_reshaped")
    export(flc2, fis=tmp_path / "flc2_fis.fis", fcl=tmp_path / "flc2_fcl.fcl")
    back = [load_controller(tmp_path / f) for f in ("flc2_fis.fis", "flc2_fcl.fcl")]
    for c in back:
        assert (c.form, c.u_min, c.u_max, c.output_gain) == ("p", -10.0, 10.0, 1.0)
        assert c.system == flc2.system
    result = compare(rig_named("dinca_cylinder"), [flc2, *back])
    metrics = result.metrics
    native = metrics["flc2_reshaped"].aggregate
    assert native["peak_command"] == pytest.approx(2.238, abs=1e-3)
    for c in back:
        assert metrics[c.name].aggregate == native, c.name
        np.testing.assert_array_equal(result[c.name].command, result["flc2_reshaped"].command)


def test_every_law_survives_the_round_trip(tmp_path):
    """Form pi, non-unit gains and one-sided limits, exactly (``repr`` numbers)."""
    c = controller_named("fpi_ehs160")
    c = dataclasses.replace(c, input_gain=0.1 + 0.2, u_min=-np.inf, u_max=7.25, design=None)
    export(c, fis=tmp_path / "law.fis", fcl=tmp_path / "law.fcl")
    for file in ("law.fis", "law.fcl"):
        back = load_controller(tmp_path / file)
        fields = ("form", "input_gain", "rate_gain", "output_gain", "u_min", "u_max", "system")
        assert [getattr(back, f) for f in fields] == [getattr(c, f) for f in fields], file
