"""How far the generated C in single precision is from the same C in double: compiled
with the system's C compiler and run on inputs spread over the input ranges."""

from __future__ import annotations

import subprocess
import tempfile
from pathlib import Path

import numpy as np

from fuzzyservo._jit import c_compiler
from fuzzyservo.atomic import write_files
from fuzzyservo.codegen._c import c_sources, identifier, system_c_sources
from fuzzyservo.controllers.fuzzy.controller import FuzzyController
from fuzzyservo.controllers.fuzzy.system import FuzzySystem

_SWEEP_MAIN = r"""#include <stdio.h>
#include "@P@.h"
int main(void)
{
    @P@_state s;
    @R@ x[@NIN@], y[@NOUT@];
    double v;
    int i;
    @INIT@
    for (;;) {
        for (i = 0; i < @NIN@; i++) {
            if (scanf("%lf", &v) != 1) return 0;
            x[i] = (@R@)v;
        }
        @CALL@
        for (i = 0; i < @NOUT@; i++) printf("%.17g\n", (double)y[i]);
    }
}
"""


def single_precision_error(target: FuzzyController | FuzzySystem, n: int = 2000) -> str:
    """The generated C in float against the same C in double on ``n`` inputs spread over
    the input ranges: a line stating the largest difference (of the map F, before the
    output gain, for a controller), or why it was not measured."""
    cc = c_compiler()
    if cc is None:
        return "single precision: not measured (no C compiler found)"
    system = target.system if isinstance(target, FuzzyController) else target
    n_in, n_out = len(system.inputs), len(system.outputs)
    rng = np.random.default_rng(0)
    xs = np.column_stack([rng.uniform(v.low, v.high, n) for v in system.inputs])
    text = "\n".join(" ".join(repr(float(x)) for x in row) for row in xs) + "\n"
    name = identifier(target.name)
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for real in ("double", "float"):
            folder = Path(tmp) / real
            if isinstance(target, FuzzyController):
                files = c_sources(target, 0.01, real)
                init, call = f"{name}_init(&s);", f"y[0] = {name}_map(&s, x[0], x[{n_in - 1}]);"
            else:
                files = system_c_sources(target, real)
                init, call = "", f"{name}_evaluate(&s, x, y);"
            main = _SWEEP_MAIN.replace("@INIT@", init).replace("@CALL@", call)
            for key, value in (("@P@", name), ("@R@", real), ("@NIN@", str(n_in)),
                               ("@NOUT@", str(1 if isinstance(target, FuzzyController) else n_out))):  # fmt: skip
                main = main.replace(key, value)
            paths = write_files({**files, "main.c": main}, folder)
            exe = folder / "sweep"
            built = subprocess.run([cc, "-std=c99", "-O2", "-o", str(exe),
                                    *(str(p) for p in paths if p.suffix == ".c"), "-lm"],
                                   capture_output=True, text=True)  # fmt: skip
            if built.returncode:
                return f"single precision: not measured ({cc} failed)"
            run = subprocess.run([str(exe)], input=text, capture_output=True, text=True)
            results.append(np.array([float(v) for v in run.stdout.split()]))
    double, single = results
    ok = np.isfinite(double) & np.isfinite(single)
    err = float(np.max(np.abs(single[ok] - double[ok]))) if ok.any() else 0.0
    span = max(v.high - v.low for v in system.outputs) or 1.0
    return (f"single precision: largest difference from double {err:.3g} ({err / span:.2e} "
            f"of the output range) on {n} inputs spread over the input ranges")  # fmt: skip
