"""IEC 61131-3 Structured Text of a whole inference system (any inputs and outputs).

* Sugeno systems (both semantics evaluate them exactly, :mod:`fuzzyservo.controllers.
  fuzzy.exact`): the evaluator written out for this system, straight-line: inputs
  clipped to their ranges, each term's membership (one FUNCTION per MATLAB shape used),
  each rule's firing (AND min/product, OR max/probabilistic OR, NOT, weight), each
  output's weighted average (or sum) of the rules' constant or linear values, the
  middle of its range when no rule fires. The same operations in the same order as the
  compiled evaluator, so the same numbers to rounding.
* Mamdani systems of one or two inputs: each output as a lookup table over the input
  ranges (``n`` points per input) read by (bi)linear interpolation, as the controller's
  ST (:mod:`._st`); the table's values are ``evaluate``'s at the grid points.

Plain IEC 61131-3 (2nd edition): LREAL, DINT, FUNCTIONs and one FUNCTION_BLOCK, no
vendor library.
"""

from __future__ import annotations

import re

import numpy as np

from fuzzyservo.codegen._st import _real
from fuzzyservo.controllers.fuzzy.system import NO_TERM, SHAPES, FuzzySystem, term_index

#: table points per input of a Mamdani system's outputs
ST_SYSTEM_POINTS = {1: 257, 2: 65}

_SHAPE_ST = {
    "trimf": (
        "a, b, c",
        """IF x = b THEN FS_TRIMF := 1.0;
ELSIF x <= a OR x >= c THEN FS_TRIMF := 0.0;
ELSIF x < b THEN FS_TRIMF := (x - a) / (b - a);
ELSE FS_TRIMF := (c - x) / (c - b);
END_IF;""",
    ),
    "trapmf": (
        "a, b, c, d",
        """y1 := 1.0;
IF x < a THEN y1 := 0.0; ELSIF x < b THEN y1 := (x - a) / (b - a); END_IF;
y2 := 1.0;
IF x > d THEN y2 := 0.0; ELSIF x > c THEN y2 := (d - x) / (d - c); END_IF;
FS_TRAPMF := MIN(y1, y2);""",
    ),
    "gaussmf": ("s, c", "FS_GAUSSMF := EXP(-((x - c) * (x - c)) / (2.0 * s * s));"),
    "gbellmf": ("a, b, c", "FS_GBELLMF := 1.0 / (1.0 + EXPT(ABS((x - c) / a), 2.0 * b));"),
    "sigmf": ("a, c", "FS_SIGMF := 1.0 / (1.0 + EXP(-a * (x - c)));"),
    "smf": (
        "a, b",
        """IF a >= b THEN
    IF x >= 0.5 * (a + b) THEN FS_SMF := 1.0; ELSE FS_SMF := 0.0; END_IF;
ELSIF x <= a THEN FS_SMF := 0.0;
ELSIF x >= b THEN FS_SMF := 1.0;
ELSIF x <= 0.5 * (a + b) THEN y1 := (x - a) / (b - a); FS_SMF := 2.0 * y1 * y1;
ELSE y1 := (x - b) / (b - a); FS_SMF := 1.0 - 2.0 * y1 * y1;
END_IF;""",
    ),
    "zmf": (
        "a, b",
        """IF a >= b THEN
    IF x <= 0.5 * (a + b) THEN FS_ZMF := 1.0; ELSE FS_ZMF := 0.0; END_IF;
ELSIF x <= a THEN FS_ZMF := 1.0;
ELSIF x >= b THEN FS_ZMF := 0.0;
ELSIF x <= 0.5 * (a + b) THEN y1 := (x - a) / (b - a); FS_ZMF := 1.0 - 2.0 * y1 * y1;
ELSE y1 := (x - b) / (b - a); FS_ZMF := 2.0 * y1 * y1;
END_IF;""",
    ),
    "pimf": ("a, b, c, d", "FS_PIMF := FS_SMF(x, a, b) * FS_ZMF(x, c, d);"),
    "gauss2mf": (
        "s1, c1, s2, c2",
        """y1 := 1.0;
IF x <= c1 THEN y1 := EXP(-((x - c1) * (x - c1)) / (2.0 * s1 * s1)); END_IF;
y2 := 1.0;
IF x >= c2 THEN y2 := EXP(-((x - c2) * (x - c2)) / (2.0 * s2 * s2)); END_IF;
FS_GAUSS2MF := y1 * y2;""",
    ),
    "dsigmf": ("a1, c1, a2, c2", "FS_DSIGMF := ABS(FS_SIGMF(x, a1, c1) - FS_SIGMF(x, a2, c2));"),
    "psigmf": ("a1, c1, a2, c2", "FS_PSIGMF := FS_SIGMF(x, a1, c1) * FS_SIGMF(x, a2, c2);"),
    "linsmf": (
        "a, b",
        """IF x < a THEN FS_LINSMF := 0.0;
ELSIF x >= b THEN FS_LINSMF := 1.0;
ELSE FS_LINSMF := (x - a) / (b - a);
END_IF;""",
    ),
    "linzmf": (
        "a, b",
        """IF x <= a THEN FS_LINZMF := 1.0;
ELSIF x > b THEN FS_LINZMF := 0.0;
ELSE FS_LINZMF := (b - x) / (b - a);
END_IF;""",
    ),
}
#: shapes whose FUNCTION calls another's
_NEEDS = {"pimf": ("smf", "zmf"), "dsigmf": ("sigmf",), "psigmf": ("sigmf",)}


