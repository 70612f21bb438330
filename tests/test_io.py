"""Bad-input tests for rig and controller files (STYLE.md practice 9).

Each case starts from a shipped file's parsed YAML, breaks one thing, writes it to a
temporary file and checks that the loader raises one :class:`ConfigError` line naming
the file, the dotted key and a fix; the CLI must turn it into one stderr line, exit 2.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from support import DATA

from fuzzyservo.cli import main
from fuzzyservo.errors import ConfigError
from fuzzyservo.io.controllers import load_controller
from fuzzyservo.io.rigs import load_rig

RIG_FILES = sorted((DATA / "rigs").glob("*.yaml"))
QUANTITY_KEYS = {"value", "unit", "source"}


def shipped(folder: str, name: str) -> dict[str, Any]:
    return yaml.safe_load((DATA / folder / f"{name}.yaml").read_text(encoding="utf-8"))


def write(tmp_path: Path, data: Any, name: str = "bad.yaml") -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


def expect_error(loader: Callable[[Path], Any], path: Path, key: str | None, *hints: str) -> str:
    """The loader fails with one line naming ``path`` (once), ``key`` and every hint."""
    with pytest.raises(ConfigError) as info:
        loader(path)
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(f"{path}: ")
    assert message.count(str(path)) == 1, "file named twice: an error was wrapped twice"
    if key is not None:
        assert info.value.key == key
        assert f"{path}: {key}: " in message
    for hint in hints:
        assert hint in message
    assert ";" in info.value.detail, f"no fix after the problem in {message!r}"
    return message


# the seed-002 composition's parameters used below, by the instance that holds them
INSTANCE = {"piston_mass": "cylinder", "piston_diameter": "cylinder", "supply_pressure": "supply",
            "supply_volume": "supply", "bulk_modulus": "oil"}  # fmt: skip


def params_of(data: dict, key: str) -> dict:
    return data["plant"]["components"][INSTANCE[key]]["parameters"]


def param(data: dict, key: str) -> dict:
    return params_of(data, key)[key]


def rename(mapping: dict, old: str, new: str) -> None:
    mapping[new] = mapping.pop(old)


# --------------------------------------------------------------------------- rig files
def _top_misspelled(d):
    rename(d, "scenarios", "scenarioss")


def _param_misspelled(d):
    rename(params_of(d, "bulk_modulus"), "bulk_modulus", "bulk_modulos")


def _scenario_misspelled(d):
    rename(d["scenarios"]["pulses"], "duration", "duraton")


def _feedback_misspelled(d):
    rename(d["feedback"], "offset", "ofset")


def _quantity_misspelled(d):
    rename(param(d, "piston_mass"), "unit", "units")


def _missing_param(d):
    del params_of(d, "piston_mass")["piston_mass"]


def _text_for_number(d):
    param(d, "piston_mass")["value"] = "heavy"


def _number_with_unit_as_text(d):
    param(d, "supply_pressure")["value"] = "70 bar"


def _negative_volume(d):
    param(d, "supply_volume")["value"] = -3


def _zero_bulk_modulus(d):
    param(d, "bulk_modulus")["value"] = 0


def _negative_mass(d):
    param(d, "piston_mass")["value"] = -1


def _limits_swapped(d):
    a = d["actuator"]
    a["lower"]["value"], a["upper"]["value"] = a["upper"]["value"], a["lower"]["value"]


def _pressure_in_cm(d):
    param(d, "supply_pressure")["unit"] = "cm"


def _unknown_unit(d):
    param(d, "piston_diameter")["unit"] = "furlong"


def _unreadable_unit(d):
    param(d, "piston_diameter")["unit"] = "m**(1/0)"


def _unknown_plant(d):
    d["plant"]["type"] = "hydraulic_crane"


def _unknown_signal(d):
    d["scenarios"]["pulses"]["reference"]["type"] = "sawtooth"


def _warmup_too_long(d):
    d["scenarios"]["pulses"]["warmup"] = {"value": 22, "unit": "s"}


def _override_nonphysical(d):
    d["scenarios"]["pulses"]["overrides"] = {"oil.bulk_modulus": {"value": -1, "unit": "bar"}}


def _override_misspelled(d):
    d["scenarios"]["pulses"]["overrides"] = {"supply.supply_presure": {"value": 50, "unit": "bar"}}


def _null_section(d):
    d["plant"] = None


def _list_for_mapping(d):
    d["plant"]["components"]["cylinder"]["parameters"] = list(params_of(d, "piston_mass"))


def _number_for_text(d):
    d["plant"]["components"]["cylinder"]["type"] = 5


def _null_value(d):
    param(d, "bulk_modulus")["value"] = None


def _huge_int(d):
    param(d, "piston_mass")["value"] = 10**400


def _list_for_number(d):
    d["scenarios"]["pulses"]["reference"]["base"] = [6.2]


def _text_in_list(d):
    d["scenarios"]["steps"]["reference"]["values"] = [6.684, "high", 6.4904]


def _duty_out_of_range(d):
    d["scenarios"]["pulses"]["reference"]["duty"] = 1.5


def _steps_not_increasing(d):
    d["scenarios"]["steps"]["reference"]["times_s"] = [2, 6, 4]


def _sample_time_zero(d):
    d["controller"]["sample_time"]["value"] = 0


def _sensor_gain_zero(d):
    d["feedback"]["gain"]["value"] = 0


def _bad_display_unit(d):
    d["output"]["display_unit"] = "bar"


def _no_scenarios(d):
    d["scenarios"] = {}


RIG_CASES = [
    # (mutation, dotted key, hints)
    (_top_misspelled, "scenarioss", ["unknown key", "did you mean 'scenarios'?"]),
    (
        _param_misspelled,
        "plant.components.oil.parameters.bulk_modulos",
        ["unknown key", "did you mean 'bulk_modulus'?"],
    ),
    (_scenario_misspelled, "scenarios.pulses.duraton", ["did you mean 'duration'?"]),
    (_feedback_misspelled, "feedback.ofset", ["did you mean 'offset'?"]),
    (
        _quantity_misspelled,
        "plant.components.cylinder.parameters.piston_mass.units",
        ["did you mean 'unit'?"],
    ),
    (
        _missing_param,
        "plant.components.cylinder.parameters",
        ["missing key 'piston_mass'", "kg", "add it"],
    ),
    (
        _text_for_number,
        "plant.components.cylinder.parameters.piston_mass.value",
        ["must be a number", "'heavy'", "write a plain number"],
    ),
    (
        _number_with_unit_as_text,
        "plant.components.supply.parameters.supply_pressure.value",
        ["'70 bar'", "'unit:'"],
    ),
    (
        _negative_volume,
        "plant.components.supply.parameters.supply_volume",
        ["must be > 0 m^3", "got -3.0", "positive"],
    ),
    (
        _zero_bulk_modulus,
        "plant.components.oil.parameters.bulk_modulus",
        ["must be > 0 Pa", "0.0", "positive"],
    ),
    (
        _negative_mass,
        "plant.components.cylinder.parameters.piston_mass",
        ["must be > 0 kg", "-1.0", "positive"],
    ),
    (_limits_swapped, "actuator", ["`lower < upper` must hold", "lower=0.02", "swap them"]),
    (
        _pressure_in_cm,
        "plant.components.supply.parameters.supply_pressure.unit",
        ["unit 'cm'", "does not fit", "give it in 'Pa'"],
    ),
    (
        _unknown_unit,
        "plant.components.cylinder.parameters.piston_diameter.unit",
        ["'furlong'", "known units:"],
    ),
    (
        _unreadable_unit,
        "plant.components.cylinder.parameters.piston_diameter.unit",
        ["'m**(1/0)'", "write it like"],
    ),
    (_unknown_plant, "plant.type", ["'hydraulic_crane'", "plant.components"]),
    (
        _unknown_signal,
        "scenarios.pulses.reference.type",
        ["'sawtooth'", "choose one of", "steps"],
    ),
    (_warmup_too_long, "scenarios.pulses.warmup", ["22.0 s", "shorter than the duration"]),
    (
        _override_nonphysical,
        "scenarios.pulses.overrides.oil.bulk_modulus",
        ["must be > 0 Pa", "-100000.0", "positive"],
    ),
    (
        _override_misspelled,
        "scenarios.pulses.overrides.supply.supply_presure",
        ["did you mean 'supply.supply_pressure'?"],
    ),
    (_null_section, "plant", ["must be a mapping", "null", "indented"]),
    (
        _list_for_mapping,
        "plant.components.cylinder.parameters",
        ["must be a mapping", "list", "indented"],
    ),
    (_number_for_text, "plant.components.cylinder.type", ["must be text", "int 5"]),
    (
        _null_value,
        "plant.components.oil.parameters.bulk_modulus.value",
        ["must be a number", "null"],
    ),
    (
        _huge_int,
        "plant.components.cylinder.parameters.piston_mass.value",
        ["must be finite", "write a plain number"],
    ),
    (_list_for_number, "scenarios.pulses.reference.base", ["must be a number", "[6.2]"]),
    (_text_in_list, "scenarios.steps.reference.values[1]", ["must be a number", "'high'"]),
    (_duty_out_of_range, "scenarios.pulses.reference.duty", ["(0, 1)", "1.5"]),
    (_steps_not_increasing, "scenarios.steps.reference.times_s", ["increase strictly"]),
    (_sample_time_zero, "controller.sample_time", ["must be > 0 s", "sampling period"]),
    (_sensor_gain_zero, "feedback.gain", ["must not be zero", "reading per unit of y"]),
    (_bad_display_unit, "output.display_unit", ["unit 'bar'", "give it in 'm'"]),
    (_no_scenarios, "scenarios", ["no scenarios", "add at least one"]),
]


@pytest.mark.parametrize(
    ("mutate", "key", "hints"), RIG_CASES, ids=[c[0].__name__.strip("_") for c in RIG_CASES]
)
def test_bad_rig_file(tmp_path, mutate, key, hints):
    data = shipped("rigs", "dinca_cylinder")
    mutate(data)
    expect_error(load_rig, write(tmp_path, data), key, *hints)


def test_bad_sensor_in_motor_rig(tmp_path):
    data = shipped("rigs", "ehs160_motor")
    rename(data["sensors"]["position"], "ratio", "ration")
    expect_error(load_rig, write(tmp_path, data), "sensors.position.ration", "'ratio'")


def test_bad_load_signal_in_motor_rig(tmp_path):
    data = shipped("rigs", "ehs160_motor")
    data["scenarios"]["brake"]["load"]["unit"] = "bar"
    expect_error(load_rig, write(tmp_path, data), "scenarios.brake.load.unit", "give it in 'N*m'")


def test_mutations_leave_shipped_data_valid(tmp_path):
    """The cases above fail for the broken key, not because the copy was already bad."""
    assert load_rig(write(tmp_path, shipped("rigs", "dinca_cylinder"))).name == "dinca_cylinder"


@pytest.mark.parametrize(
    ("reference", "expected"),
    [
        ({"type": "constant", "unit": "cm", "value": 3.0}, [5.75 + 0.1936 * 3.0] * 3),
        (
            {"type": "steps", "unit": "mm", "initial": 0, "times_s": [1.0], "values": [25.0]},
            [5.75, 5.75 + 0.1936 * 2.5, 5.75 + 0.1936 * 2.5],
        ),
    ],
)
def test_reference_in_length_goes_through_the_sensor(tmp_path, reference, expected):
    """Seed 002 eq. 19: U_R = 5.75 V + 0.1936 V/cm · y, so a reference in cm is a voltage."""
    data = shipped("rigs", "dinca_cylinder")
    data["scenarios"]["pulses"]["reference"] = reference
    rig = load_rig(write(tmp_path, data))
    values = rig.scenarios["pulses"].reference.sample(np.array([0.0, 1.0, 5.0]))
    np.testing.assert_allclose(values, expected, rtol=1e-12)


def test_reference_in_wrong_dimension(tmp_path):
    data = shipped("rigs", "dinca_cylinder")
    data["scenarios"]["pulses"]["reference"]["unit"] = "bar"
    expect_error(
        load_rig,
        write(tmp_path, data),
        "scenarios.pulses.reference.unit",
        "'bar'",
        "feedback unit (V)",
        "give the reference in one of them",
    )


# --------------------------------------------------------------------------- file level
def test_invalid_yaml_names_the_line(tmp_path):
    path = tmp_path / "broken.yaml"
    path.write_text("name: broken\ntitle: x\nplant: [unclosed\nsource: y\n", encoding="utf-8")
    message = expect_error(load_rig, path, None, "not valid YAML", "fix the syntax")
    assert "line 4" in message


def test_tab_indentation_names_the_line(tmp_path):
    path = tmp_path / "tabs.yaml"
    path.write_text("name: x\nplant:\n  components: {}\n\tinitial: {}\n", encoding="utf-8")
    assert "line 4" in expect_error(load_rig, path, None, "not valid YAML")


def test_file_not_found(tmp_path):
    missing = tmp_path / "no_such_rig.yaml"
    expect_error(load_rig, missing, None, "file not found", "check the path")
    expect_error(load_controller, missing, None, "file not found")


@pytest.mark.parametrize("content", [[1, 2, 3], "just text", 42, None])
def test_top_level_not_a_mapping(tmp_path, content):
    path = write(tmp_path, content)
    expect_error(load_rig, path, None, "top level must be a mapping", "name: ...")
    expect_error(load_controller, path, None, "top level must be a mapping")


def test_file_not_utf8(tmp_path):
    path = tmp_path / "latin1.yaml"
    path.write_bytes("name: Dînca\n".encode("latin-1"))
    expect_error(load_rig, path, None, "not UTF-8", "save the file as UTF-8")


# --------------------------------------------------------------------------- controller files
def _kind_unknown(d):
    d["kind"] = "PID"


def _kind_missing(d):
    del d["kind"]


def _gain_misspelled(d):
    rename(d, "gain", "gian")


def _limits_wrong_order(d):
    d["output_limits"] = [10, -10]


def _limits_three(d):
    d["output_limits"] = [-10, 0, 10]


def _limits_text(d):
    d["output_limits"] = "±10 V"


def _gain_text(d):
    d["gain"] = "ten"


def _gain_with_unit(d):
    d["gain"] = {"value": 10, "unit": "V/V"}


def _pi_key_on_p(d):
    d["ki"] = 0.5


CONTROLLER_CASES = [
    (_kind_unknown, "kind", ["'PID'", "choose one of", "'PI'"]),
    (_kind_missing, None, ["missing key 'kind'", "open_loop"]),
    (_gain_misspelled, "gian", ["unknown key", "did you mean 'gain'?"]),
    (_limits_wrong_order, "output_limits", ["u_min < u_max", "[10.0, -10.0]", "[-10, 10]"]),
    (_limits_three, "output_limits", ["[u_min, u_max]", "[-10, 10]"]),
    (_limits_text, "output_limits", ["must be a list of numbers", "[1, 2.5]"]),
    (_gain_text, "gain", ["must be a number", "'ten'"]),
    (_gain_with_unit, "gain", ["takes no unit"]),
    (_pi_key_on_p, "ki", ["kind PI, not P", "remove it or change kind"]),
]


@pytest.mark.parametrize(
    ("mutate", "key", "hints"),
    CONTROLLER_CASES,
    ids=[c[0].__name__.strip("_") for c in CONTROLLER_CASES],
)
def test_bad_controller_file(tmp_path, mutate, key, hints):
    data = shipped("studies/controllers", "p_k10")
    mutate(data)
    expect_error(load_controller, write(tmp_path, data), key, *hints)


def test_controller_copy_is_valid(tmp_path):
    assert load_controller(write(tmp_path, shipped("studies/controllers", "p_k10"))).gain == 10


# --------------------------------------------------------------------------- command line
def _one_error_line(capsys) -> str:
    captured = capsys.readouterr()
    lines = captured.err.splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith("fuzzyservo: error: ")
    assert "Traceback" not in captured.err
    return lines[0]


@pytest.mark.parametrize(
    "mutate",
    [_param_misspelled, _null_section, _list_for_mapping, _huge_int, _unreadable_unit],
    ids=lambda f: f.__name__.strip("_"),
)
def test_cli_bad_rig_file(tmp_path, capsys, mutate):
    data = shipped("rigs", "dinca_cylinder")
    mutate(data)
    bad = write(tmp_path, data, "bad_rig.yaml")
    assert main(["compare", str(bad), "--out", str(tmp_path / "out")]) == 2
    line = _one_error_line(capsys)
    assert str(bad) in line
    assert not (tmp_path / "out").exists()


def test_cli_unreadable_rig_files(tmp_path, capsys):
    broken = tmp_path / "broken.yaml"
    broken.write_text("plant: {type: x\n", encoding="utf-8")
    latin1 = tmp_path / "latin1.yaml"
    latin1.write_bytes("name: Dînca\n".encode("latin-1"))
    for path in (broken, latin1, tmp_path / "missing.yaml"):
        assert main(["compare", str(path), "--out", str(tmp_path)]) == 2
        assert str(path) in _one_error_line(capsys)


def test_cli_unknown_scenario(tmp_path, capsys):
    argv = ["compare", "dinca_cylinder", "p_k10", "--scenario", "nope", "--out", str(tmp_path)]
    assert main(argv) == 2
    line = _one_error_line(capsys)
    assert "'nope'" in line
    for known in shipped("rigs", "dinca_cylinder")["scenarios"]:
        assert known in line


def test_cli_unknown_controller(tmp_path, capsys):
    argv = ["compare", "dinca_cylinder", "no_such_controller", "--out", str(tmp_path)]
    assert main(argv) == 2
    line = _one_error_line(capsys)
    assert "'no_such_controller'" in line
    assert "p_k10" in line


def test_cli_bad_controller_file(tmp_path, capsys):
    data = shipped("studies/controllers", "p_k10")
    _kind_unknown(data)
    bad = write(tmp_path, data, "bad_controller.yaml")
    assert main(["compare", "dinca_cylinder", str(bad), "--out", str(tmp_path)]) == 2
    assert f"{bad}: kind:" in _one_error_line(capsys)


# --------------------------------------------------------------------------- shipped files
def _numbers_outside_quantities(node: Any, path: tuple) -> list[str]:
    """Dotted paths of numbers not written as ``{value, unit, source}`` (scenarios excepted)."""
    if path[:1] == ("scenarios",):
        return []
    if isinstance(node, dict):
        if "value" in node:
            missing = QUANTITY_KEYS - set(node)
            return [f"{'.'.join(path)} lacks {sorted(missing)}"] if missing else []
        return [p for k, v in node.items() for p in _numbers_outside_quantities(v, (*path, k))]
    if isinstance(node, list):
        return [p for i, v in enumerate(node) for p in _numbers_outside_quantities(v, (*path, i))]
    is_number = isinstance(node, int | float) and not isinstance(node, bool)
    if isinstance(node, str) and path[-1] != "unit":
        try:
            is_number = math.isfinite(float(node))
        except ValueError:
            pass
    return [f"{'.'.join(map(str, path))} = {node!r} is a bare number"] if is_number else []


@pytest.mark.parametrize("path", RIG_FILES, ids=lambda p: p.stem)
def test_shipped_rig_numbers_carry_unit_and_source(path):
    data = yaml.safe_load(path.read_text(encoding="utf-8"))
    assert _numbers_outside_quantities(data, ()) == []
    plant = data["plant"]
    if "components" in plant:  # a composition: each component's parameters
        sections = [c.get("parameters", {}) for c in plant["components"].values()]
    else:
        sections = [plant["parameters"]]
    sections.append(plant.get("initial", {}))
    sections += [data["actuator"], data["controller"], data["feedback"]]
    sections += list(data.get("sensors", {}).values())
    for section in sections:
        for key, value in section.items():
            if key in ("name", "signal", "unit"):
                continue
            assert isinstance(value, dict), f"{path.name}: {key} = {value!r}"
            if "file" in value:  # a vector parameter read from a file (e.g. nn_weights)
                assert isinstance(value["source"], str) and value["source"].strip()
                continue
            assert QUANTITY_KEYS <= set(value), f"{path.name}: {key} lacks {QUANTITY_KEYS}"
            assert isinstance(value["source"], str) and value["source"].strip()


def test_number_walk_flags_bare_numbers():
    """The walk above would catch a bare number or a quantity without its source."""
    data = {
        "plant": {"parameters": {"m": 1, "d": {"value": 2, "unit": "cm"}}},
        "scenarios": {"a": 3},
    }
    found = _numbers_outside_quantities(copy.deepcopy(data), ())
    assert found == [
        "plant.parameters.m = 1 is a bare number",
        "plant.parameters.d lacks ['source']",
    ]


def test_the_public_loaders_take_a_shipped_name_or_a_path(tmp_path):
    """``load_rig("dinca_cylinder")`` and ``load_controller("p_k10")`` find the shipped
    files from any folder, as every command does; a path still means that file, and an
    unknown name lists the known ones."""
    from fuzzyservo import load_controller, load_rig
    from fuzzyservo.errors import ConfigError

    assert load_rig("dinca_cylinder").name == "dinca_cylinder"
    assert load_controller("p_k10").name == "p_k10"
    with pytest.raises(ConfigError, match=r"no rig named .nope.; known: .*dinca_cylinder"):
        load_rig("nope")
    with pytest.raises(ConfigError, match="file not found"):
        load_rig(tmp_path / "missing.yaml")
