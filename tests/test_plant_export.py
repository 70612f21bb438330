"""A rig's plant out as an FMU (issue 39): the C translated from the components'
equations gives the numba kernels' numbers bit for bit, the FMU validates in FMPy (FMI
3.0 and 2.0, model exchange and co-simulation), and seed 002's plant run back as an FMU
plant gives the native loop's metrics and positions."""

from __future__ import annotations

import ctypes
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest
from support import run_cli

from fuzzyservo import load_rig
from fuzzyservo.codegen import TranslationError, c_compiler, plant_c_sources
from fuzzyservo.components.effects import INPUT_EFFECTS, LIBRARY

ROOT = Path(__file__).resolve().parents[1]
RIGS = sorted(p.stem for p in (ROOT / "rigs").glob("*.yaml"))
CC = c_compiler()
needs_cc = pytest.mark.skipif(CC is None, reason="no C compiler (cc, gcc, clang or $CC)")

_D = ctypes.POINTER(ctypes.c_double)


def _library(plant, folder: Path) -> ctypes.CDLL:
    for name, text in plant_c_sources(plant).items():
        (folder / name).write_text(text)
    lib = folder / "plant.so"
    subprocess.run([CC, "-std=c99", "-O2", "-Wall", "-Werror", "-Wno-unused-but-set-variable",
                    "-Wno-unused-variable", "-shared", "-fPIC", "-o", str(lib),
                    str(folder / "plant_model.c"), "-lm"], check=True)  # fmt: skip
    dll = ctypes.CDLL(str(lib))
    for fn in (dll.plant_rhs, dll.plant_signals):
        fn.argtypes = [_D, ctypes.c_double, ctypes.c_double, _D, _D]
        fn.restype = None
    return dll


def _worst(rig, folder: Path, draws: int = 60) -> tuple[float, float]:
    """Largest |C − numba| of the derivatives and of the signals at random states."""
    plant = rig.plant.for_params(rig.params)
    dll = _library(plant, folder)
    p = plant.packed(rig.params)
    x0 = plant.initial_state(rig.params)
    typical = plant.typical_state(rig.params)
    rng = np.random.default_rng(7)
    worst = [0.0, 0.0]
    for _ in range(draws):
        x = x0 + 0.3 * typical * rng.normal(size=x0.size)
        u = rig.actuator.rated * rng.normal()
        f = 100.0 * rng.normal()
        for k, (fn, n) in enumerate(
            ((plant.kernels.plant_rhs, x.size), (plant.kernels.plant_signals, len(plant.signals)))
        ):
            ours, theirs = np.zeros(n), np.zeros(n)
            fn(x, u, f, p, ours)
            (dll.plant_rhs if k == 0 else dll.plant_signals)(
                x.ctypes.data_as(_D), u, f, p.ctypes.data_as(_D), theirs.ctypes.data_as(_D)
            )
            same = (ours == theirs) | (np.isnan(ours) & np.isnan(theirs))
            worst[k] = max(worst[k], float(np.max(np.where(same, 0.0, np.abs(ours - theirs)))))
    return worst[0], worst[1]


@needs_cc
@pytest.mark.parametrize("name", RIGS)
def test_the_c_of_every_shipped_rig_gives_the_kernels_numbers_bit_for_bit(name, tmp_path):
    assert _worst(load_rig(name), tmp_path) == (0.0, 0.0)


@needs_cc
def test_every_plant_effect_translates_bit_for_bit(tmp_path):
    """Each effect a cylinder reads, at the middle of its calibration bounds (friction with
    a pre-sliding distance: LuGre's bristle state), through the same C."""
    base = load_rig("dinca_cylinder")
    scales = base.scales()
    for k, name in enumerate(e for e in base.plant.effects if e not in INPUT_EFFECTS):
        values = {}
        for prm in LIBRARY[name].params:
            try:
                lo, hi = prm.bounds(scales)
            except (AttributeError, TypeError, ValueError):
                continue
            values[prm.field] = 0.5 * (lo + hi)
        if "friction" in name:
            values[f"{'coulomb' if name.startswith('coulomb') else 'stribeck'}_presliding_si"] = (
                1e-5
            )
        rig = base.with_effect(name).with_params(**values)
        folder = tmp_path / str(k)
        folder.mkdir()
        assert _worst(rig, folder, draws=30) == (0.0, 0.0), name