def _function(shape: str) -> str:
    args, body = _SHAPE_ST[shape]
    decl = "\n".join(f"    {a.strip()} : LREAL;" for a in args.split(","))
    return (f"FUNCTION FS_{shape.upper()} : LREAL\nVAR_INPUT\n    x : LREAL;\n{decl}\nEND_VAR\n"
            f"VAR\n    y1 : LREAL;\n    y2 : LREAL;\nEND_VAR\n{body}\nEND_FUNCTION\n")  # fmt: skip


def _names(system: FuzzySystem) -> list[str]:
    """ST identifiers for the inputs then the outputs (``in1``, ``out1`` … when the
    variables' names are not distinct identifiers)."""
    names = [re.sub(r"\W", "_", v.name, flags=re.ASCII).strip("_") for v in system.inputs]
    names += [re.sub(r"\W", "_", v.name, flags=re.ASCII).strip("_") for v in system.outputs]
    ok = all(n and not n[0].isdigit() and "__" not in n for n in names)
    if ok and len({n.upper() for n in names}) == len(names):
        return names
    return [f"in{k + 1}" for k in range(len(system.inputs))] + [
        f"out{k + 1}" for k in range(len(system.outputs))
    ]


def system_st_source(system: FuzzySystem, name: str) -> str:
    """The Structured Text of ``system`` as FUNCTION_BLOCK ``name`` (module docstring)."""
    names = _names(system)
    n_in = len(system.inputs)
    ins, outs = names[:n_in], names[n_in:]
    head = [
        f"(* {name}: fuzzy inference system generated by fuzzyservo (do not edit).",
        f"   {system.type}, {system.semantics} semantics; inputs {', '.join(ins)} are clipped "
        "to their ranges.",
    ]
    if system.type == "sugeno":
        return _sugeno(system, name, ins, outs, head)
    if n_in > 2:
        raise ValueError(
            f"{system.name!r}: Structured Text holds a Mamdani system as lookup tables over at "
            f"most two inputs; it has {n_in}: export it with --c DIR or --fmu FILE"
        )
    return _mamdani_tables(system, name, ins, outs, head)


def _declarations(ins: list[str], outs: list[str], local: list[str]) -> list[str]:
    return ["VAR_INPUT", *(f"    {n} : LREAL;" for n in ins), "END_VAR",
            "VAR_OUTPUT", *(f"    {n} : LREAL;" for n in outs), "END_VAR",
            "VAR", *(f"    {n} : LREAL;" for n in local), "END_VAR"]  # fmt: skip


