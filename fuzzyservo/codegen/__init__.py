"""Code generation: a fuzzy controller as self-contained C99 or IEC 61131-3 Structured Text.

The generated code computes the controller step exactly as the compiled evaluator does:
it embeds the packed parameter vector (:meth:`FuzzyController.pack`) and ports the
evaluator that reads it (:mod:`._c_runtime`, :mod:`._st`), so one evaluator exists in
three languages rather than a second design per target. No library, no allocation:
the state (previous error, previous command, scratch space) is a struct the caller owns.

``lut``: a lookup-table variant — the static map F sampled on an n (× n) grid over the
input universes (inputs are clipped to them, so the table covers every input) and
interpolated linearly (bilinearly); :func:`lut_error` measures how far it is from F.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fuzzyservo.codegen._c_runtime import RUNTIME
from fuzzyservo.codegen._fmi import fmu_model, fmu_sources, model_description
from fuzzyservo.codegen._st_system import system_st_source
from fuzzyservo.controllers.fuzzy.controller import (
    FORMS,
    FUZZY_PARAMS,
    FUZZY_STATE,
    SCRATCH,
    SYSTEM,
    FuzzyController,
)
from fuzzyservo.controllers.fuzzy.evaluate import (
    EXACT,
    OUTPUT_HEAD,
    SAMPLED,
    SAMPLED_RULE,
    SAMPLED_VARIABLE,
    SYSTEM_HEAD,
)
from fuzzyservo.controllers.fuzzy.exact import EXACT_HEAD, EXACT_RULE, EXACT_TERM, EXACT_VARIABLE
from fuzzyservo.controllers.fuzzy.shapes import SHAPE_CODES
from fuzzyservo.controllers.fuzzy.system import NO_TERM, FuzzySystem
from fuzzyservo.controllers.layout import slots

__all__ = [
    "LutError", "c_sources", "fmu_model", "fmu_sources", "identifier", "lut_error",
    "lut_table", "model_description", "system_c_sources", "system_st_source", "write_c",
    "write_st",
]  # fmt: skip

REALS = ("double", "float")
#: the packed vectors' layouts the generated code reads, by the prefix of its constants
_LAYOUTS = {
    "CP": FUZZY_PARAMS,
    "T": SYSTEM_HEAD,
    "H": OUTPUT_HEAD,
    "SV": SAMPLED_VARIABLE,
    "SR": SAMPLED_RULE,
    "X": EXACT_HEAD,
    "XV": EXACT_VARIABLE,
    "XT": EXACT_TERM,
    "XR": EXACT_RULE,
}


def identifier(name: str) -> str:
    """A C / Structured Text identifier made from a controller name."""
    ident = re.sub(r"\W", "_", name, flags=re.ASCII).strip("_") or "controller"
    return ident if not ident[0].isdigit() else f"c_{ident}"


def _literal(x: float, real: str) -> str:
    if math.isinf(x):
        return ("-" if x < 0 else "") + f"({real})HUGE_VAL"
    text = repr(float(x))
    return text + ("f" if real == "float" and "inf" not in text else "")


def _array(values: np.ndarray, real: str, per_line: int = 6) -> str:
    items = [_literal(v, real) for v in values]
    return ",\n".join(
        "    " + ", ".join(items[k : k + per_line]) for k in range(0, len(items), per_line)
    )


@dataclass(frozen=True)
class LutError:
    """How far the table is from the map: the largest error found on a grid ``refine``
    times finer, and a bound that adds the Lipschitz estimate of the error over half a
    fine-grid step (in output units, before the output gain)."""

    found: float
    bound: float
    span: float
    refine: int


def lut_table(controller: FuzzyController, n: int) -> tuple[list[np.ndarray], np.ndarray]:
    """Grids over the input universes and the static map F on them, shape (n,) or (n, n)."""
    if n < 2:
        raise ValueError(f"a lookup table needs n >= 2 points per input, got {n}")
    grids = [np.linspace(v.low, v.high, n) for v in controller.system.inputs]
    return grids, _map(controller, np.meshgrid(*grids, indexing="ij"))


def _map(controller: FuzzyController, mesh: list[np.ndarray]) -> np.ndarray:
    """F on raw universe inputs (the evaluator behind ``curve``, gains taken out)."""
    from fuzzyservo.controllers.fuzzy.evaluate import evaluate_inputs

    xs = np.column_stack([m.ravel() for m in mesh])
    out, _ = evaluate_inputs(controller.system, xs)
    return out[:, 0].reshape(mesh[0].shape)


def lut_interp(grids: list[np.ndarray], table: np.ndarray, points: list[np.ndarray]) -> np.ndarray:
    """The table read as the generated code reads it (uniform grid, clipped, (bi)linear)."""
    idx, frac = [], []
    for g, x in zip(grids, points, strict=True):
        n = g.size
        h = (g[-1] - g[0]) / (n - 1)
        t = (np.clip(x, g[0], g[-1]) - g[0]) / h
        k = np.minimum(np.floor(t).astype(int), n - 2)
        idx.append(k)
        frac.append(t - k)
    if len(grids) == 1:
        (k,), (f,) = idx, frac
        return table[k] + f * (table[k + 1] - table[k])
    (k, l), (f, g) = idx, frac
    a = table[k, l] + g * (table[k, l + 1] - table[k, l])
    b = table[k + 1, l] + g * (table[k + 1, l + 1] - table[k + 1, l])
    return a + f * (b - a)


def lut_error(controller: FuzzyController, n: int, refine: int | None = None) -> LutError:
    """Largest |table − F| over the input range, on a grid ``refine`` times finer than the
    table (16 for one input, 6 for two), and a bound from the error's slope there."""
    grids, table = lut_table(controller, n)
    refine = refine or (16 if len(grids) == 1 else 6)
    fine = [np.linspace(g[0], g[-1], (g.size - 1) * refine + 1) for g in grids]
    mesh = np.meshgrid(*fine, indexing="ij")
    err = lut_interp(grids, table, mesh) - _map(controller, mesh)
    slope = max(
        float(np.max(np.abs(np.diff(err, axis=a)))) / (f[1] - f[0]) for a, f in enumerate(fine)
    )
    steps = [f[1] - f[0] for f in fine]
    found = float(np.max(np.abs(err)))
    out = controller.system.output
    return LutError(found, found + slope * 0.5 * math.hypot(*steps), out.high - out.low, refine)