def test_code_outside_the_translated_subset_is_refused_by_function_and_line(monkeypatch):
    from fuzzyservo.plants import c_source as _plant_c

    def uses_a_list(P, X, u):
        values = [u, 2.0 * u]
        return values[0]

    unit = _plant_c._Unit()
    with pytest.raises(TranslationError) as info:
        unit.function(uses_a_list, (("rec", ("a",)), ("rec", ("y",)), _plant_c.NUM))
    message = str(info.value)
    assert "uses_a_list (line" in message and "List" in message
    assert "\n" not in message


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """Seed 002's plant as FMI 3.0 and 2.0 FMUs, each with the rig that runs it."""
    if CC is None:
        pytest.skip("no C compiler (cc, gcc, clang or $CC)")
    pytest.importorskip("fmpy", reason="plant FMUs are checked with FMPy (the fmi extra)")
    from fuzzyservo.workflows import export_plant

    folder = tmp_path_factory.mktemp("plant_fmu")
    rig = load_rig("dinca_cylinder")
    return {fmi: export_plant(rig, folder / f"dinca_fmi{fmi}.fmu", fmi=fmi) for fmi in (3, 2)}


@pytest.mark.parametrize("fmi", [3, 2])
def test_the_exported_plant_validates_in_fmpy_for_both_interfaces(exported, fmi):
    from fmpy import read_model_description
    from fmpy.validation import validate_fmu

    result = exported[fmi]
    fmu = result.paths[0]
    assert validate_fmu(str(fmu)) == []
    assert "FMPy validation: no problems" in result.text()
    md = read_model_description(str(fmu))
    assert md.modelExchange is not None and md.coSimulation is not None
    states = [d.variable.derivative.name for d in md.derivatives]
    assert states == ["cylinder.y", "cylinder.v", "supply.p_s", "supply.p_t", "cylinder.p_a",
                      "cylinder.p_b"]  # fmt: skip
    with zipfile.ZipFile(fmu) as z:
        names = z.namelist()
    assert "sources/plant_model.c" in names and "sources/fmu.c" in names


@pytest.mark.parametrize("fmi", [3, 2])
def test_co_simulation_follows_fmpys_model_exchange_run(exported, fmi):
    """A held current of 5 mA for 0.3 s: the FMU's own Rosenbrock solver stepped at 1 ms
    (co-simulation, tolerance 1e-8) against CVode on its model-exchange interface."""
    import fmpy

    fmu = str(exported[fmi].paths[0])
    held = np.array([(0.0, 5e-3, 0.0), (0.3, 5e-3, 0.0)],
                    dtype=[("time", float), ("i", float), ("f_load", float)])  # fmt: skip
    common = dict(stop_time=0.3, output_interval=1e-3, input=held,
                  output=["y", "p_a"])  # fmt: skip
    me = fmpy.simulate_fmu(fmu, fmi_type="ModelExchange", solver="CVode",
                           relative_tolerance=1e-9, **common)  # fmt: skip
    cs = fmpy.simulate_fmu(fmu, fmi_type="CoSimulation", relative_tolerance=1e-8, **common)
    travel = np.ptp(me["y"])
    assert travel > 1e-3  # the piston moves
    assert np.max(np.abs(cs["y"] - me["y"])) < 1e-4 * travel
    assert np.max(np.abs(cs["p_a"] - me["p_a"])) < 1e-4 * np.ptp(me["p_a"])


@pytest.mark.parametrize("controller", ["p_k10", "flc2_reshaped"])
def test_seed_002_run_back_as_an_fmu_plant_gives_the_native_loop(exported, controller):
    """The round trip of issue 39: the exported plant (FMI 3.0 model exchange) in the rig
    export wrote beside it, under P K=10 and FLC2 on `pulses`: every metric within 0.5 %
    and the position within 1e-6 of its travel."""
    from fuzzyservo import load_controller, simulate
    from fuzzyservo.metrics import result_metrics

    native_rig = load_rig("dinca_cylinder")
    fmu_rig = load_rig(exported[3].paths[1])
    ctrl = load_controller(ROOT / "studies" / "controllers" / f"{controller}.yaml")
    native = simulate(native_rig, ctrl, "pulses")
    ours = simulate(fmu_rig, ctrl, "pulses")
    assert ours.status == native.status == "ok"
    travel = np.ptp(native.output)
    assert np.max(np.abs(ours.output - native.output)) <= 1e-6 * travel
    m_native, m_fmu = result_metrics(native).aggregate, result_metrics(ours).aggregate
    for key, value in m_native.items():
        if np.isfinite(value) and value != 0:
            assert abs(m_fmu[key] - value) <= 5e-3 * abs(value), key