def _sugeno(
    system: FuzzySystem, name: str, ins: list[str], outs: list[str], head: list[str]
) -> str:
    n_in = len(ins)
    used = {t.shape for v in system.inputs for t in v.terms}
    for s in list(used):
        used |= set(_NEEDS.get(s, ()))
    functions = [_function(s) for s in _SHAPE_ST if s in used]
    mu = [f"m{i}_{k}" for i, v in enumerate(system.inputs) for k in range(len(v.terms))]
    w = [f"w{r}" for r in range(len(system.rules))]
    local = [f"xc{i}" for i in range(n_in)] + mu + w + ["acc", "num", "den", "z"]
    body = [*head, "   Sugeno: the evaluator written out, exact to rounding. *)",
            f"FUNCTION_BLOCK {name}", *_declarations(ins, outs, local), ""]  # fmt: skip
    for i, v in enumerate(system.inputs):
        body.append(f"xc{i} := MIN(MAX({ins[i]}, {_real(v.low)}), {_real(v.high)});")
        for k, t in enumerate(v.terms):
            params = ", ".join(_real(p) for p in t.params[: SHAPES[t.shape]])
            body.append(f"m{i}_{k} := FS_{t.shape.upper()}(xc{i}, {params});")
    for r, rule in enumerate(system.rules):
        first = True
        for i, code in enumerate(rule.antecedent):
            if code == NO_TERM:
                continue
            k, negated = term_index(code)
            m = f"(1.0 - m{i}_{k})" if negated else f"m{i}_{k}"
            if first:
                body.append(f"acc := {m};")
                first = False
            elif rule.connective == "and":
                op = f"MIN(acc, {m})" if system.and_method == "min" else f"acc * {m}"
                body.append(f"acc := {op};")
            else:
                op = f"MAX(acc, {m})" if system.or_method == "max" else f"acc + {m} - acc * {m}"
                body.append(f"acc := {op};")
        body.append(f"w{r} := acc * {_real(rule.weight)};")
    for o, v in enumerate(system.outputs):
        body += ["num := 0.0;", "den := 0.0;"]
        for r, rule in enumerate(system.rules):
            code = rule.consequents[o]
            k, negated = term_index(code)
            if code == NO_TERM or negated:
                continue
            t = v.terms[k]
            if t.shape == "constant":
                body.append(f"z := {_real(t.params[0])};")
            else:
                body.append(f"z := {_real(t.params[n_in])};")
                body += [f"z := z + {_real(t.params[i])} * xc{i};" for i in range(n_in)]
            body.append(f"IF w{r} <> 0.0 THEN num := num + w{r} * z; den := den + w{r}; END_IF;")
        value = "num" if system.defuzzification == "wtsum" else "num / den"
        body.append(f"IF den = 0.0 THEN {outs[o]} := {_real(0.5 * (v.low + v.high))}; "
                    f"ELSE {outs[o]} := {value}; END_IF;")  # fmt: skip
    body.append("END_FUNCTION_BLOCK")
    return "\n".join(functions) + "\n" + "\n".join(body) + "\n"


def _mamdani_tables(
    system: FuzzySystem, name: str, ins: list[str], outs: list[str], head: list[str]
) -> str:
    from fuzzyservo.controllers.fuzzy.evaluate import evaluate_inputs

    n_in = len(ins)
    n = ST_SYSTEM_POINTS[n_in]
    grids = [np.linspace(v.low, v.high, n) for v in system.inputs]
    mesh = np.meshgrid(*grids, indexing="ij")
    values, _ = evaluate_inputs(system, np.column_stack([m.ravel() for m in mesh]))
    tables = []
    for o, _out in enumerate(outs):
        col = values[:, o]
        rows = ["    " + ", ".join(_real(x) for x in col[k : k + 6]) for k in range(0, col.size, 6)]
        tables += [f"    T{o} : ARRAY[0..{col.size - 1}] OF LREAL := [", ",\n".join(rows), "    ];"]
    consts = [f"    N : DINT := {n};"]
    for i, g in enumerate(grids):
        consts += [f"    LO{i} : LREAL := {_real(g[0])};", f"    HI{i} : LREAL := {_real(g[-1])};"]
    local = ["t0", "t1", "x0", "x1"]
    body = [*head, f"   Mamdani: each output a lookup table of {n} point(s) per input, read",
            "   linearly; the table holds evaluate's values at its points. *)",
            f"FUNCTION_BLOCK {name}", *_declarations(ins, outs, local),
            "VAR", "    k : DINT;", "    l : DINT;", "END_VAR",
            "VAR CONSTANT", *consts, *tables, "END_VAR", ""]  # fmt: skip
    cells = []
    for i in range(n_in):
        cells += [
            f"x{i} := MIN(MAX({ins[i]}, LO{i}), HI{i});",
            f"t{i} := (x{i} - LO{i}) / ((HI{i} - LO{i}) / DINT_TO_LREAL(N - 1));",
            f"{'kl'[i]} := LREAL_TO_DINT(TRUNC(t{i}));",
            f"IF {'kl'[i]} > N - 2 THEN {'kl'[i]} := N - 2; END_IF;",
            f"t{i} := t{i} - DINT_TO_LREAL({'kl'[i]});",
        ]
    body += cells
    for o, out in enumerate(outs):
        t = f"T{o}"
        if n_in == 1:
            body.append(f"{out} := {t}[k] + t0 * ({t}[k + 1] - {t}[k]);")
        else:
            a = f"({t}[k * N + l] + t1 * ({t}[k * N + l + 1] - {t}[k * N + l]))"
            b = f"({t}[(k + 1) * N + l] + t1 * ({t}[(k + 1) * N + l + 1] - {t}[(k + 1) * N + l]))"
            body.append(f"{out} := {a} + t0 * ({b} - {a});")
    body.append("END_FUNCTION_BLOCK")
    return "\n".join(body) + "\n"