def c_sources(
    controller: FuzzyController,
    sample_time_s: float,
    real: str = "double",
    lut: int | None = None,
) -> dict[str, str]:
    """``{name}.h`` and ``{name}.c``: the controller step in C99 (module docstring)."""
    if real not in REALS:
        raise ValueError(f"real must be one of {list(REALS)}, got {real!r}")
    if not (math.isfinite(sample_time_s) and sample_time_s > 0):
        raise ValueError(f"the sample time must be > 0 s, got {sample_time_s}")
    name = identifier(controller.name)
    cp, cs = controller.pack(sample_time_s)
    n_in = len(controller.system.inputs)
    semantics = int(cp[SYSTEM + SYSTEM_HEAD.semantics])
    body = [
        f"/* {name}: fuzzy controller step generated by fuzzyservo (do not edit).",
        f"   form {controller.form}, {controller.system.type}, {controller.system.semantics} "
        f"semantics, sample time {sample_time_s!r} s, {real}"
        + (f", lookup table {lut} points per input" if lut else "")
        + ". */",
        "#include <math.h>",
        f'#include "{name}.h"',
        "",
        *_c_constants(),
        "",
    ]
    if lut:
        grids, table = lut_table(controller, lut)
        head = cp[:SYSTEM]
        body += [
            f"static const {real} CP[{SYSTEM}] = {{\n{_array(head, real)}\n}};",
            f"static const {real} LUT_LO[{n_in}] = {{ {', '.join(_literal(g[0], real) for g in grids)} }};",
            f"static const {real} LUT_HI[{n_in}] = {{ {', '.join(_literal(g[-1], real) for g in grids)} }};",
            f"static const {real} LUT[{table.size}] = {{\n{_array(table.ravel(), real)}\n}};",
            f"#define LUT_N {lut}L",
            "",
            _LUT_MAP.replace("@R@", real),
        ]
    else:
        body += [
            f"#define FS_SAMPLED {int(semantics == SAMPLED)}",
            f"#define FS_EXACT {int(semantics == EXACT)}",
            f"static const {real} CP[{cp.size}] = {{\n{_array(cp, real)}\n}};",
            RUNTIME.replace("@R@", real).replace("@CONSTANT@", str(SHAPE_CODES["constant"])),
            _MAP.replace("@R@", real)
            .replace("@NIN@", str(n_in))
            .replace("@SECOND@", "xs[1] = x1;" if n_in > 1 else "(void)x1;"),
        ]
    init = "\n".join(f"    s->{slot.name} = 0;" for slot in slots(FUZZY_STATE))
    step = _STEP.replace("@INIT@", init).replace("@FORM_PI@", str(FORMS.index("pi")))
    body.append(step.replace("@R@", real).replace("@P@", name))
    scratch = 1 if lut else cs.size - SCRATCH
    header = _HEADER.replace("@STATE@", _c_state()).replace("@NS@", str(scratch))
    header = header.replace("@R@", real).replace("@P@", name)
    header = header.replace("@PU@", name.upper()).replace("@NIN@", str(n_in))
    header = header.replace("@NK@", str(SYSTEM))
    return {f"{name}.h": header, f"{name}.c": "\n".join(body) + "\n"}


