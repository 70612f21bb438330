"""MATLAB ``.fis`` files: exact round trip, MATLAB's tipper example, bad input (STYLE.md 9)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from support import DATA

from fuzzyservo.cli import main
from fuzzyservo.controllers.fuzzy.controller import FuzzyController
from fuzzyservo.controllers.fuzzy.fis import fis_text, parse_fis
from fuzzyservo.controllers.fuzzy.skfuzzy_adapter import SkfuzzyReference
from fuzzyservo.errors import ConfigError
from fuzzyservo.io.controllers import load_controller
from fuzzyservo.io.fuzzy_files import controller_from_fis, read_fis, write_fis
from fuzzyservo.io.rigs import load_rig
from fuzzyservo.simulation import simulate

TIPPER = Path(__file__).resolve().parent / "data" / "tipper.fis"
SHIPPED = ["flc1_translated", "flc2_reshaped"]


def shipped(name: str) -> FuzzyController:
    return load_controller(DATA / "studies" / "controllers" / f"{name}.yaml")


# --------------------------------------------------------------------------- round trip
@pytest.mark.parametrize("name", SHIPPED)
def test_export_import_is_exact(tmp_path, name):
    original = shipped(name)
    path = write_fis(original.system, tmp_path / f"{name}.fis")
    system = read_fis(path)
    assert system == original.system  # dataclass equality (description is not compared)
    back = controller_from_fis(path)
    assert (back.form, back.name) == ("p", name)
    assert (back.input_gain, back.output_gain) == (1.0, 1.0) and not back.has_limits
    e = np.linspace(-2.5, 2.5, 1001)  # beyond the range too: inputs are clipped
    same_gains = FuzzyController(system=original.system, form="p")
    np.testing.assert_array_equal(back.curve(e), same_gains.curve(e))


def test_two_input_round_trip_keeps_not_none_or_and_weights():
    system = read_fis(TIPPER)
    text = fis_text(system).replace("3 2, 3 (1) : 2", "3 -1, 3 (0.25) : 2")
    text = text.replace("2 0, 2 (1) : 1", "2 -2, 2 (0.1) : 1")
    edited = parse_fis(text)
    assert edited.rules[2].antecedent == (2, -2) and edited.rules[2].weight == 0.25
    assert edited.rules[1].antecedent == (1, -3) and edited.rules[1].connective == "and"
    assert parse_fis(fis_text(edited)) == edited


def test_rule_term_codes_decode_in_one_place():
    """term_code/term_index and the .fis MF numbers (k > 0, 0 none, -k NOT) are inverses."""
    from fuzzyservo.controllers.fuzzy.system import (
        NO_TERM,
        from_matlab,
        term_code,
        term_index,
        to_matlab,
    )

    assert term_index(NO_TERM) == (-1, False)
    for k in range(4):
        for negated in (False, True):
            assert term_index(term_code(k, negated)) == (k, negated)
    for number in (-3, -1, 0, 1, 3):
        assert to_matlab(from_matlab(number)) == number
    assert (from_matlab(0), from_matlab(2), from_matlab(-2)) == (NO_TERM, 1, term_code(1, True))


def test_a_not_consequent_reads_as_not_in_the_rule_lines():
    """The rule line and the designer's rule table decode the consequent: NOT Z is no
    longer shown as another term (a negative index into the terms did that)."""
    from fuzzyservo.io.fuzzy import rule_text

    system = read_fis(TIPPER)
    text = fis_text(system).replace("3 2, 3 (1) : 2", "3 2, -3 (1) : 2")
    edited = parse_fis(text)
    rule = edited.rules[2]
    assert rule_text(edited, rule).endswith(f"-> ~{edited.output.terms[2].name}")


def test_written_text_is_matlab_layout():
    system = shipped("flc1_translated").system
    lines = fis_text(system).splitlines()
    out = system.output
    assert lines[:4] == ["[System]", "Name='flc1_translated'", "Type='mamdani'", "Version=2.0"]
    for key in (
        "NumInputs=1",
        "NumOutputs=1",
        "NumRules=7",
        "AndMethod='min'",
        "OrMethod='max'",
        "ImpMethod='min'",
        "AggMethod='max'",
        "DefuzzMethod='centroid'",
        "[Input1]",
        "Range=[-2 2]",
        "NumMFs=7",
        "[Output1]",
        f"Range=[{float(out.low)!r} {float(out.high)!r}]".replace(".0 ", " ").replace(".0]", "]"),
        "[Rules]",
        "1, 1 (1) : 1",
    ):
        assert key in lines, key
    ns = out.terms[2]
    assert (
        f"MF3='NS':'trimf',[{' '.join(repr(float(p)).removesuffix('.0') for p in ns.params)}]"
        in lines
    )  # repr digits


def test_names_that_cannot_be_quoted_are_refused():
    system = shipped("flc1_translated").system
    bad = dataclasses.replace(system, name="it's")
    with pytest.raises(ValueError, match="rename it"):
        fis_text(bad)


# --------------------------------------------------------------------------- MATLAB's tipper
def test_tipper_reads_as_documented():
    system = read_fis(TIPPER)
    assert [v.name for v in system.inputs] == ["service", "food"]
    assert [t.name for t in system.output.terms] == ["cheap", "average", "generous"]
    assert [r.connective for r in system.rules] == ["or", "and", "or"]
    assert system.rules[1].antecedent == (1, -1)  # "2 0": food not used
    c = load_controller(TIPPER)
    assert (c.form, c.name) == ("pd", "tipper")


def test_tipper_compiled_evaluator_matches_scikit_fuzzy():
    c = controller_from_fis(TIPPER)
    rng = np.random.default_rng(7)
    pts = np.vstack([rng.uniform(0, 10, (30, 2)), [[0, 0], [10, 10], [3, 8], [5, 5], [0, 10]]])
    fast = c.curve(pts[:, 0], pts[:, 1])
    with SkfuzzyReference(c.system) as ref:
        slow = ref.compute_many(pts)
    np.testing.assert_allclose(fast, slow, rtol=0, atol=1e-9 * 30.0)  # 1e-9 of the range


def test_tipper_against_matlab_evalfis():
    """MATLAB's documented outputs (mathworks.com/help/fuzzy/mamfis.evalfis.html:
    [2 1] → 7.0169, [4 5] → 14.4585, [7 8] → 20.3414; older guide, "FIS Evaluation":
    [1 2] → 5.5586). MATLAB samples the output on 101 points and evaluates input MFs
    analytically; we sample 201 points plus breakpoints and interpolate inputs, so the
    values differ in the third decimal. (The 16.7 % shown for service 3, food 8 in the
    guide's inference diagram is an illustration with other MFs: tipper.fis gives 18.006
    there, analytically and here.)"""
    c = controller_from_fis(TIPPER)
    service, food = np.array([2.0, 4, 7, 1]), np.array([1.0, 5, 8, 2])
    np.testing.assert_allclose(
        c.curve(service, food), [7.0169, 14.4585, 20.3414, 5.5586], rtol=0, atol=0.02
    )
    # symmetric inputs give the average tip; clipped-triangle centroid at (3, 8)
    assert c.curve(np.array([5.0]), np.array([5.0]))[0] == pytest.approx(15.0, abs=1e-9)
    assert c.curve(np.array([3.0]), np.array([8.0]))[0] == pytest.approx(18.006, abs=0.01)


def test_classic_tipper_and_newer_file_agree():
    """The MATLAB 6.5 tipper (food [0 0 1 3], [7 9 10 10], no Version, no counts) equals the
    R2018b+ one on the range; NumMFs/NumInputs/NumRules may be missing."""
    text = TIPPER.read_text(encoding="utf-8")
    classic = text.replace("[-2 0 1 3]", "[0 0 1 3]").replace("[7 9 10 12]", "[7 9 10 10]")
    classic = "\n".join(
        line for line in classic.splitlines() if not line.startswith(("Version", "Num"))
    )
    old = parse_fis(classic, "classic.fis")
    new = read_fis(TIPPER)
    grid = np.linspace(0, 10, 41)
    s, f = np.meshgrid(grid, grid)
    np.testing.assert_array_equal(
        FuzzyController(system=old, form="pd").curve(s, f),
        FuzzyController(system=new, form="pd").curve(s, f),
    )


def test_latin1_file_and_comments(tmp_path):
    text = "# exported\n" + TIPPER.read_text(encoding="utf-8").replace("'cheap'", "'bon marché'")
    path = tmp_path / "tipper_fr.fis"
    path.write_bytes(text.encode("latin-1"))
    assert read_fis(path).output.terms[0].name == "bon marché"


# --------------------------------------------------------------------------- simulation
def test_fis_controller_simulates_on_the_rig(tmp_path):
    path = write_fis(shipped("flc1_translated").system, tmp_path / "flc1.fis")
    controller = load_controller(path)
    result = simulate(
        load_rig(DATA / "rigs" / "dinca_cylinder.yaml"), controller, "steps", duration_s=4
    )
    assert result.status == "ok", result.message


# --------------------------------------------------------------------------- bad input
BASE = TIPPER.read_text(encoding="utf-8")


def edit(old: str, new: str) -> str:
    assert old in BASE, old
    return BASE.replace(old, new, 1)


BAD = {
    "sugeno terms in mamdani": (
        edit("'trimf',[0 5 10]", "'constant',[5]"),
        "[Output1].MF1",
        "Sugeno output term",
    ),
    "mamdani terms in sugeno": (
        edit("Type='mamdani'", "Type='sugeno'").replace("'centroid'", "'wtaver'"),
        "[Output1].MF1",
        "'constant' or 'linear'",
    ),
    "sugeno defuzz": (edit("Type='mamdani'", "Type='sugeno'"), "[System].DefuzzMethod", "wtaver"),
    "type2": (edit("Type='mamdani'", "Type='mamdanitype2'"), "[System].Type", "type-2"),
    "hybrid": (edit("Type='mamdani'", "Type='hybrid'"), "[System].Type", "mamdani, sugeno"),
    "fuzzylite shape": (
        edit("'gaussmf',[1.5 10]", "'rampmf',[1 2]"),
        "[Input1].MF3",
        "fuzzylite shape",
    ),
    "custom shape": (
        edit("'gaussmf',[1.5 10]", "'my_custom_mf',[1 2]"),
        "[Input1].MF3",
        "my_custom_mf",
    ),
    "too few params": (
        edit("'gaussmf',[1.5 10]", "'pimf',[1 2 3]"),
        "[Input1].MF3",
        "pimf takes 4",
    ),
    "decimal MF number": (
        edit("3 2, 3 (1) : 2", "2.5 2, 3 (1) : 2"),
        "[Rules]",
        "not a whole number",
    ),
    "NumInputs=3": (edit("NumInputs=2", "NumInputs=3"), "[System].NumInputs", "2 input"),
    "two outputs": (
        BASE.replace("[Rules]", "[Output2]\nName='y'\nRange=[0 1]\n\n[Rules]"),
        "[System].NumOutputs",
        "2 output sections",
    ),
    "NumOutputs=2": (edit("NumOutputs=1", "NumOutputs=2"), "[System].NumOutputs", "1 output"),
    "missing MF in rule": (edit("3 2, 3 (1) : 2", "4 2, 3 (1) : 2"), "[Rules]", "MF4"),
    "missing output MF": (edit("3 2, 3 (1) : 2", "3 2, 4 (1) : 2"), "[Rules]", "MF4"),
    "no condition": (edit("3 2, 3 (1) : 2", "0 0, 3 (1) : 2"), "[Rules]", "no condition"),
    "one antecedent": (edit("3 2, 3 (1) : 2", "3, 3 (1) : 2"), "[Rules]", "2 input(s)"),
    "two consequents": (edit("3 2, 3 (1) : 2", "3 2, 3 1 (1) : 2"), "[Rules]", "2 output"),
    "weight > 1": (edit("3 2, 3 (1) : 2", "3 2, 3 (2) : 2"), "[Rules]", "[0, 1]"),
    "connective 3": (edit("3 2, 3 (1) : 2", "3 2, 3 (1) : 3"), "[Rules]", "1 (AND) or 2 (OR)"),
    "rule without comma": (edit("3 2, 3 (1) : 2", "3 2 3 (1) : 2"), "[Rules]", "cannot read"),
    "NumMFs wrong": (edit("NumMFs=2", "NumMFs=4"), "[Input2].NumMFs", "4"),
    "NumRules wrong": (edit("NumRules=3", "NumRules=5"), "[System].NumRules", "3 rule"),
    "NumInputs wrong": (edit("NumInputs=2", "NumInputs=1"), "[System].NumInputs", "2 input"),
    "NumMFs not a number": (edit("NumMFs=2", "NumMFs=two"), "[Input2].NumMFs", "whole number"),
    "unclosed MF": (edit("[1.5 10]", "[1.5 10"), "[Input1].MF3", "cannot read"),
    "MF params count": (edit("[0 5 10]", "[0 5]"), "[Output1].MF1", "trimf takes 3"),
    "MF params order": (edit("[0 5 10]", "[10 5 0]"), "[Output1].MF1", "in order"),
    "MF param text": (edit("[0 5 10]", "[0 five 10]"), "[Output1].MF1", "'five'"),
    "MF param inf": (edit("[0 5 10]", "[0 5 Inf]"), "[Output1].MF1", "finite"),
    "range reversed": (edit("Range=[0 30]", "Range=[30 0]"), "[Output1].Range", "low"),
    "range empty": (edit("Range=[0 30]", "Range=[5 5]"), "[Output1].Range", "low"),
    "range one number": (edit("Range=[0 30]", "Range=[30]"), "[Output1].Range", "two numbers"),
    "range no brackets": (edit("Range=[0 30]", "Range=0 30"), "[Output1].Range", "brackets"),
    "missing range": (edit("Range=[0 30]\n", ""), "[Output1]", "Range"),
    "no MFs": (
        BASE.split("MF1='cheap'")[0] + "\n[Rules]\n1 1, 1 (1) : 2\n",
        "[Output1]",
        "no membership",
    ),
    "and method": (edit("AndMethod='min'", "AndMethod='myand'"), "[System].AndMethod", "prod"),
    "defuzz wtaver": (
        edit("DefuzzMethod='centroid'", "DefuzzMethod='wtaver'"),
        "[System].DefuzzMethod",
        "bisector",
    ),
    "unquoted name": (edit("Name='tip'", "Name=tip"), "[Output1].Name", "single quotes"),
    "no equals": (edit("NumRules=3", "NumRules 3"), "[System] (line", "Key=value"),
    "duplicate key": (edit("NumRules=3", "NumRules=3\nNumRules=3"), "[System].NumRules", "twice"),
    "unknown key": (edit("NumRules=3", "Colour='red'"), "[System].Colour", "unknown key"),
    "unknown section": (edit("[Rules]", "[Rulez]"), "line", "[Rulez]"),
    "duplicate section": (BASE + "\n[Output1]\nName='x'\n", "line", "twice"),
    "text before system": ("hello\n" + BASE, "line", "before the first section"),
    "no system": (BASE.split("[Input1]")[1], "line", "[System]"),
    "empty file": ("", "[System]", "no [System]"),
    "only comments": ("% nothing\n# here\n", "[System]", "no [System]"),
    "missing type": (edit("Type='mamdani'\n", ""), "[System]", "Type"),
    "no rules section": (BASE.split("[Rules]")[0], "[System]", "[Rules]"),
    "empty rules": (BASE.split("[Rules]")[0] + "[Rules]\n", "[Rules]", "empty"),
    "no output": (
        BASE.split("[Output1]")[0] + "[Rules]" + BASE.split("[Rules]")[1],
        "[System]",
        "no [Output1]",
    ),
    "input9": (edit("[Output1]", "[Input9]"), "line", "without [Input3]"),
    "input2 only": (
        BASE.split("[Input1]")[0] + "[Input2]" + BASE.split("[Input2]")[1],
        "line",
        "without [Input1]",
    ),
}


def expect_fis_error(path: Path, where: str | None, hint: str) -> str:
    with pytest.raises(ConfigError) as info:
        read_fis(path)
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(f"{path}: ")
    assert message.count(str(path)) == 1
    if where is not None:
        assert info.value.key is not None and where in info.value.key, info.value.key
        assert "line" in info.value.key or info.value.key.startswith("["), info.value.key
    assert hint in message, message
    assert ";" in info.value.detail, f"no fix after the problem in {message!r}"
    return message


@pytest.mark.parametrize("case", BAD, ids=str)
def test_bad_fis_is_one_located_config_error(tmp_path, case):
    text, where, hint = BAD[case]
    path = tmp_path / "bad.fis"
    path.write_text(text, encoding="utf-8")
    expect_fis_error(path, where, hint)


def test_errors_carry_line_numbers(tmp_path):
    path = tmp_path / "bad.fis"
    path.write_text(BAD["custom shape"][0], encoding="utf-8")
    assert "[Input1].MF3 (line 25): unsupported membership function 'my_custom_mf'" in (
        expect_fis_error(path, "[Input1].MF3", "replace it")
    )


def test_missing_file_and_uncovered_rule_base(tmp_path):
    expect_fis_error(tmp_path / "nowhere.fis", None, "not found")
    # narrow service triangles leave gaps (e.g. service 3) where no rule fires
    path = tmp_path / "holes.fis"
    path.write_text(
        BASE.replace("MF1='poor':'gaussmf',[1.5 0]", "MF1='poor':'trimf',[0 1 2]")
        .replace("MF2='good':'gaussmf',[1.5 5]", "MF2='good':'trimf',[4 5 6]")
        .replace("MF3='excellent':'gaussmf',[1.5 10]", "MF3='excellent':'trimf',[8 9 10]")
        .replace("1 1, 1 (1) : 2", "1 0, 1 (1) : 1")
        .replace("3 2, 3 (1) : 2", "3 0, 3 (1) : 1"),
        encoding="utf-8",
    )
    read_fis(path)  # the system itself is valid ...
    with pytest.raises(ConfigError, match=r"holes\.fis: \[Rules\]: .*uncovered.*; "):
        controller_from_fis(path)  # ... but leaves inputs where no rule fires


def test_cli_turns_a_bad_fis_into_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.fis"
    bad.write_text(BAD["custom shape"][0], encoding="utf-8")
    assert main(["compare", "dinca_cylinder", str(bad), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(bad) in err[0] and "my_custom_mf" in err[0]


def test_mf_lines_are_read_in_order_as_matlab_does(tmp_path):
    """A key that names another number than its line's place (a gap, a number given twice)
    is read by its place, as MATLAB reads MF lines, with a warning naming the line."""
    from fuzzyservo.errors import FileWarning

    path = tmp_path / "gap.fis"
    path.write_text(edit("MF3='excellent'", "MF4='excellent'"), encoding="utf-8")
    with pytest.warns(FileWarning, match=r"\[Input1\]\.MF4 \(line \d+\): read as MF3"):
        system = read_fis(path)
    assert system == read_fis_text_quietly(BASE)


def read_fis_text_quietly(text: str):
    from fuzzyservo.controllers.fuzzy.fis import parse_fis

    return parse_fis(text, "base.fis")
