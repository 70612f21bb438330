"""Generated C: compiled with the system's C compiler, compared with the Python evaluator.

Exact variant in double: within 1e-9 of the output span at 10 000 inputs (static map)
and over 2 000 samples of the control law; float: within 1e-5 of the span; lookup
table: within the bound :func:`lut_error` reports.
"""

from __future__ import annotations

import dataclasses
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from support import controller_named

from fuzzyservo.codegen import identifier, lut_error, write_c
from fuzzyservo.controllers.fuzzy.controller import FuzzyController
from fuzzyservo.controllers.fuzzy.evaluate import evaluate_inputs
from fuzzyservo.controllers.fuzzy.fis import parse_fis
from fuzzyservo.io.fuzzy_files import controller_from_fis

DATA = Path(__file__).resolve().parent / "data"
CC = shutil.which("cc") or shutil.which("gcc")
pytestmark = pytest.mark.skipif(CC is None, reason="no C compiler (cc/gcc) on PATH")

SUGENO = """[System]
Name='sugeno_pd'
Type='sugeno'
NumInputs=2
NumOutputs=1
NumRules=4
AndMethod='prod'
OrMethod='probor'
ImpMethod='prod'
AggMethod='sum'
DefuzzMethod='wtaver'

[Input1]
Name='e'
Range=[-1 1]
NumMFs=2
MF1='N':'zmf',[-1 1]
MF2='P':'smf',[-1 1]

[Input2]
Name='de'
Range=[-5 5]
NumMFs=2
MF1='N':'sigmf',[-2 0]
MF2='P':'gauss2mf',[2 1 3 4]

[Output1]
Name='u'
Range=[-2 2]
NumMFs=3
MF1='neg':'linear',[1.5 0.1 -0.2]
MF2='zero':'constant',[0]
MF3='pos':'linear',[1.5 0.2 0.2]

[Rules]
1 1, 1 (1) : 1
1 2, 2 (0.5) : 1
2 -1, 2 (0.7) : 2
2 2, 3 (1) : 1
"""


def shipped(name: str) -> FuzzyController:
    return controller_named(name)


def tipper(semantics: str, **methods: str) -> FuzzyController:
    c = controller_from_fis(DATA / "tipper.fis")
    system = dataclasses.replace(c.system, semantics=semantics, **methods)
    return dataclasses.replace(c, system=system, u_min=-100.0, u_max=100.0)


def negated() -> FuzzyController:
    """Per-rule implication then probor aggregation, one consequent negated (NOT cheap)."""
    c = tipper("skfuzzy", aggregation="probor")
    rules = list(c.system.rules)
    rules[1] = dataclasses.replace(rules[1], consequent=-2)  # NOT cheap
    return dataclasses.replace(c, system=dataclasses.replace(c.system, rules=tuple(rules)))


def sugeno() -> FuzzyController:
    return FuzzyController(system=parse_fis(SUGENO), form="pd", name="sugeno_pd")


CASES = {
    "tuned (p, skfuzzy)": lambda: shipped("flc_dinca_tuned"),
    "fpi_ehs160 (pi, 7x7)": lambda: shipped("fpi_ehs160"),
    "tipper matlab": lambda: tipper("matlab"),
    "tipper probor, NOT output": negated,
    "tipper matlab bisector": lambda: tipper("matlab", defuzzification="bisector"),
    "sugeno": sugeno,
}

HARNESS = r"""#include <stdio.h>
#include "@P@.h"
int main(void)
{
    @P@_state s;
    char mode;
    double a, b;
    @P@_init(&s);
    while (scanf(" %c %lf %lf", &mode, &a, &b) == 3) {
        if (mode == 'm') printf("%.17g\n", (double)@P@_map(&s, (@R@)a, (@R@)b));
        else printf("%.17g\n", (double)@P@_step(&s, (@R@)a, (@R@)b));
    }
    return 0;
}
"""


