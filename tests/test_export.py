"""Exports that run in the controller's place: ``.fis`` and FCL carry the control law
(form, gains, output limits) beside the inference system, so seed 002's FLC2 read back
from either gives the metrics of the YAML controller, the command's included (issue 27:
the command's peak was 2.0 V instead of 2.238 V when the limits were dropped and the
rig's actuator range applied instead)."""

from __future__ import annotations

import dataclasses
import importlib.util
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest
from support import SHARED, controller_named, rig_named

from fuzzyservo.analysis.compare import compare
from fuzzyservo.cli import main
from fuzzyservo.codegen import c_compiler, identifier
from fuzzyservo.controllers.fuzzy.evaluate import evaluate_inputs
from fuzzyservo.controllers.fuzzy.fis import parse_fis
from fuzzyservo.controllers.fuzzy.system import FuzzySystem
from fuzzyservo.io.controllers import load_controller
from fuzzyservo.io.fuzzy_files import read_fcl, read_fis
from fuzzyservo.workflows import export


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


# --------------------------------------------------------------------------- every system
CONFORMANCE = SHARED / "conformance" / "fuzzylite" / "examples"
#: the 22 MATLAB originals (fuzzylite's copies; sltbu.fis only in its original/ folder)
MATLAB = sorted(
    [*CONFORMANCE.glob("mamdani/matlab/*.fis"), *CONFORMANCE.glob("takagi-sugeno/matlab/*.fis"),
     *CONFORMANCE.glob("original/takagi-sugeno/matlab/sltbu.fis")]
)  # fmt: skip
CC = c_compiler()
HARNESS = r"""#include <stdio.h>
#include "@P@.h"
int main(void)
{
    @P@_state s;
    double x[@PU@_INPUTS], y[@PU@_OUTPUTS];
    int i;
    for (;;) {
        for (i = 0; i < @PU@_INPUTS; i++)
            if (scanf("%lf", &x[i]) != 1) return 0;
        @P@_evaluate(&s, x, y);
        for (i = 0; i < @PU@_OUTPUTS; i++) printf("%.17g\n", y[i]);
    }
}
"""


def sweep(system: FuzzySystem, n: int = 400, seed: int = 3) -> np.ndarray:
    """Inputs over each range and 5 % beyond (clipped), the corners included."""
    rng = np.random.default_rng(seed)
    cols = []
    for v in system.inputs:
        pad = 0.05 * (v.high - v.low)
        x = rng.uniform(v.low - pad, v.high + pad, n)
        x[:2] = v.low, v.high
        cols.append(x)
    return np.column_stack(cols)


def run_c(folder: Path, system: FuzzySystem, xs: np.ndarray) -> np.ndarray:
    name = identifier(system.name)
    main_c = folder / "main.c"
    main_c.write_text(HARNESS.replace("@PU@", name.upper()).replace("@P@", name), encoding="utf-8")
    exe = folder / "run"
    subprocess.run([CC, "-std=c99", "-Wall", "-Wextra", "-Werror", "-O1", "-o", str(exe),
                    str(main_c), str(folder / f"{name}.c"), "-lm"], check=True,
                   capture_output=True, text=True)  # fmt: skip
    text = "\n".join(" ".join(repr(float(v)) for v in row) for row in xs) + "\n"
    out = subprocess.run([str(exe)], input=text, capture_output=True, text=True, check=True)
    return np.array([float(v) for v in out.stdout.split()]).reshape(len(xs), -1)


def assert_same(got: np.ndarray, expected: np.ndarray, system: FuzzySystem, rel: float) -> None:
    spans = [max(1.0, v.high - v.low) for v in system.outputs]
    np.testing.assert_array_equal(np.isnan(got), np.isnan(expected))
    ok = ~np.isnan(expected)
    np.testing.assert_allclose(got[ok], expected[ok], rtol=0, atol=rel * max(spans))