@pytest.mark.slow
def test_every_command_runs_on_the_exported_plant(exported, tmp_path):
    """The rig export wrote runs compare, margins, robustness (sampling the FMU's
    parameters by their rig-file keys), tune and calibrate (a parameter of the FMU fitted
    with an interval) like the native rig."""
    import json

    import yaml

    import fuzzyservo as fs
    from fuzzyservo.calibration.synthetic import synthetic_run

    rig_file = exported[3].paths[1]
    study = {
        "name": "fmu_study",
        "rig": str(rig_file),
        "scenarios": ["steps"],
        "controller": str(ROOT / "studies" / "controllers" / "pi_dinca.yaml"),
        "parameters": {"kp": {"low": 0.5, "high": 30.0, "log": True}},
        "objective": {"weights": {"settling_time_s": 1.0, "sse_abs": 1000.0}},
        "uncertainty": {
            "samples": 3,
            "seed": 1,
            "parameters": {"cylinder.piston_mass": {"uniform": [1, 2], "unit": "kg"}},
        },
        "seed": 1,
        "trials": 3,
    }
    study_path = tmp_path / "study.yaml"
    study_path.write_text(yaml.safe_dump(study, sort_keys=False), encoding="utf-8")

    def cli(*args: str) -> str:
        return run_cli(tmp_path, *args)

    assert "p_k10" in cli("compare", str(rig_file), "p_k10", "--scenario", "steps", "--out", "c")
    assert "gain margin" in cli("margins", str(rig_file), "p_k10", "--scenario", "steps").lower()
    cli("robustness", str(rig_file), "p_k10", "--uncertainty", str(study_path), "--samples", "3",
        "--out", "rob")  # fmt: skip
    cli("tune", str(study_path), "--out", "tune", "--trials", "3")
    assert (tmp_path / "tune" / "summary.json").is_file()

    # calibrate: a record with a 65 bar supply; the rig fits the supply pressure
    data = yaml.safe_load(rig_file.read_text(encoding="utf-8"))
    data["plant"]["fmu"]["file"] = str((rig_file.parent / data["plant"]["fmu"]["file"]).resolve())
    truth = json.loads(json.dumps(data))
    truth["plant"]["parameters"] = {"supply.supply_pressure": {"value": 65, "unit": "bar"}}
    data["plant"]["parameters"] = {
        "supply.supply_pressure": {"value": 70, "unit": "bar", "fit": [50, 90]}
    }
    (tmp_path / "truth.yaml").write_text(yaml.safe_dump(truth), encoding="utf-8")
    (tmp_path / "fit.yaml").write_text(yaml.safe_dump(data), encoding="utf-8")
    p_k10 = fs.load_controller("p_k10")
    record = synthetic_run(fs.load_rig(tmp_path / "truth.yaml"), p_k10, "steps", {},
                           {"y": 1e-5}, seed=3)  # fmt: skip
    result = fs.calibrate(fs.load_rig(tmp_path / "fit.yaml"), record, p_k10,
                          effects=["valve_bias"], max_effects=1)  # fmt: skip
    fitted = result.to_dict()["uncertainty"]["supply.supply_pressure"]
    low, high = fitted["interval"]
    assert low <= 65e5 <= high or low <= 65 <= high


def test_the_designer_runs_on_the_exported_plant(exported, tmp_path):
    """The designer's session on the exported plant's rig: FLC2 and a slider move run
    on the FMU as on the composition."""
    from fuzzyservo import load_controller, simulate
    from fuzzyservo.designer.files import Folders
    from fuzzyservo.designer.session import Session

    rig_file = exported[3].paths[1]
    flc2 = ROOT / "studies" / "controllers" / "flc2_reshaped.yaml"
    session = Session.open(Folders.make(ROOT, tmp_path / "out", rig_file.parent), rig_file, flc2)
    run = session.run()
    native = simulate(load_rig("dinca_cylinder"), load_controller(flc2), session.scenario)
    assert run.result.status == "ok"
    assert np.max(np.abs(run.result.output - native.output)) <= 1e-6 * np.ptp(native.output)
    session.set_design("input", "reshape", 1.2)
    assert session.run().metrics["settling_time_s"] != run.metrics["settling_time_s"]