def build(controller: FuzzyController, folder: Path, real: str, lut: int | None = None) -> Path:
    paths = write_c(controller, folder, 0.01, real, lut)
    name = identifier(controller.name)
    harness = folder / "main.c"
    harness.write_text(HARNESS.replace("@P@", name).replace("@R@", real), encoding="utf-8")
    exe = folder / "run"
    subprocess.run(
        [CC, "-std=c99", "-pedantic", "-Wall", "-Wextra", "-Werror", "-O2",
         "-o", str(exe), str(harness), *(str(p) for p in paths if p.suffix == ".c"), "-lm"],
        check=True, capture_output=True, text=True,
    )  # fmt: skip
    return exe


def run(exe: Path, mode: str, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    text = "".join(f"{mode} {float(x)!r} {float(y)!r}\n" for x, y in zip(a, b, strict=True))
    out = subprocess.run([str(exe)], input=text, capture_output=True, text=True, check=True)
    return np.array([float(v) for v in out.stdout.split()])


def inputs(controller: FuzzyController, n: int = 10_000) -> tuple[np.ndarray, np.ndarray]:
    """Points over the universes and a little beyond (clipping), plus the corners."""
    rng = np.random.default_rng(16)
    cols = []
    for var in controller.system.inputs:
        pad = 0.05 * (var.high - var.low)
        x = rng.uniform(var.low - pad, var.high + pad, n)
        x[:3] = (var.low, var.high, 0.5 * (var.low + var.high))
        cols.append(x)
    if len(cols) == 1:
        cols.append(np.zeros(n))
    return cols[0], cols[1]


def python_map(controller: FuzzyController, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    xs = np.column_stack([a, b][: len(controller.system.inputs)])
    return evaluate_inputs(controller.system, xs)[0][:, 0]


def span(controller: FuzzyController) -> float:
    out = controller.system.output
    return out.high - out.low


@pytest.mark.parametrize("case", CASES)
def test_exact_c_matches_the_evaluator(tmp_path, case):
    controller = CASES[case]()
    exe = build(controller, tmp_path, "double")
    a, b = inputs(controller)
    np.testing.assert_allclose(
        run(exe, "m", a, b), python_map(controller, a, b), rtol=0, atol=1e-9 * span(controller)
    )
    # the control law: a reference sweep against a lagging measurement, 2000 samples
    t = np.arange(2000) * 0.01
    r = 1.5 * np.sin(2 * np.pi * 0.4 * t)
    y = 1.5 * np.sin(2 * np.pi * 0.4 * (t - 0.05)) + 0.01 * np.cos(37 * t)
    state = controller.init(0.01)
    expected = []
    for rk, yk in zip(r, y, strict=True):
        u, state = controller.step(state, rk, yk)
        expected.append(u)
    gain = abs(controller.output_gain) * max(1.0, 0.01 * len(t) * (controller.form == "pi"))
    np.testing.assert_allclose(
        run(exe, "s", r, y), expected, rtol=0, atol=1e-9 * span(controller) * gain
    )


@pytest.mark.parametrize("case", ["tuned (p, skfuzzy)", "tipper matlab", "sugeno"])
def test_float_c_is_close(tmp_path, case):
    controller = CASES[case]()
    exe = build(controller, tmp_path, "float")
    a, b = inputs(controller)
    np.testing.assert_allclose(
        run(exe, "m", a, b), python_map(controller, a, b), rtol=0, atol=1e-5 * span(controller)
    )


@pytest.mark.parametrize(("case", "n"), [("tuned (p, skfuzzy)", 257), ("tipper matlab", 41)])
def test_lookup_table_within_its_reported_error(tmp_path, case, n):
    controller = CASES[case]()
    exe = build(controller, tmp_path, "double", lut=n)
    error = lut_error(controller, n)
    a, b = inputs(controller)
    got = np.abs(run(exe, "m", a, b) - python_map(controller, a, b))
    assert got.max() <= error.bound + 1e-12 * span(controller)
    assert error.found <= error.bound < 0.05 * span(controller)


# --------------------------------------------------------------------------- Structured Text
def st_to_python(text: str) -> str:
    """The exported function block as a Python function ``step(state, r, y, reset)``: a
    literal translation of the IEC 61131-3 subset it uses (assignments, IF/ELSIF/ELSE,
    MIN/MAX/TRUNC and the DINT/LREAL conversions), so the test runs the ST text itself."""
    import re

    body = re.sub(r"\(\*.*?\*\)", "", text, flags=re.S)
    decls, code = body.split("END_VAR\n\n", 1) if "END_VAR\n\n" in body else (body, "")
    decls = body[: body.rindex("END_VAR") + len("END_VAR")]
    code = body[body.rindex("END_VAR") + len("END_VAR") :].replace("END_FUNCTION_BLOCK", "")
    consts = []
    for m in re.finditer(r"(\w+)\s*:\s*[^:;]*?:=\s*(\[[^\]]*\]|[^;]+);", decls, flags=re.S):
        value = m[2].replace("TRUE", "True").replace("FALSE", "False")
        consts.append(f"    {m[1]} = {value.strip()}")
    out = ["def step(state, r, y, reset):", *consts]
    out.append("    e_prev, u_prev, started = state")
    indent = 1
    for raw in code.splitlines():
        line = raw.strip().rstrip(";")
        if not line:
            continue
        line = re.sub(r"LREAL_TO_DINT\(TRUNC\(", "int((", line)
        line = line.replace("DINT_TO_LREAL(", "float(").replace("<>", "!=")
        line = line.replace(":=", "\0")
        line = re.sub(r"(?<![<>!=])=(?!=)", "==", line).replace("\0", "=")
        line = line.replace("TRUE", "True").replace("FALSE", "False")
        line = line.replace("MIN(", "min(").replace("MAX(", "max(")
        if line.startswith("IF ") and line.endswith(" THEN"):
            out.append("    " * indent + f"if {line[3:-5]}:")
            indent += 1
        elif line.startswith("ELSIF "):
            out.append("    " * (indent - 1) + f"elif {line[6:-5]}:")
        elif line == "ELSE":
            out.append("    " * (indent - 1) + "else:")
        elif line == "END_IF":
            indent -= 1
        else:
            out.append("    " * indent + line)
    out.append("    return u, (e_prev, u_prev, started)")
    return "\n".join(out)


@pytest.mark.parametrize(("case", "n"), [("tuned (p, skfuzzy)", 33), ("fpi_ehs160 (pi, 7x7)", 7)])
def test_structured_text_parses_and_computes_the_table_law(tmp_path, case, n):
    """blark (an IEC 61131-3 parser) accepts the text; run literally, it gives the
    lookup-table law: the C table variant's numbers (Debian has no IEC 61131-3 compiler)."""
    blark = pytest.importorskip("blark.parse", reason="blark (IEC 61131-3 parser) not installed")
    from fuzzyservo.codegen import write_st

    controller = CASES[case]()
    path, size = write_st(controller, tmp_path / "fb.st", 0.01, n)
    text = path.read_text(encoding="utf-8")
    parsed = blark.parse_source_code(text)
    assert parsed.exception is None, parsed.exception
    namespace: dict = {}
    exec(st_to_python(text), namespace)  # the test's own translation of the generated text
    exe = build(controller, tmp_path / "c", "double", lut=n)
    rng = np.random.default_rng(3)
    r = rng.uniform(-2, 2, 500)
    y = r + rng.normal(0, 0.3, r.size)
    state = (0.0, 0.0, False)
    got = []
    for rk, yk in zip(r, y, strict=True):
        u, state = namespace["step"](state, rk, yk, False)
        got.append(u)
    np.testing.assert_allclose(got, run(exe, "s", r, y), rtol=0, atol=1e-9 * span(controller))
    assert size == n