@pytest.mark.skipif(not MATLAB, reason=f"conformance data absent ({CONFORMANCE}); see ../shared")
@pytest.mark.skipif(CC is None, reason="no C compiler (cc/gcc) on PATH")
def test_every_matlab_original_exports_and_its_c_equals_evaluate(tmp_path, capsys):
    assert len(MATLAB) == 22
    for path in MATLAB:
        out = tmp_path / path.stem
        assert main(["export", str(path), "--fis", str(out / "s.fis"), "--fcl",
                     str(out / "s.fcl"), "--c", str(out / "c"), "--st", str(out / "s.st")]) == 0, path  # fmt: skip
        system = read_fis(path)
        assert parse_fis((out / "s.fis").read_text(encoding="utf-8")) == system, path.name
        assert read_fcl(out / "s.fcl").rules == system.rules
        for semantics in ("skfuzzy", "matlab"):  # the C of both semantics
            s = dataclasses.replace(system, semantics=semantics)
            folder = out / semantics
            export(s, c_dir=folder)
            xs = sweep(s)
            assert_same(run_c(folder, s, xs), evaluate_inputs(s, xs)[0], s, 1e-12)
    assert "written" in capsys.readouterr().out


# --------------------------------------------------------------------------- FMUs
needs_fmpy = pytest.mark.skipif(
    importlib.util.find_spec("fmpy") is None, reason="FMPy (the [fmi] extra) not installed"
)


class Slave:
    """An FMU instantiated with FMPy, stepped by hand (FMI 3.0 or 2.0)."""

    def __init__(self, path: Path, name: str = "a"):
        from fmpy import extract, read_model_description
        from fmpy.fmi2 import FMU2Slave
        from fmpy.fmi3 import FMU3Slave

        md = read_model_description(str(path))
        self.v3 = md.fmiVersion.startswith("3")
        self.refs = {v.name: v.valueReference for v in md.modelVariables}
        cls = FMU3Slave if self.v3 else FMU2Slave
        self.fmu = cls(guid=md.guid, unzipDirectory=extract(str(path)), instanceName=name,
                       modelIdentifier=md.coSimulation.modelIdentifier)  # fmt: skip
        self.fmu.instantiate()
        self.start()
        self.t = 0.0

    def start(self) -> None:
        if self.v3:
            self.fmu.enterInitializationMode(startTime=0.0)
        else:
            self.fmu.setupExperiment(startTime=0.0)
            self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()

    def set(self, **values: float) -> None:
        refs, vals = [self.refs[k] for k in values], [float(v) for v in values.values()]
        (self.fmu.setFloat64 if self.v3 else self.fmu.setReal)(refs, vals)

    def get(self, *names: str) -> list[float]:
        return (self.fmu.getFloat64 if self.v3 else self.fmu.getReal)([self.refs[n] for n in names])

    def step(self, h: float) -> None:
        self.fmu.doStep(self.t, h)
        self.t += h

    def close(self) -> None:
        self.fmu.terminate()
        self.fmu.freeInstance()


def shower() -> Path:
    return CONFORMANCE / "mamdani" / "matlab" / "shower.fis"


@needs_fmpy
@pytest.mark.skipif(CC is None, reason="no C compiler (cc/gcc) on PATH")
@pytest.mark.parametrize("fmi", [3, 2])
def test_flc2_fmu_validates_and_runs_as_the_controller(tmp_path, fmi):
    from fmpy.validation import validate_fmu

    flc2 = controller_named("flc2_reshaped")
    fmu = tmp_path / "flc2.fmu"
    assert main(["export", "flc2_reshaped", "--fmu", str(fmu), "--fmi", str(fmi)]) == 0
    assert validate_fmu(str(fmu)) == []
    with zipfile.ZipFile(fmu) as z:
        names = z.namelist()
    assert "sources/flc2_reshaped.c" in names and "sources/fmu.c" in names
    assert any(n.startswith("binaries/") for n in names)
    # swept over the error's range: the static map, reference e and measurement 0
    a, b = Slave(fmu, "a"), Slave(fmu, "b")  # two instances, independent
    e = np.linspace(-2.2, 2.2, 441)
    got = []
    for x in e:
        a.set(reference=x, measurement=0.0)
        a.step(0.01)
        got += a.get("command")
    np.testing.assert_allclose(got, flc2.curve(e), rtol=0, atol=1e-9)
    # the control law over time, the gain changed as a tunable parameter
    changed = dataclasses.replace(flc2, output_gain=0.5, design=None)
    b.set(output_gain=0.5)
    state, t = changed.init(0.01), np.arange(300) * 0.01
    for r, y in zip(np.sin(5 * t) * 2.5, np.sin(5 * t - 0.3) * 2.4, strict=True):
        u, state = changed.step(state, r, y)
        b.set(reference=r, measurement=y)
        b.step(0.01)
        assert b.get("command")[0] == pytest.approx(u, abs=1e-12)
    a.close()
    b.close()


