"""MATLAB interop: evalfis semantics, per-rule aggregation, Sugeno, lossless .fis and FCL
round trips, the evaluate command, bad FCL and CSV input (STYLE.md 9)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from support import DATA, SHARED

from fuzzyservo.cli import main
from fuzzyservo.controllers.fuzzy.evaluate import evaluate_inputs
from fuzzyservo.controllers.fuzzy.fcl import fcl_text, parse_fcl
from fuzzyservo.controllers.fuzzy.fis import fis_text, parse_fis
from fuzzyservo.controllers.fuzzy.shapes import mf_array
from fuzzyservo.controllers.fuzzy.system import FuzzySystem, Rule, Term, Variable
from fuzzyservo.errors import ConfigError
from fuzzyservo.io.controllers import load_controller
from fuzzyservo.io.fuzzy_files import read_fis

TIPPER = Path(__file__).resolve().parent / "data" / "tipper.fis"
CONFORMANCE = SHARED / "conformance" / "fuzzylite" / "examples"


def matlab(system: FuzzySystem, **changes) -> FuzzySystem:
    return dataclasses.replace(system, semantics="matlab", **changes)


# --------------------------------------------------------------------------- evalfis
def test_matlab_semantics_give_evalfis_numbers_for_tipper():
    """MATLAB's documented outputs (mathworks.com/help/fuzzy/mamfis.evalfis.html:
    [2 1] → 7.0169, [4 5] → 14.4585, [7 8] → 20.3414; "FIS Evaluation": [1 2] → 5.5586),
    which the skfuzzy semantics miss in the third decimal (test_fis.py)."""
    out, silent = evaluate_inputs(
        matlab(read_fis(TIPPER)), np.array([[2, 1], [4, 5], [7, 8], [1, 2.0]])
    )
    np.testing.assert_allclose(out[:, 0], [7.0169, 14.4585, 20.3414, 5.5586], rtol=0, atol=5e-5)
    assert silent == 0


def test_no_rule_fired_is_mid_range_in_matlab_and_nan_in_skfuzzy():
    v = Variable("x", 0.0, 10.0, (Term("low", "trimf", (0.0, 1.0, 2.0)),))
    out = Variable("y", -4.0, 6.0, (Term("a", "trimf", (-4.0, 1.0, 6.0)),))
    system = FuzzySystem("gap", (v,), out, (Rule((0,), 0),))
    for semantics, expected in (("matlab", 1.0), ("skfuzzy", np.nan)):
        got, silent = evaluate_inputs(
            dataclasses.replace(system, semantics=semantics), np.array([[5.0], [1.0]])
        )
        np.testing.assert_equal(got[0, 0], expected)
        assert silent == 1 and got[1, 0] == pytest.approx(1.0, abs=1e-9)


def aggregate_reference(system: FuzzySystem, x: float, n: int = 200_001) -> float:
    """Per-rule implication then aggregation, centroid of n samples, in numpy."""
    u = np.linspace(system.output.low, system.output.high, n)
    var = system.inputs[0]
    y = np.zeros(n)
    for rule in system.rules:
        t_in = var.terms[rule.antecedent[0]]
        w = mf_array(t_in.shape, t_in.params, np.array([x]))[0] * rule.weight
        t_out = system.output.terms[rule.consequent]
        mu = mf_array(t_out.shape, t_out.params, u)
        v = np.minimum(w, mu) if system.implication == "min" else w * mu
        y = (
            np.maximum(y, v)
            if system.aggregation == "max"
            else (y + v if system.aggregation == "sum" else y + v - y * v)
        )
    return float(np.sum(u * y) / np.sum(y))


@pytest.mark.parametrize("aggregation", ["sum", "probor", "max"])
@pytest.mark.parametrize("implication", ["min", "prod"])
def test_rules_sharing_a_consequent_are_implied_one_by_one(aggregation, implication):
    """Two rules conclude the same term with different strengths: implication per rule,
    then aggregation (the old evaluator merged them first: 0.5 % of the range off)."""
    x = Variable(
        "x", 0.0, 10.0, (Term("a", "trimf", (0.0, 3.0, 8.0)), Term("b", "trimf", (2.0, 6.0, 10.0)))
    )
    y = Variable(
        "y", 0.0, 10.0, (Term("c", "trimf", (1.0, 4.0, 9.0)), Term("d", "gaussmf", (1.5, 8.0)))
    )
    rules = (Rule((0,), 0), Rule((1,), 0, 0.8), Rule((1,), 1, 0.5))
    system = FuzzySystem("shared", (x,), y, rules, implication=implication, aggregation=aggregation)
    for xv in (3.5, 4.7, 5.5):
        ref = aggregate_reference(system, xv)
        fine, _ = evaluate_inputs(matlab(system, sample_points=20001), np.array([[xv]]))
        assert fine[0, 0] == pytest.approx(ref, abs=1e-4)
        sampled, _ = evaluate_inputs(system, np.array([[xv]]))
        assert sampled[0, 0] == pytest.approx(ref, abs=2e-3)  # 201-point universe, gaussmf


def test_sugeno_by_hand():
    """z = 2 e + 1 (linear) and 4 (constant); w = μ_low(e), μ_high(e) with linsmf/linzmf;
    wtaver Σwz/Σw, wtsum Σwz."""
    e = Variable(
        "e", 0.0, 1.0, (Term("low", "linzmf", (0.0, 1.0)), Term("high", "linsmf", (0.0, 1.0)))
    )
    u = Variable(
        "u", 0.0, 5.0, (Term("lin", "linear", (2.0, 1.0)), Term("four", "constant", (4.0,)))
    )
    system = FuzzySystem(
        "tsk", (e,), u, (Rule((0,), 0), Rule((1,), 1, 0.5)), type="sugeno", defuzzification="wtaver"
    )
    xs = np.array([[0.0], [0.25], [0.6], [1.0]])
    w1, w2 = 1 - xs[:, 0], 0.5 * xs[:, 0]
    z1 = 2 * xs[:, 0] + 1
    got, _ = evaluate_inputs(system, xs)
    np.testing.assert_allclose(got[:, 0], (w1 * z1 + w2 * 4) / (w1 + w2), rtol=0, atol=1e-12)
    got, _ = evaluate_inputs(dataclasses.replace(system, defuzzification="wtsum"), xs)
    np.testing.assert_allclose(got[:, 0], w1 * z1 + w2 * 4, rtol=0, atol=1e-12)


def test_shapes_match_matlab_definitions():
    x = np.array([-1.0, 0.0, 0.5, 1.0, 1.5, 2.0, 3.0])
    np.testing.assert_allclose(mf_array("smf", (0.0, 2.0), x), [0, 0, 0.125, 0.5, 0.875, 1, 1])
    np.testing.assert_allclose(mf_array("zmf", (0.0, 2.0), x), [1, 1, 0.875, 0.5, 0.125, 0, 0])
    np.testing.assert_allclose(
        mf_array("pimf", (0.0, 1.0, 2.0, 3.0), x)[[1, 3, 5, 6]], [0, 1, 1, 0]
    )
    np.testing.assert_allclose(mf_array("sigmf", (2.0, 1.0), np.array([1.0])), [0.5])
    np.testing.assert_allclose(mf_array("gauss2mf", (1.0, 0.0, 1.0, 1.0), np.array([0.5])), [1.0])
    np.testing.assert_allclose(mf_array("trimf", (0.0, 0.0, 2.0), np.array([0.0, -0.1])), [1, 0])


# --------------------------------------------------------------------------- round trips
def systems() -> list[FuzzySystem]:
    found = [read_fis(TIPPER), load_controller(DATA / "studies/controllers/fpi_ehs160.yaml").system]
    if CONFORMANCE.is_dir():
        for path in sorted(CONFORMANCE.rglob("*.fis")):
            try:
                found.append(read_fis(path))
            except ConfigError:
                pass
    return found


def test_fis_round_trip_is_lossless_settings_included():
    for system in systems():
        edited = dataclasses.replace(
            system,
            semantics="matlab",
            sample_points=57,
            inputs=(dataclasses.replace(system.inputs[0], points=33), *system.inputs[1:]),
        )
        for s in (system, edited):
            assert parse_fis(fis_text(s)) == s, s.name


def test_fcl_round_trip_is_lossless():
    done = 0
    for system in systems():
        try:
            text = fcl_text(system)
        except ValueError as exc:  # names FCL cannot hold (hyphens, spaces, repeated terms)
            assert "rename it" in str(exc) or "unique" in str(exc)
            continue
        assert parse_fcl(text) == system, system.name
        edited = dataclasses.replace(system, semantics="matlab", sample_points=11)
        assert parse_fcl(fcl_text(edited)) == edited
        done += 1
    assert done >= 2


def test_fcl_reads_standard_points_and_singletons():
    text = """FUNCTION_BLOCK demo
    VAR_INPUT e : REAL; END_VAR
    VAR_OUTPUT u : REAL; END_VAR
    FUZZIFY e
        TERM neg := (-1, 1) (0, 0);
        TERM pos := (0, 0) (1, 1);
        RANGE := (-1 .. 1);
    END_FUZZIFY
    DEFUZZIFY u
        TERM down := -2;
        TERM up := 2;
        METHOD : COGS;
        RANGE := (-2 .. 2);
    END_DEFUZZIFY
    RULEBLOCK r
        AND : MIN;
        RULE 1 : IF e IS neg THEN u IS down;
        RULE 2 : IF e IS pos
                 THEN u IS up WITH 0.5;
    END_RULEBLOCK
    END_FUNCTION_BLOCK
    """
    system = parse_fcl(text)
    assert system.type == "sugeno" and system.rules[1].weight == 0.5
    assert system.inputs[0].terms[0] == Term("neg", "trapmf", (-1.0, -1.0, -1.0, 0.0))
    out, _ = evaluate_inputs(system, np.array([[-1.0], [0.5]]))
    np.testing.assert_allclose(out[:, 0], [-2.0, 2.0])


@pytest.mark.parametrize(
    ("edit", "hint"),
    [
        (("IS neg THEN", "IS nog THEN"), "no term 'nog'"),
        (("RANGE := (-1 .. 1);", ""), "RANGE"),
        (("METHOD : COG;", "METHOD : FOO;"), "unsupported METHOD FOO"),
        (("IF e IS neg", "IF e IS neg AND e IS pos OR e IS neg"), "mixing AND and OR"),
        (("FUNCTION_BLOCK demo", "FUNCTION_BLOK demo"), "cannot read"),
    ],
)
def test_bad_fcl_is_one_located_config_error(edit, hint):
    text = """FUNCTION_BLOCK demo