def system_c_sources(system: FuzzySystem, real: str = "double") -> dict[str, str]:
    """``{name}.h`` and ``{name}.c``: any inference system (every input and output, Mamdani
    or Sugeno, both semantics) as ``{name}_evaluate(state, x, y)`` in C99 — what
    ``evaluate`` (and MATLAB's ``evalfis``) computes, from the same packed vector and
    evaluator port as :func:`c_sources`."""
    from fuzzyservo.controllers.fuzzy.evaluate import pack_system

    if real not in REALS:
        raise ValueError(f"real must be one of {list(REALS)}, got {real!r}")
    name = identifier(system.name)
    cp, scratch = pack_system(system)
    n_in, n_out = len(system.inputs), len(system.outputs)
    semantics = int(cp[SYSTEM_HEAD.semantics])
    ranges = "\n".join(
        f"   {kind} {k}: {v.name} [{v.low!r}, {v.high!r}]"
        for kind, group in (("input", system.inputs), ("output", system.outputs))
        for k, v in enumerate(group)
    )
    body = [
        f"/* {name}: fuzzy inference system generated by fuzzyservo (do not edit).",
        f"   {system.type}, {system.semantics} semantics, {n_in} input(s), {n_out} output(s),"
        f" {real}.",
        ranges,
        "   Inputs are clipped to their ranges. */",
        "#include <math.h>",
        f'#include "{name}.h"',
        "",
        *_c_constants(),
        "",
        f"#define FS_SAMPLED {int(semantics == SAMPLED)}",
        f"#define FS_EXACT {int(semantics == EXACT)}",
        f"static const {real} CP[{cp.size}] = {{\n{_array(cp, real)}\n}};",
        RUNTIME.replace("@R@", real).replace("@CONSTANT@", str(SHAPE_CODES["constant"])),
        _SYSTEM_EVALUATE.replace("@R@", real).replace("@P@", name),
    ]
    header = _SYSTEM_HEADER.replace("@NS@", str(scratch)).replace("@R@", real)
    header = header.replace("@P@", name).replace("@PU@", name.upper())
    header = header.replace("@NIN@", str(n_in)).replace("@NOUT@", str(n_out))
    return {f"{name}.h": header, f"{name}.c": "\n".join(body) + "\n"}