def test_margins_on_the_exported_plant_are_the_native_ones(exported):
    """The gain and delay margins by bisection on the FMU plant: its instance is shared
    by every run with the same parameters, so the two searches run one after the other
    (side by side they would interleave their calls on it) and give the native margins."""
    from fuzzyservo import load_controller, margins

    p_k10 = load_controller("p_k10")
    native = margins(load_rig("dinca_cylinder"), p_k10, "steps")
    ours = margins(load_rig(exported[3].paths[1]), p_k10, "steps")
    assert ours.gain.value == pytest.approx(native.gain.value, rel=1e-9)
    assert ours.delay.value == pytest.approx(native.delay.value, rel=1e-9)


def _rig_variant(rig_file: Path, folder: Path, name: str, **fmu: str) -> Path:
    """The rig ``export`` wrote, without its valve lag, its FMU mapped with ``fmu``."""
    import yaml

    data = yaml.safe_load(rig_file.read_text(encoding="utf-8"))
    data["plant"]["fmu"]["file"] = str((rig_file.parent / data["plant"]["fmu"]["file"]).resolve())
    data["plant"]["fmu"].update(fmu)
    data.pop("effects", None)
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


@pytest.mark.parametrize("fmi", [3, 2])
def test_a_co_simulation_plant_is_stepped_once_per_interval(exported, fmi, tmp_path):
    """The exported plant taken through its co-simulation interface (its own Rosenbrock
    solver, one doStep per control interval) under P K=10 on `pulses`, against the same
    FMU for model exchange (both without the rig's valve lag, a stage the loop would
    integrate beside a stepped plant): the metrics within 0.5 %."""
    from fuzzyservo import load_controller, simulate
    from fuzzyservo.metrics import result_metrics

    rig_file = exported[fmi].paths[1]
    me = load_rig(_rig_variant(rig_file, tmp_path, "me", interface="model-exchange"))
    cs = load_rig(_rig_variant(rig_file, tmp_path, "cs", interface="co-simulation"))
    assert cs.plant.stepped and "co-simulation" in cs.plant.description
    assert cs.plant.states[0] == "y"
    p_k10 = load_controller("p_k10")
    ours, theirs = simulate(cs, p_k10, "pulses"), simulate(me, p_k10, "pulses")
    assert ours.status == theirs.status == "ok"
    assert np.max(np.abs(ours.output - theirs.output)) < 1e-3 * np.ptp(theirs.output)
    m_cs, m_me = result_metrics(ours).aggregate, result_metrics(theirs).aggregate
    for key, value in m_me.items():
        if np.isfinite(value) and value != 0:
            assert abs(m_cs[key] - value) <= 5e-3 * abs(value), key


def test_a_co_simulation_plant_refuses_what_needs_integrating(exported, tmp_path):
    """The valve lag (a state the loop integrates) and the reference path are refused in
    one line naming why; an unknown interface too."""
    import yaml

    from fuzzyservo import load_controller, simulate_reference
    from fuzzyservo.errors import ConfigError

    rig_file = exported[3].paths[1]
    cs_file = _rig_variant(rig_file, tmp_path, "cs", interface="co-simulation")
    with pytest.raises(ConfigError, match="stepped by its own solver") as info:
        simulate_reference(load_rig(cs_file), load_controller("p_k10"), "steps")
    assert "\n" not in str(info.value)
    data = yaml.safe_load(cs_file.read_text(encoding="utf-8"))
    data["effects"] = {"valve_lag": {"time_constant": {"value": 3, "unit": "ms"}}}
    (tmp_path / "lag.yaml").write_text(yaml.safe_dump(data), encoding="utf-8")
    with pytest.raises(ConfigError, match=r"valve_lag.*not applicable") as info:
        load_rig(tmp_path / "lag.yaml")
    assert "\n" not in str(info.value)
    data["plant"]["fmu"]["interface"] = "scheduled"
    (tmp_path / "bad.yaml").write_text(yaml.safe_dump(data), encoding="utf-8")
    with pytest.raises(ConfigError, match=r"interface.*model-exchange"):
        load_rig(tmp_path / "bad.yaml")