VAR_INPUT
    e : REAL;
END_VAR
VAR_OUTPUT
    u : REAL;
END_VAR
FUZZIFY e
    RANGE := (-1 .. 1);
    TERM neg := (-2, 0) (-1, 1) (0, 0);
    TERM pos := (0, 0) (1, 1) (2, 0);
END_FUZZIFY
DEFUZZIFY u
    RANGE := (-2 .. 2);
    TERM down := (-2, 0) (-1, 1) (0, 0);
    TERM up := (0, 0) (1, 1) (2, 0);
    METHOD : COG;
END_DEFUZZIFY
RULEBLOCK r
    RULE 1 : IF e IS neg THEN u IS down;
    RULE 2 : IF e IS pos THEN u IS up;
END_RULEBLOCK
END_FUNCTION_BLOCK
"""
    parse_fcl(text, "ok.fcl")
    with pytest.raises(ConfigError) as info:
        parse_fcl(text.replace(*edit), "bad.fcl")
    assert hint in str(info.value) and "bad.fcl" in str(info.value) and "line" in str(info.value)


# --------------------------------------------------------------------------- evaluate
def test_evaluate_command_writes_one_column_per_output(tmp_path, capsys):
    csv = tmp_path / "in.csv"
    csv.write_text("time,food,service\n0,1,2\n1,5,4\n2,8,7\n3,2,1\n", encoding="utf-8")
    out = tmp_path / "res" / "out.csv"
    assert (
        main(["evaluate", str(TIPPER), str(csv), "--semantics", "matlab", "--out", str(out)]) == 0
    )
    lines = out.read_text(encoding="utf-8").splitlines()
    assert lines[0] == "tip"
    np.testing.assert_allclose(
        [float(v) for v in lines[1:]], [7.0169, 14.4585, 20.3414, 5.5586], atol=5e-5
    )
    err = capsys.readouterr().err
    assert "['time']" in err and "ignored" in err
    assert main(["evaluate", str(TIPPER), str(csv)]) == 0  # skfuzzy semantics, printed
    printed = capsys.readouterr().out.splitlines()
    assert printed[0] == "tip" and len(printed) == 5
    assert abs(float(printed[1]) - 7.0169) < 0.02


def test_evaluate_warns_when_no_rule_fires(tmp_path, capsys):
    v = Variable("x", 0.0, 10.0, (Term("low", "trimf", (0.0, 1.0, 2.0)),))
    out = Variable("y", -4.0, 6.0, (Term("a", "trimf", (-4.0, 1.0, 6.0)),))
    fis = tmp_path / "gap.fis"
    fis.write_text(fis_text(FuzzySystem("gap", (v,), out, (Rule((0,), 0),))), encoding="utf-8")
    csv = tmp_path / "in.csv"
    csv.write_text("x\n5\n1\n", encoding="utf-8")
    assert main(["evaluate", str(fis), str(csv), "--semantics", "matlab"]) == 0
    captured = capsys.readouterr()
    lines = captured.out.splitlines()
    assert lines[:2] == ["y", "1.0"] and float(lines[2]) == pytest.approx(1.0, abs=1e-9)
    assert "no rule fired for 1" in captured.err and "middle of its range" in captured.err


@pytest.mark.parametrize(
    ("content", "hint"),
    [
        ("service\n1\n", "no column for input(s) ['food']"),
        ("service,food\n1,x\n", "row 2: 'x' is not a finite number"),
        ("service,food\n", "no rows"),
        ("", "is empty"),
    ],
)
def test_evaluate_bad_csv_is_one_line(tmp_path, capsys, content, hint):
    csv = tmp_path / "in.csv"
    csv.write_text(content, encoding="utf-8")
    assert main(["evaluate", str(TIPPER), str(csv)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and hint in err[0] and str(csv) in err[0]


def test_export_writes_every_format(tmp_path, capsys):
    args = ["export", "flc_dinca_tuned", "--fis", str(tmp_path / "t.fis"), "--fcl",
            str(tmp_path / "t.fcl"), "--c", str(tmp_path / "c"), "--st", str(tmp_path / "t.st"),
            "--lut", "65"]  # fmt: skip
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert "largest error" in printed and "of the output range" in printed
    for name in ("t.fis", "t.fcl", "t.st", "c/flc_dinca_tuned.c", "c/flc_dinca_tuned.h"):
        assert (tmp_path / name).stat().st_size > 100
    tuned = load_controller(DATA / "studies/controllers/flc_dinca_tuned.yaml")
    assert read_fis(tmp_path / "t.fis") == tuned.system
    assert main(["export", "flc_dinca_tuned"]) == 2
    assert "at least one of" in capsys.readouterr().err