def _c_constants() -> list[str]:
    """The slots of the packed vectors as C constants (``CP_SAMPLE_TIME``, ``H_N_RULES``
    ...; ``<prefix>_SIZE`` a record's size), generated from the layouts the compiled
    code reads."""
    lines = ["/* slots of the packed vectors (fuzzyservo.controllers.layout) */"]
    for prefix, layout in _LAYOUTS.items():
        names = [f"{prefix}_{slot.name.upper()} = {k}" for k, slot in enumerate(slots(layout))]
        names.append(f"{prefix}_SIZE = {len(layout)}")
        lines.append(f"enum {{ {', '.join(names)} }};")
    lines += [
        f"enum {{ CP_SYSTEM = {SYSTEM} }}; /* the packed system starts here */",
        f"enum {{ SEM_EXACT = {EXACT} }}; /* T_SEMANTICS of the matlab semantics */",
        f"#define NO_TERM ({NO_TERM}L)",
    ]
    return lines


def _c_state() -> str:
    """The state struct's members: the controller's state slots, then its scratch space."""
    lines = [
        f"    {'int' if slot.flag else '@R@'} {slot.name}; /* {slot.doc} */"
        for slot in slots(FUZZY_STATE)
    ]
    return "\n".join([*lines, "    @R@ scratch[@NS@];"])


def write_c(
    controller: FuzzyController,
    folder: str | Path,
    sample_time_s: float,
    real: str = "double",
    lut: int | None = None,
) -> list[Path]:
    """Write :func:`c_sources` into ``folder`` (created); returns the paths."""
    from fuzzyservo.atomic import write_files

    return write_files(c_sources(controller, sample_time_s, real, lut), folder)


def write_st(
    controller: FuzzyController, path: str | Path, sample_time_s: float, lut: int | None = None
) -> tuple[Path, int]:
    """Write the Structured Text function block (:mod:`._st`); returns the path and the
    table size per input."""
    from fuzzyservo.codegen._st import st_source

    if not (math.isfinite(sample_time_s) and sample_time_s > 0):
        raise ValueError(f"the sample time must be > 0 s, got {sample_time_s}")
    text, n = st_source(controller, sample_time_s, identifier(controller.name), lut)
    from fuzzyservo.atomic import write_text

    return write_text(path, text), n


_HEADER = """/* @P@: fuzzy controller step generated by fuzzyservo. C99, no library, no allocation.

   @P@_state s;
   @P@_init(&s);
   every sample:  u = @P@_step(&s, reference, measurement);
*/
#ifndef @PU@_H
#define @PU@_H

#define @PU@_INPUTS @NIN@

typedef struct {
@STATE@
} @P@_state;

void @P@_init(@P@_state *s);
/* one sample of the control law: the command for reference r and measurement y */
@R@ @P@_step(@P@_state *s, @R@ r, @R@ y);
/* the static map F(x0 [, x1]) on the scaled inputs (gains applied by the caller) */
@R@ @P@_map(@P@_state *s, @R@ x0, @R@ x1);
/* the control law with the settings k (@PU@_PARAMS numbers: form index, input, rate and
   output gain, u_min, u_max, sample time, inputs), e.g. changed from @P@_defaults(k) */
#define @PU@_PARAMS @NK@
void @P@_defaults(@R@ *k);
@R@ @P@_law(@P@_state *s, const @R@ *k, @R@ r, @R@ y);

#endif
"""

_SYSTEM_HEADER = """/* @P@: fuzzy inference system generated by fuzzyservo. C99, no library, no allocation.

   @P@_state s;
   @R@ x[@PU@_INPUTS] = {...}, y[@PU@_OUTPUTS];
   @P@_evaluate(&s, x, y);
*/
#ifndef @PU@_H
#define @PU@_H

#define @PU@_INPUTS @NIN@
#define @PU@_OUTPUTS @NOUT@

typedef struct {
    @R@ scratch[@NS@]; /* the evaluator's work space */
} @P@_state;

/* every output y for the inputs x; returns how many outputs no rule fired for (those are
   NaN in the skfuzzy semantics, mid-range in the matlab semantics) */
int @P@_evaluate(@P@_state *s, const @R@ *x, @R@ *y);

#endif
"""