@pytest.mark.skipif(not MATLAB, reason=f"conformance data absent ({CONFORMANCE}); see ../shared")
@needs_fmpy
@pytest.mark.skipif(CC is None, reason="no C compiler (cc/gcc) on PATH")
@pytest.mark.parametrize("fmi", [3, 2])
def test_shower_fmu_has_two_outputs_equal_to_evaluate(tmp_path, fmi):
    from fmpy import read_model_description
    from fmpy.validation import validate_fmu

    fmu = tmp_path / "shower.fmu"
    assert main(["export", str(shower()), "--fmu", str(fmu), "--fmi", str(fmi)]) == 0
    assert validate_fmu(str(fmu)) == []
    system = read_fis(shower())
    declared = {v.name: v for v in read_model_description(str(fmu)).modelVariables}
    for v in system.inputs:  # each input's range as its min/max
        assert (float(declared[v.name].min), float(declared[v.name].max)) == (v.low, v.high)
    slave = Slave(fmu)
    xs = sweep(system, 300)[2:]
    xs = np.clip(xs, [v.low for v in system.inputs], [v.high for v in system.inputs])
    got = []
    for row in xs:
        slave.set(**{v.name: x for v, x in zip(system.inputs, row, strict=True)})
        slave.step(0.01)
        got.append(slave.get(*(v.name for v in system.outputs)))
    slave.close()
    assert_same(np.array(got), evaluate_inputs(system, xs)[0], system, 1e-9)


