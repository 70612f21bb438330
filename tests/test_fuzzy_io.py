"""Fuzzy controller files: every bad input is one line naming file, place, problem (and exit 2)."""

from __future__ import annotations

import copy

import pytest
import yaml
from support import DATA

from fuzzyservo.cli import main
from fuzzyservo.errors import ConfigError
from fuzzyservo.io.controllers import load_controller

FLC2 = yaml.safe_load((DATA / "studies" / "controllers" / "flc2_reshaped.yaml").read_text())
EXPLICIT_TERMS = {
    "NB": ["trapmf", [-5, -5, -2, -1]],
    "Z": ["trimf", [-1.5, 0, 1.5]],
    "PB": ["trapmf", [1, 2, 5, 5]],
}


def _write(tmp_path, data):
    path = tmp_path / "c.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _variant(change):
    data = copy.deepcopy(FLC2)
    change(data)
    return data


def _explicit(data, terms):
    data["input"] = {"name": "e", "range": [-2, 2], "terms": terms}
    data["output"] = {"name": "u", "range": [-3, 3], "terms": copy.deepcopy(EXPLICIT_TERMS)}
    data["rules"] = ["NB -> NB", "Z -> Z", "PB -> PB"]


CASES = [
    # unordered breakpoints of an explicit term
    (
        lambda d: _explicit(d, {**EXPLICIT_TERMS, "Z": ["trimf", [1.5, 0, -1.5]]}),
        "input.terms.Z",
        "in order",
    ),
    # overlapping nothing: a gap no rule covers
    (
        lambda d: _explicit(
            d,
            {
                "NB": ["trapmf", [-5, -5, -2, -1.5]],
                "Z": ["trimf", [-0.5, 0, 0.5]],
                "PB": ["trapmf", [1.5, 2, 5, 5]],
            },
        ),
        "",
        "uncovered",
    ),
    # fewer or more than the declared terms of a seven-term design
    (
        lambda d: d["input"].update(increments=[1, 1, 1, 1, 1, 1, 1]),
        "input.increments",
        "8 positive numbers",
    ),
    (lambda d: d["input"].update(increments=[1] * 9), "input.increments", "8 positive numbers"),
    (
        lambda d: d["input"].update(increments=[1, 1, -1, 1, 1, 1, 1, 1]),
        "input.increments",
        "8 positive",
    ),
    # rule names that do not exist
    (lambda d: d.update(rules=["NB -> NB", "ZZ -> Z"]), "rules[1]", "no term 'ZZ'"),
    (lambda d: d.update(rules=["NB -> XL"]), "rules[0]", "no term 'XL'"),
    (lambda d: d.update(rules=["NB => NB"]), "rules[0]", "cannot read rule"),
    # ranges of zero width or in the wrong order
    (lambda d: d["input"].update(range=[1, 1]), "input.range", "zero width"),
    (lambda d: d["output"].update(range=[3, -3]), "output.range", "low < high"),
    # methods, forms, gains, shapes
    (
        lambda d: d.update(methods={"defuzzification": "middle"}),
        "methods.defuzzification",
        "unknown method",
    ),
    (lambda d: d.update(form="pid"), "form", "unknown form"),
    (lambda d: d.update(gains={"output": 0}), "gains.output", "must not be zero"),
    (
        lambda d: _explicit(d, {**EXPLICIT_TERMS, "Z": ["rampmf", [1, 0]]}),
        "input.terms.Z",
        "unknown shape",
    ),
    (
        lambda d: _explicit(d, {**EXPLICIT_TERMS, "Z": ["trimf", [0, 1]]}),
        "input.terms.Z",
        "takes 3 parameters",
    ),
    (lambda d: d["input"].update(reshap=2.0), "input.reshap", "did you mean 'reshape'"),
    (lambda d: d.update(form="pd"), "", "'rate' input"),
]


@pytest.mark.parametrize(("change", "key", "text"), CASES)
def test_bad_fuzzy_files(tmp_path, change, key, text):
    path = _write(tmp_path, _variant(change))
    with pytest.raises(ConfigError) as info:
        load_controller(path)
    message = str(info.value)
    assert str(path) in message and key in message and text in message
    assert "\n" not in message


def test_cli_exit_2_on_a_bad_fuzzy_file(tmp_path, capsys):
    path = _write(tmp_path, _variant(lambda d: d.update(rules=["NB -> XL"])))
    assert main(["show", str(path), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Traceback" not in err[0]


def test_the_explicit_form_loads(tmp_path):
    c = load_controller(
        _write(tmp_path, _variant(lambda d: _explicit(d, copy.deepcopy(EXPLICIT_TERMS))))
    )
    assert [t.name for t in c.system.inputs[0].terms] == ["NB", "Z", "PB"]