_SYSTEM_EVALUATE = """
int @P@_evaluate(@P@_state *s, const @R@ *x, @R@ *y) { return evaluate_point(0, s->scratch, x, y); }
"""

_MAP = """
static @R@ fs_map(@R@ *scratch, @R@ x0, @R@ x1)
{
    @R@ *xs = scratch, *out = scratch + @NIN@;
    long n_out = ix(CP[CP_SYSTEM + T_N_OUTPUTS]);
    xs[0] = x0;
    @SECOND@
    evaluate_point(CP_SYSTEM, scratch + @NIN@ + n_out, xs, out);
    return out[0];
}
"""

_LUT_MAP = """static @R@ lut_min(@R@ a, @R@ b) { return b < a ? b : a; }
static @R@ lut_max(@R@ a, @R@ b) { return b > a ? b : a; }

/* cell index and fraction of x on the uniform grid of input i (clipped to the grid) */
static long lut_cell(int i, @R@ x, @R@ *frac)
{
    @R@ h = (LUT_HI[i] - LUT_LO[i]) / (@R@)(LUT_N - 1);
    @R@ t = (lut_min(lut_max(x, LUT_LO[i]), LUT_HI[i]) - LUT_LO[i]) / h;
    long k = (long)floor(t);
    if (k > LUT_N - 2) k = LUT_N - 2;
    *frac = t - (@R@)k;
    return k;
}

static @R@ fs_map(@R@ *scratch, @R@ x0, @R@ x1)
{
    @R@ f, g, a, b;
    long k, l;
    (void)scratch;
    k = lut_cell(0, x0, &f);
    if (sizeof(LUT_LO) / sizeof(LUT_LO[0]) == 1) {
        (void)x1;
        return LUT[k] + f * (LUT[k + 1] - LUT[k]);
    }
    l = lut_cell(1 % (int)(sizeof(LUT_LO) / sizeof(LUT_LO[0])), x1, &g);
    a = LUT[k * LUT_N + l] + g * (LUT[k * LUT_N + l + 1] - LUT[k * LUT_N + l]);
    b = LUT[(k + 1) * LUT_N + l] + g * (LUT[(k + 1) * LUT_N + l + 1] - LUT[(k + 1) * LUT_N + l]);
    return a + f * (b - a);
}
"""

_STEP = """
void @P@_init(@P@_state *s)
{
@INIT@
}

@R@ @P@_map(@P@_state *s, @R@ x0, @R@ x1) { return fs_map(s->scratch, x0, x1); }

void @P@_defaults(@R@ *k)
{
    int i;
    for (i = 0; i < CP_SYSTEM; i++) k[i] = CP[i];
}

/* u = G_u F(G_e e [, G_de de]) (form p, pd) or u_k = u_(k-1) + T_s G_u F(...) (form pi),
   clipped to [u_min, u_max]; de = (e - e_prev) / T_s, 0 at the first sample */
@R@ @P@_law(@P@_state *s, const @R@ *k, @R@ r, @R@ y)
{
    @R@ e = r - y, ts = k[CP_SAMPLE_TIME], de, f, u, lo = k[CP_U_MIN], hi = k[CP_U_MAX];
    de = s->started ? (e - s->e_prev) / ts : 0;
    f = fs_map(s->scratch, k[CP_INPUT_GAIN] * e, k[CP_RATE_GAIN] * de);
    u = (long)k[CP_FORM] == @FORM_PI@ ? s->u_prev + ts * k[CP_OUTPUT_GAIN] * f
                                       : k[CP_OUTPUT_GAIN] * f;
    u = (hi < (lo > u ? lo : u)) ? hi : (lo > u ? lo : u);
    s->e_prev = e;
    s->u_prev = u;
    s->started = 1;
    return u;
}

@R@ @P@_step(@P@_state *s, @R@ r, @R@ y) { return @P@_law(s, CP, r, y); }
"""