def test_fmu_option_errors_are_one_line(tmp_path, capsys):
    assert main(["export", "flc2_reshaped", "--fmu", str(tmp_path / "x.zip")]) == 2
    assert main(["export", "flc2_reshaped", "--fmu", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all("--fmu" in line for line in err)


# --------------------------------------------------------------------------- FMU controllers
@needs_fmpy
@pytest.mark.skipif(CC is None, reason="no C compiler (cc/gcc) on PATH")
def test_an_fmu_controller_in_compare_reproduces_the_native_run(tmp_path, capsys):
    """FLC2 → FMU → back into the loop (kind: fmu): the same run as the YAML controller."""
    assert main(["export", "flc2_reshaped", "--fmu", str(tmp_path / "flc2.fmu")]) == 0
    file = tmp_path / "flc2_fmu.yaml"
    file.write_text("name: flc2_fmu\nkind: fmu\nfile: flc2.fmu\noutput_limits: [-10, 10]\n"
                    "reference: reference\nmeasurement: measurement\ncommand: command\n",
                    encoding="utf-8")  # fmt: skip
    rig = rig_named("dinca_cylinder")
    result = compare(rig, [controller_named("flc2_reshaped"), load_controller(file)])
    native, fmu = result["flc2_reshaped"], result["flc2_fmu"]
    assert (
        fmu.ok and result.metrics["flc2_fmu"].aggregate == result.metrics["flc2_reshaped"].aggregate
    )
    np.testing.assert_allclose(fmu.command, native.command, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fmu.output, native.output, rtol=0, atol=1e-9)
    # the command line too, and a mapping that does not match is one clear line
    assert main(["compare", "dinca_cylinder", str(file), "--out", str(tmp_path / "o")]) == 0
    bad = tmp_path / "bad.yaml"
    bad.write_text(file.read_text(encoding="utf-8").replace("measurement: measurement",
                                                            "measurement: y"), encoding="utf-8")  # fmt: skip
    capsys.readouterr()
    assert main(["compare", "dinca_cylinder", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "'y' is not an input" in err[0] and "bad.yaml" in err[0]


@needs_fmpy
@pytest.mark.skipif(CC is None, reason="no C compiler (cc/gcc) on PATH")
def test_an_fmu_controller_in_margins_and_robustness_equals_the_native_one(tmp_path):
    """The FMU controller in the two other analyses the issue names: the same gain and
    delay margins and the same Monte Carlo table as the YAML controller it came from."""
    from support import shipped

    import fuzzyservo
    from fuzzyservo.io.studies import load_study
    from fuzzyservo.tuning import MAIN_STUDY

    assert main(["export", "flc2_reshaped", "--fmu", str(tmp_path / "flc2.fmu")]) == 0
    file = tmp_path / "flc2_fmu.yaml"
    file.write_text("name: flc2_reshaped\nkind: fmu\nfile: flc2.fmu\noutput_limits: [-10, 10]\n"
                    "reference: reference\nmeasurement: measurement\ncommand: command\n",
                    encoding="utf-8")  # fmt: skip
    rig, native, fmu = (
        rig_named("dinca_cylinder"),
        controller_named("flc2_reshaped"),
        load_controller(file),
    )
    a, b = fuzzyservo.margins(rig, native), fuzzyservo.margins(rig, fmu)
    timed = ("seconds",)
    assert {k: v for k, v in b.to_dict().items() if k not in timed} == {
        k: v for k, v in a.to_dict().items() if k not in timed
    }
    study = load_study(shipped(MAIN_STUDY, "studies"))
    draw = {"samples": 2, "scenarios": ["steps"]}
    rows = [fuzzyservo.robustness(rig, [c], study, **draw).rows() for c in (native, fmu)]
    assert rows[0] == rows[1]


# --------------------------------------------------------------------------- Structured Text
def st_to_python(text: str) -> dict:
    """The Structured Text of an exported system run as Python: a literal translation of
    the subset it uses (FUNCTIONs, one FUNCTION_BLOCK, IF/ELSIF/ELSE, MIN/MAX/EXP/ABS/
    EXPT/TRUNC, constant arrays); ``ns["block"](**inputs)`` returns the outputs."""
    import math
    import re

    text = re.sub(r"\(\*.*?\*\)", "", text, flags=re.S)

    def expr(e: str) -> str:
        e = e.replace("<>", "!=").replace(":=", "\0")
        e = re.sub(r"(?<![<>!=])=(?!=)", "==", e).replace("\0", "=")
        e = re.sub(r"\bOR\b", "or", re.sub(r"\bAND\b", "and", e))
        for st, py in (("MIN", "min"), ("MAX", "max"), ("EXPT", "pow"), ("EXP", "math.exp"),
                       ("ABS", "abs"), ("LREAL_TO_DINT", "int"), ("TRUNC", "math.trunc"),
                       ("DINT_TO_LREAL", "float")):  # fmt: skip
            e = re.sub(rf"\b{st}\(", f"{py}(", e)
        return e

    def body(code: str, indent: int) -> list[str]:
        code = re.sub(r"\bTHEN\b", "THEN;", code)
        code = re.sub(r"\b(ELSIF|ELSE|END_IF)\b", r";\1", code)
        code = re.sub(r"\bELSE\b", "ELSE;", code)
        out = []
        for piece in (p.strip() for p in code.split(";")):
            if not piece:
                continue
            if piece.startswith("IF "):
                out.append("    " * indent + f"if {expr(piece[3:-5])}:")
                indent += 1
            elif piece.startswith("ELSIF "):
                out.append("    " * (indent - 1) + f"elif {expr(piece[6:-5])}:")
            elif piece == "ELSE":
                out.append("    " * (indent - 1) + "else:")
            elif piece == "END_IF":
                indent -= 1
            else:
                out.append("    " * indent + expr(piece))
        return out

    py = []
    for m in re.finditer(r"FUNCTION (\w+) : LREAL\s*VAR_INPUT(.*?)END_VAR\s*VAR.*?END_VAR(.*?)END_FUNCTION\b", text, flags=re.S):  # fmt: skip
        args = re.findall(r"(\w+) : LREAL", m[2])
        py += [f"def {m[1]}({', '.join(args)}):", *body(m[3], 1), f"    return {m[1]}"]
    fb = re.search(r"FUNCTION_BLOCK (\w+)(.*?)END_FUNCTION_BLOCK", text, flags=re.S)[2]
    ins = re.findall(r"(\w+) : LREAL", re.search(r"VAR_INPUT(.*?)END_VAR", fb, re.S)[1])
    outs = re.findall(r"(\w+) : LREAL", re.search(r"VAR_OUTPUT(.*?)END_VAR", fb, re.S)[1])
    code = fb[fb.rindex("END_VAR") + len("END_VAR") :]
    consts = [f"    {n} = {v.strip()}" for n, v in re.findall(r"(\w+) : [^:;]*?:= (\[[^\]]*\]|[^;]+);",
                                                              fb[: fb.rindex("END_VAR")])]  # fmt: skip
    py += [f"def block({', '.join(ins)}):", *consts, *body(code, 1),
           f"    return [{', '.join(outs)}]"]  # fmt: skip
    ns: dict = {"math": math}
    exec("\n".join(py), ns)
    return ns


@pytest.mark.skipif(not MATLAB, reason=f"conformance data absent ({CONFORMANCE}); see ../shared")
def test_structured_text_of_every_matlab_original(tmp_path):
    """Sugeno systems: the evaluator written out, equal to evaluate to rounding; Mamdani:
    lookup tables holding evaluate's values at their points. blark (an IEC 61131-3
    parser), when installed, accepts every file."""
    from fuzzyservo.codegen import lut_interp

    try:
        from blark.parse import parse_source_code
    except ImportError:
        parse_source_code = None
    for path in MATLAB:
        system = read_fis(path)
        st = tmp_path / f"{path.stem}.st"
        export(system, st=st)
        text = st.read_text(encoding="utf-8")
        if parse_source_code is not None and path.stem in ("slcp1", "sugeno1"):
            assert parse_source_code(text).exception is None, path.name
        block = st_to_python(text)["block"]
        xs = sweep(system, 60)
        got = np.array([block(*row) for row in xs])
        if system.type == "sugeno":
            assert_same(got, evaluate_inputs(system, xs)[0], system, 1e-12)
            continue
        n = 257 if len(system.inputs) == 1 else 65
        grids = [np.linspace(v.low, v.high, n) for v in system.inputs]
        mesh = np.meshgrid(*grids, indexing="ij")
        table = evaluate_inputs(system, np.column_stack([m.ravel() for m in mesh]))[0]
        for o in range(len(system.outputs)):
            expected = lut_interp(grids, table[:, o].reshape(mesh[0].shape), list(xs.T))
            np.testing.assert_allclose(got[:, o], expected, rtol=0, atol=1e-9, err_msg=path.name)


@pytest.mark.skipif(not MATLAB, reason=f"conformance data absent ({CONFORMANCE}); see ../shared")
@pytest.mark.skipif(CC is None, reason="no C compiler (cc/gcc) on PATH")
def test_float_c_states_its_error_against_double(tmp_path, capsys):
    assert main(["export", str(shower()), "--c", str(tmp_path / "c"), "--float"]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if "single precision" in x)
    relative = float(line.split("(")[1].split()[0])
    assert 0 < relative < 1e-5  # float's 6e-8 relative, a few operations deep
