"""A plant's C model as one FMU for model exchange and co-simulation
(fuzzyservo/codegen/_plant_wrapper.py), on a hand-written model: a damped mass-spring
driving a stiff first-order lag (``dq/dt = -1e5·(q - y)``), against scipy's Radau."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from fuzzyservo.codegen import c_compiler
from fuzzyservo.codegen._plant_wrapper import (
    PlantFmuModel,
    PlantVariable,
    plant_fmu_build,
    plant_model_description,
)
from fuzzyservo.io.fmu import write_fmu_build

fmpy = pytest.importorskip("fmpy", reason="the plant FMU tests need FMPy (the fmi extra)")
solve_ivp = pytest.importorskip("scipy.integrate", reason="the reference needs scipy").solve_ivp
if c_compiler() is None:
    pytest.skip("no C compiler (cc, gcc, clang or $CC) to build the FMU", allow_module_level=True)
from fmpy.validation import validate_fmu  # noqa: E402

HEADER = """#ifndef PLANT_MODEL_H
#define PLANT_MODEL_H
void plant_rhs(const double *x, double u, double f_ext, const double *p, double *dx);
void plant_signals(const double *x, double u, double f_ext, const double *p, double *out);
#endif
"""

SOURCE = """#include "plant_model.h"
/* x = (y, v, q), p = (m, k, c) */
void plant_rhs(const double *x, double u, double f_ext, const double *p, double *dx)
{
    dx[0] = x[1];
    dx[1] = (u - p[1] * x[0] - p[2] * x[1]) / p[0] + f_ext / p[0];
    dx[2] = -1e5 * (x[2] - x[0]);
}

void plant_signals(const double *x, double u, double f_ext, const double *p, double *out)
{
    (void)u; (void)f_ext; (void)p;
    out[0] = x[0];
    out[1] = x[1];
    out[2] = x[2];
    out[3] = 2.0 * x[0];
}
"""

M, K, C = 1.0, 10.0, 2.0
V = PlantVariable


def _model() -> PlantFmuModel:
    return PlantFmuModel(
        identifier="mass_spring",
        description="damped mass-spring with a stiff lag",
        states=(
            V("x.y", "m", "position", 0.0),
            V("x.v", "m/s", "velocity", 0.0),
            V("x.q", "m", "stiff lag of y", 0.0),
        ),
        nominals=(0.1, 0.3, 0.1),
        typical=(0.1, 0.3, 0.1),
        input=V("u", "N", "force command"),
        load=V("f_ext", "N", "external load"),
        outputs=(
            V("y", "m", "position"),
            V("v", "m/s", "velocity"),
            V("q", "m", "lag"),
            V("y2", "m", "twice the position"),
        ),
        parameters=(
            V("m", "kg", "mass", M),
            V("k", "N/m", "stiffness", K),
            V("c", "N*s/m", "damping", C),
        ),
        c_files={"plant_model.h": HEADER, "plant_model.c": SOURCE},
        tolerance=1e-6,
    )


def _reference(t: np.ndarray, k: float = K, u: float = 1.5) -> np.ndarray:
    """y(t) by scipy's Radau, for the force ``u`` (command and load)."""

    def f(_t: float, x: np.ndarray) -> list[float]:
        return [x[1], (u - k * x[0] - C * x[1]) / M, -1e5 * (x[2] - x[0])]

    sol = solve_ivp(f, (0.0, float(t[-1])), [0.0, 0.0, 0.0], method="Radau", t_eval=t,
                    rtol=1e-11, atol=1e-12)  # fmt: skip
    assert sol.success
    return sol.y[0]


@pytest.fixture(scope="module", params=[2, 3])
def fmu(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Path:
    build = plant_fmu_build(_model(), fmi=request.param)
    assert build.binary is not None, build.problem
    return write_fmu_build(build, tmp_path_factory.mktemp("fmu") / f"plant{request.param}.fmu")


# u held at 1.0, the load at 0.5 (the plant sees their sum)
_INPUT = np.array([(0.0, 1.0, 0.5), (2.0, 1.0, 0.5)],
                  dtype=[("time", float), ("u", float), ("f_ext", float)])  # fmt: skip


def _simulate(path: Path, fmi_type: str, **kwargs: object) -> np.ndarray:
    return fmpy.simulate_fmu(str(path), fmi_type=fmi_type, input=_INPUT, stop_time=2.0,
                             output=["y", "y2", "x.y"], **kwargs)  # fmt: skip


def test_the_fmu_validates_in_fmpy(fmu):
    assert validate_fmu(str(fmu)) == []
    md = fmpy.read_model_description(str(fmu))
    assert md.modelExchange is not None and md.coSimulation is not None
    assert md.numberOfContinuousStates == 3 and md.numberOfEventIndicators == 0


def test_the_layout_the_wrapper_documents():
    """Value references: time, the states, their derivatives, input, load, outputs,
    parameters, tolerance; derivatives point at their states; units by base units."""
    model = _model()
    root = ET.fromstring(plant_model_description(model, 3))
    by_vr = {int(v.get("valueReference")): v for v in root.iter("Float64")}
    assert by_vr[0].get("name") == "time"
    assert [by_vr[vr].get("name") for vr in (1, 4, 7, 8, 9, 13, 16)] == [
        "x.y", "der(x.y)", "u", "f_ext", "y", "m", "tolerance"]  # fmt: skip
    assert by_vr[4].get("derivative") == "1" and by_vr[4].get("unit") == "m/s"
    units = {u.get("name"): u.find("BaseUnit").attrib for u in root.iter("Unit")}
    assert units["N/m"] == {"kg": "1", "s": "-2"}
    with pytest.raises(ValueError, match="share a name"):
        plant_model_description(
            PlantFmuModel(**{**model.__dict__, "parameters": (V("u", "1", "clash"),)}), 3
        )


def test_model_exchange_follows_radau(fmu):
    result = _simulate(fmu, "ModelExchange", solver="CVode", relative_tolerance=1e-10,
                       output_interval=1e-3)  # fmt: skip
    error = np.max(np.abs(result["y"] - _reference(result["time"])))
    assert error < 1e-6, error
    assert np.array_equal(result["y2"], 2.0 * result["y"])
    assert np.array_equal(result["x.y"], result["y"])


def test_co_simulation_follows_radau(fmu):
    result = _simulate(fmu, "CoSimulation", output_interval=1e-3, relative_tolerance=1e-8)
    error = np.max(np.abs(result["y"] - _reference(result["time"])))
    assert error < 1e-5, error


def test_a_parameter_set_at_start_changes_the_run(fmu):
    result = _simulate(fmu, "CoSimulation", output_interval=1e-2, relative_tolerance=1e-8,
                       start_values={"k": 40.0})  # fmt: skip
    assert np.max(np.abs(result["y"] - _reference(result["time"], k=40.0))) < 1e-5
    assert np.max(np.abs(result["y"] - _reference(result["time"]))) > 1e-2
