"""A plant's C model as an FMU for model exchange and co-simulation (FMI 3.0 or 2.0):
the text of ``modelDescription.xml``, of the FMI wrapper ``fmu.c`` around the model's
``plant_rhs``/``plant_signals`` (:mod:`._plant_c`), and the build.

Value references: 0 time (FMI 3.0 only), then the states, their derivatives
``der(<state>)``, the input, the load, the outputs, the parameters and ``tolerance``. The
instance keeps every value by reference in one array, so the states, the parameters and
the outputs are contiguous blocks the model functions read and write in place.

* **Model exchange**: the importer sets the time, the states and the inputs; the
  derivatives and outputs are computed when read. No event indicators, no time events.
* **Co-simulation**: ``doStep`` integrates the states over the step with the held inputs
  by the loop's own adaptive Rosenbrock-W method ROS34PW2 (order 3, L-stable, a
  finite-difference Jacobian refreshed when a step is rejected), ported from
  :func:`fuzzyservo.simulation._plant_loop.integrate_interval`: each state's local error is
  kept below ``tolerance`` times its nominal value. The step size carries over between
  communication steps.

A parameter the plant does not read is a constant (``tunable=False``), not a parameter.
All state is in the instance; the generated code allocates nothing after instantiation.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np

from fuzzyservo.codegen._fmi import _attrs, _number, _stubs
from fuzzyservo.codegen._fmi_api import COMMON2, COMMON3, FMI2, FMI3
from fuzzyservo.codegen._fmu import FmuBuild, build_binary, fmi_headers
from fuzzyservo.simulation._loop import _A_U, _C_U, _E_U, _GAMMA, _M_U, _STAGES
from fuzzyservo.units import parse_unit

_BASES = ("m", "kg", "s", "A", "rad")  # fuzzyservo.units' dimension order


@dataclass(frozen=True)
class PlantVariable:
    """One variable of a plant FMU: name, SI unit, description, start value; a parameter
    with ``tunable`` False is written as a constant (the plant does not read it)."""

    name: str
    unit: str
    description: str
    start: float = 0.0
    tunable: bool = True


@dataclass(frozen=True)
class PlantFmuModel:
    """What a plant FMU declares and holds (module docstring)."""

    identifier: str
    description: str
    states: tuple[PlantVariable, ...]
    nominals: tuple[float, ...]  # each state's magnitude: FMI nominal, co-simulation error scale
    typical: tuple[float, ...]  # each state's finite-difference size (co-simulation Jacobian)
    input: PlantVariable
    load: PlantVariable
    outputs: tuple[PlantVariable, ...]
    parameters: tuple[PlantVariable, ...]
    c_files: dict[str, str]
    tolerance: float = 1e-6

    @property
    def token(self) -> str:
        """The instantiation token (GUID): a digest of the generated code and variables."""
        text = "".join(self.c_files.values()) + repr(self)
        d = hashlib.sha1(text.encode()).hexdigest()
        return f"{{{d[:8]}-{d[8:12]}-{d[12:16]}-{d[16:20]}-{d[20:32]}}}"


@dataclass(frozen=True)
class _Layout:
    """Value references of each block (module docstring)."""

    nx: int
    ny: int
    npar: int

    @property
    def x0(self) -> int:
        return 1

    @property
    def dx0(self) -> int:
        return 1 + self.nx

    @property
    def u(self) -> int:
        return 1 + 2 * self.nx

    @property
    def load(self) -> int:
        return self.u + 1

    @property
    def y0(self) -> int:
        return self.u + 2

    @property
    def p0(self) -> int:
        return self.y0 + self.ny

    @property
    def tol(self) -> int:
        return self.p0 + self.npar

    @property
    def size(self) -> int:
        return self.tol + 1


def _layout(model: PlantFmuModel) -> _Layout:
    return _Layout(len(model.states), len(model.outputs), len(model.parameters))


# --------------------------------------------------------------------------- description
def _unit_xml(units: set[str]) -> list[str]:
    lines = ["  <UnitDefinitions>"]
    for name in sorted(units):
        unit = parse_unit(name)
        dims = {b: d for b, d in zip(_BASES, unit.dims, strict=True) if d != 0}
        if any(d.denominator != 1 for d in dims.values()):  # FMI base units are integers
            lines.append(f"    <Unit{_attrs(name=name)}/>")
            continue
        base = _attrs(**{b: int(d) for b, d in dims.items()})
        factor = "" if unit.factor == 1.0 else f' factor="{_number(unit.factor)}"'
        lines.append(f"    <Unit{_attrs(name=name)}><BaseUnit{base}{factor}/></Unit>")
    return [*lines, "  </UnitDefinitions>"]


def _rows(model: PlantFmuModel) -> list[dict[str, object]]:
    """Every variable by value reference: its attributes, version-neutral."""
    lay = _layout(model)
    rows: list[dict[str, object]] = [dict(name="time", causality="independent",
                                          variability="continuous", unit="s",
                                          description="simulation time")]  # fmt: skip
    for k, (s, nominal) in enumerate(zip(model.states, model.nominals, strict=True)):
        rows.append(dict(name=s.name, causality="local", variability="continuous",
                         initial="exact", start=s.start, unit=s.unit, nominal=nominal,
                         description=s.description, state=k))  # fmt: skip
    for k, s in enumerate(model.states):
        rows.append(dict(name=f"der({s.name})", causality="local", variability="continuous",
                         initial="calculated", unit=_per_second(s.unit),
                         description=f"time derivative of {s.name}",
                         derivative=lay.x0 + k))  # fmt: skip
    for v in (model.input, model.load):
        rows.append(dict(name=v.name, causality="input", variability="continuous",
                         start=v.start, unit=v.unit, description=v.description))  # fmt: skip
    for v in model.outputs:
        rows.append(dict(name=v.name, causality="output", variability="continuous",
                         initial="calculated", unit=v.unit, description=v.description))  # fmt: skip
    for v in model.parameters:
        kind = ("parameter", "fixed") if v.tunable else ("local", "constant")
        rows.append(dict(name=v.name, causality=kind[0], variability=kind[1], initial="exact",
                         start=v.start, unit=v.unit, description=v.description))  # fmt: skip
    rows.append(dict(name="tolerance", causality="parameter", variability="tunable",
                     initial="exact", start=model.tolerance, unit="1", min=1e-14,
                     description="co-simulation: relative local-error tolerance of the "
                     "Rosenbrock solver (times each state's nominal value)"))  # fmt: skip
    return rows


def _per_second(unit: str) -> str:
    return "1/s" if unit in ("1", "") else f"({unit})/s" if "/" in unit else f"{unit}/s"


def plant_model_description(model: PlantFmuModel, fmi: int = 3) -> str:
    """``modelDescription.xml`` of ``model`` for FMI ``fmi`` (3 or 2)."""
    if fmi not in (2, 3):
        raise ValueError(f"fmi must be 2 or 3, got {fmi}")
    rows = _rows(model)
    lay = _layout(model)
    names = [str(r["name"]) for r in rows]
    if len(set(names)) != len(names):
        twice = sorted({n for n in names if names.count(n) > 1})
        raise ValueError(f"the plant's variables {twice} share a name; rename one")
    units = {str(r["unit"]) for r in rows if r.get("unit")}
    head = _attrs(modelName=model.identifier, description=model.description,
                  generationTool="fuzzyservo", variableNamingConvention="flat")  # fmt: skip
    ident = _attrs(modelIdentifier=model.identifier)
    outputs = [vr for vr, r in enumerate(rows) if r["causality"] == "output"]
    derivatives = [vr for vr, r in enumerate(rows) if "derivative" in r]
    experiment = (
        '  <DefaultExperiment startTime="0" stopTime="1" '
        f'tolerance="{_number(model.tolerance)}" stepSize="0.001"/>'
    )
    if fmi == 3:
        lines = [
            '<?xml version="1.0" encoding="UTF-8"?>',
            f'<fmiModelDescription fmiVersion="3.0"{head}{_attrs(instantiationToken=model.token)}>',
            f'  <ModelExchange{ident} needsCompletedIntegratorStep="false" '
            'canGetAndSetFMUState="false" canSerializeFMUState="false"/>',
            f'  <CoSimulation{ident} canHandleVariableCommunicationStepSize="true" '
            'hasEventMode="false" canGetAndSetFMUState="false" canSerializeFMUState="false" '
            'providesIntermediateUpdate="false" canReturnEarlyAfterIntermediateUpdate="false"/>',
            *_unit_xml(units),
            experiment,
            "  <ModelVariables>",
        ]
        for vr, r in enumerate(rows):
            attrs = _attrs(name=r["name"], valueReference=vr, causality=r["causality"],
                           variability=r["variability"], initial=r.get("initial"),
                           description=r.get("description"), unit=r.get("unit"),
                           derivative=r.get("derivative"),
                           nominal=_num(r.get("nominal")), min=_num(r.get("min")),
                           start=_num(r.get("start")))  # fmt: skip
            lines.append(f"    <Float64{attrs}/>")
        lines += ["  </ModelVariables>", "  <ModelStructure>"]
        lines += [f'    <Output valueReference="{vr}"/>' for vr in outputs]
        lines += [f'    <ContinuousStateDerivative valueReference="{vr}"/>' for vr in derivatives]
        lines += [f'    <InitialUnknown valueReference="{vr}"/>' for vr in outputs + derivatives]
        lines += ["  </ModelStructure>", "</fmiModelDescription>"]
        return "\n".join(lines) + "\n"
    files = "".join(f'<File name="{f}"/>' for f in _c_file_names(model))
    lines = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f'<fmiModelDescription fmiVersion="2.0"{head}{_attrs(guid=model.token)} '
        'numberOfEventIndicators="0">',
        f'  <ModelExchange{ident} completedIntegratorStepNotNeeded="true">'
        f"<SourceFiles>{files}</SourceFiles></ModelExchange>",
        f'  <CoSimulation{ident} canHandleVariableCommunicationStepSize="true">'
        f"<SourceFiles>{files}</SourceFiles></CoSimulation>",
        *_unit_xml(units),
        experiment,
        "  <ModelVariables>",
    ]
    index = {}  # value reference -> 1-based index among the ScalarVariables
    for vr, r in enumerate(rows):
        if r["causality"] == "independent":
            continue
        index[vr] = len(index) + 1
        derivative = index.get(int(r["derivative"])) if "derivative" in r else None  # type: ignore[call-overload]
        real = _attrs(unit=r.get("unit"), derivative=derivative, nominal=_num(r.get("nominal")),
                      min=_num(r.get("min")), start=_num(r.get("start")))  # fmt: skip
        initial = r.get("initial") if r["causality"] != "input" else None
        if r["variability"] == "constant":
            initial = None  # FMI 2.0: a constant's start is its value
        lines += [f"    <ScalarVariable{_attrs(name=r['name'], valueReference=vr, causality=r['causality'], variability=r['variability'], initial=initial, description=r.get('description'))}>",
                  f"      <Real{real}/>", "    </ScalarVariable>"]  # fmt: skip
    unknowns = "".join(f'<Unknown index="{index[vr]}"/>' for vr in outputs)
    ders = "".join(f'<Unknown index="{index[vr]}"/>' for vr in derivatives)
    initial_unknowns = "".join(
        f'<Unknown index="{index[vr]}"/>' for vr in sorted(outputs + derivatives)
    )
    lines += ["  </ModelVariables>", "  <ModelStructure>",
              f"    <Outputs>{unknowns}</Outputs>",
              f"    <Derivatives>{ders}</Derivatives>",
              f"    <InitialUnknowns>{initial_unknowns}</InitialUnknowns>",
              "  </ModelStructure>", "</fmiModelDescription>"]  # fmt: skip
    del lay
    return "\n".join(lines) + "\n"


def _num(x: object) -> str | None:
    return None if x is None else _number(float(x))  # type: ignore[arg-type]


def _c_file_names(model: PlantFmuModel) -> list[str]:
    return [f for f in model.c_files if f.endswith(".c")] + ["fmu.c"]


# --------------------------------------------------------------------------- sources
def plant_fmu_sources(model: PlantFmuModel, fmi: int = 3) -> dict[str, str]:
    """The files of the FMU's ``sources/`` folder: the model's C, the FMI wrapper
    ``fmu.c`` and (FMI 3.0) ``buildDescription.xml``."""
    files = dict(model.c_files)
    files["fmu.c"] = plant_wrapper(model, fmi)
    if fmi == 3:
        sources = "".join(f'<SourceFile name="{f}"/>' for f in _c_file_names(model))
        files["buildDescription.xml"] = (
            '<?xml version="1.0" encoding="UTF-8"?>\n<fmiBuildDescription fmiVersion="3.0">\n'
            f'  <BuildConfiguration modelIdentifier="{model.identifier}">\n'
            f'    <SourceFileSet language="C99">{sources}</SourceFileSet>\n'
            '    <Library name="m"/>\n  </BuildConfiguration>\n</fmiBuildDescription>\n'
        )
    return files


def _array(values: object) -> str:
    return ", ".join(_number(float(v)) for v in np.ravel(values))  # type: ignore[arg-type]


def plant_wrapper(model: PlantFmuModel, fmi: int = 3) -> str:
    """``fmu.c``: the FMI functions around the plant's C (module docstring)."""
    lay = _layout(model)
    rows = _rows(model)
    start = [float(r.get("start", 0.0) or 0.0) for r in rows]  # type: ignore[arg-type]
    kinds = []  # 1: an input (any time), 2: a parameter or start (before initialisation)
    for r in rows:
        kinds.append({"input": 1, "parameter": 2}.get(str(r["causality"]), 0))
        if r.get("initial") == "exact" and r["causality"] == "local" and "state" in r:
            kinds[-1] = 3  # a state: its start before initialisation, else through the API
    header = next(f for f in model.c_files if f.endswith(".h"))
    replace = {
        "@INCLUDE@": f'#include "{header}"\n#include "fmi{fmi}Functions.h"',
        "@NV@": str(lay.size), "@NX@": str(lay.nx), "@NY@": str(lay.ny), "@X0@": str(lay.x0),
        "@DX0@": str(lay.dx0), "@U@": str(lay.u), "@F@": str(lay.load), "@Y0@": str(lay.y0),
        "@P0@": str(lay.p0), "@TOL@": str(lay.tol), "@START@": _array(start),
        "@KINDS@": ", ".join(map(str, kinds)), "@NOMINAL@": _array(model.nominals),
        "@TYPICAL@": _array(model.typical), "@TOKEN@": model.token, "@STAGES@": str(_STAGES),
        "@GAMMA@": _number(_GAMMA), "@A_U@": _array(_A_U), "@C_U@": _array(_C_U),
        "@M_U@": _array(_M_U), "@E_U@": _array(_E_U),
    }  # fmt: skip
    logger = _LOGGER3 if fmi == 3 else _LOGGER2
    body = _CORE.replace("LOGGER_FIELDS", logger) + (_FMI3 if fmi == 3 else _FMI2)
    body = body.replace("@COMMON@", COMMON3 if fmi == 3 else COMMON2)
    for key, value in replace.items():
        body = body.replace(key, value)
    return body + _stubs(FMI3 if fmi == 3 else FMI2, body)


def plant_fmu_build(model: PlantFmuModel, *, fmi: int = 3) -> FmuBuild:
    """The FMU of ``model``: its texts, and its binary compiled for this platform (none,
    with the reason, when no C compiler is found or the build fails)."""
    if fmi not in (2, 3):
        raise ValueError(f"fmi must be 2 or 3, got {fmi}")
    fmi_headers(fmi)  # FMPy's headers first: a clear error without the fmi extra
    sources = plant_fmu_sources(model, fmi)
    files = {"modelDescription.xml": plant_model_description(model, fmi)}
    files |= {f"sources/{name}": text for name, text in sources.items()}
    files["documentation/index.html"] = _DOCUMENTATION.format(
        description=model.description, fmi=fmi
    )
    return build_binary(fmi, files, sources, model.identifier)


_DOCUMENTATION = """<!DOCTYPE html>
<html><head><meta charset="utf-8"><title>{description}</title></head><body>
<h1>{description}</h1>
<p>FMI {fmi}.0 FMU generated by fuzzyservo, for model exchange and co-simulation. Its
equations are translated to C from the components fuzzyservo composes the plant from.</p>
<p>States are named <code>&lt;component&gt;.&lt;state&gt;</code>; every signal of the plant is an
output; every parameter the plant reads is a parameter, named by its rig-file key, in SI
units. Co-simulation integrates with an adaptive Rosenbrock-W method (ROS34PW2), its local
error kept below <code>tolerance</code> times each state's nominal value.</p>
<p>Rebuild for another platform from <code>sources/</code> (C99, no library but libm): compile
every <code>.c</code> file with the FMI headers on the include path into a shared library
named after the model identifier.</p>
</body></html>
"""

_CORE = r"""/* FMI wrapper generated by fuzzyservo (do not edit): a plant for model exchange and
   co-simulation. The instance holds every variable by value reference in v[]. */
#include <stdlib.h>
#include <string.h>
#include <math.h>
@INCLUDE@

#define N_VARS @NV@
#define NX @NX@
#define NY @NY@
#define X0 @X0@
#define DX0 @DX0@
#define U_VR @U@
#define F_VR @F@
#define Y0 @Y0@
#define P0 @P0@
#define TOL_VR @TOL@
#define STAGES @STAGES@
#define MAX_STEPS 200000

static const double START[N_VARS] = { @START@ };
/* 1: an input, 2: a parameter, 3: a state's start, 0: not settable */
static const int KIND[N_VARS] = { @KINDS@ };
static const double NOMINAL[NX] = { @NOMINAL@ };
static const double TYPICAL[NX] = { @TYPICAL@ };
/* ROS34PW2 in transformed variables (fuzzyservo.simulation._loop) */
static const double GAMMA = @GAMMA@;
static const double A_U[STAGES][STAGES] = { @A_U@ };
static const double C_U[STAGES][STAGES] = { @C_U@ };
static const double M_U[STAGES] = { @M_U@ };
static const double E_U[STAGES] = { @E_U@ };

typedef struct {
    double v[N_VARS];
    double h;                 /* the co-simulation's next step size (0: not yet) */
    int initialised;
    double f0[NX], ftmp[NX], xs[NX], xn[NX], k[STAGES][NX];
    double jac[NX][NX], w[NX][NX];
    int piv[NX];
    LOGGER_FIELDS
} Instance;

static void model_update(Instance *m)
{
    plant_rhs(&m->v[X0], m->v[U_VR], m->v[F_VR], &m->v[P0], &m->v[DX0]);
    plant_signals(&m->v[X0], m->v[U_VR], m->v[F_VR], &m->v[P0], &m->v[Y0]);
}

static void rhs(Instance *m, const double *x, double *dx)
{
    plant_rhs(x, m->v[U_VR], m->v[F_VR], &m->v[P0], dx);
}

static int lu_factor(double a[NX][NX], int *piv)
{
    int i, j, k, p;
    for (k = 0; k < NX; k++) {
        double big = fabs(a[k][k]), inv;
        p = k;
        for (i = k + 1; i < NX; i++)
            if (fabs(a[i][k]) > big) { big = fabs(a[i][k]); p = i; }
        if (big == 0.0 || !isfinite(big)) return 0;
        piv[k] = p;
        if (p != k)
            for (j = 0; j < NX; j++) { double t = a[k][j]; a[k][j] = a[p][j]; a[p][j] = t; }
        inv = 1.0 / a[k][k];
        for (i = k + 1; i < NX; i++) {
            double f;
            a[i][k] *= inv;
            f = a[i][k];
            if (f != 0.0)
                for (j = k + 1; j < NX; j++) a[i][j] -= f * a[k][j];
        }
    }
    return 1;
}

static void lu_solve(double a[NX][NX], const int *piv, double *b)
{
    int i, j, k;
    for (k = 0; k < NX; k++)
        if (piv[k] != k) { double t = b[k]; b[k] = b[piv[k]]; b[piv[k]] = t; }
    for (i = 0; i < NX; i++) {
        double s = b[i];
        for (j = 0; j < i; j++) s -= a[i][j] * b[j];
        b[i] = s;
    }
    for (i = NX - 1; i >= 0; i--) {
        double s = b[i];
        for (j = i + 1; j < NX; j++) s -= a[i][j] * b[j];
        b[i] = s / a[i][i];
    }
}

static void jacobian(Instance *m, double *x)
{
    int i, j;
    rhs(m, x, m->f0);
    for (j = 0; j < NX; j++) {
        double xj = x[j], dj = 1.4901161193847656e-08 * fmax(fabs(xj), TYPICAL[j]);
        x[j] = xj + dj;
        rhs(m, x, m->ftmp);
        x[j] = xj;
        for (i = 0; i < NX; i++) m->jac[i][j] = (m->ftmp[i] - m->f0[i]) / dj;
    }
}

/* Advance the states over `duration` with the inputs held: 1 on success, 0 on failure. */
static int integrate(Instance *m, double duration)
{
    double *x = &m->v[X0], t = 0.0, tol = m->v[TOL_VR], h_first = 0.0;
    double h = m->h > 0.0 ? fmin(m->h, duration) : duration, h_min = 1e-14 * duration;
    int steps = 0, need_jac = 0, fresh = 1, i, j, st;
    if (NX == 0) return 1;
    jacobian(m, x);
    while (t < duration * (1.0 - 1e-12)) {
        double hs = fmin(h, duration - t), h_inv, diag, err = 0.0;
        int finite = 1;
        if (steps >= MAX_STEPS) return 0;
        if (need_jac) { jacobian(m, x); need_jac = 0; fresh = 1; }
        h_inv = 1.0 / hs;
        diag = h_inv / GAMMA;
        for (i = 0; i < NX; i++) {
            for (j = 0; j < NX; j++) m->w[i][j] = -m->jac[i][j];
            m->w[i][i] += diag;
        }
        if (!lu_factor(m->w, m->piv)) return 0;
        for (i = 0; i < NX; i++) m->k[0][i] = m->f0[i];
        lu_solve(m->w, m->piv, m->k[0]);
        for (st = 1; st < STAGES; st++) {
            for (i = 0; i < NX; i++) {
                double acc = x[i];
                for (j = 0; j < st; j++) acc += A_U[st][j] * m->k[j][i];
                m->xs[i] = acc;
            }
            rhs(m, m->xs, m->ftmp);
            for (i = 0; i < NX; i++) {
                double acc = 0.0;
                for (j = 0; j < st; j++) acc += C_U[st][j] * m->k[j][i];
                m->k[st][i] = m->ftmp[i] + acc * h_inv;
            }
            lu_solve(m->w, m->piv, m->k[st]);
        }
        for (i = 0; i < NX; i++) {
            double acc = x[i], e = 0.0;
            for (st = 0; st < STAGES; st++) {
                acc += M_U[st] * m->k[st][i];
                e += E_U[st] * m->k[st][i];
            }
            m->xn[i] = acc;
            e = fabs(e) / (tol * NOMINAL[i]);
            if (!isfinite(acc) || !isfinite(e)) finite = 0;
            else if (e > err) err = e;
        }
        steps++;
        if (finite && err <= 1.0) {
            double fac = err == 0.0 ? 5.0 : fmin(5.0, fmax(0.2, 0.8 * pow(err, -1.0 / 3.0)));
            t += hs;
            for (i = 0; i < NX; i++) x[i] = m->xn[i];
            if (t < duration * (1.0 - 1e-12)) rhs(m, x, m->f0);
            fresh = 0;
            if (hs < h) { if (fac < 1.0) h = fmin(h, hs * fac); }
            else h = fmin(hs * fac, duration);
            if (h_first == 0.0) h_first = h;
        } else {
            if (!fresh) { need_jac = 1; continue; }
            h = hs * (finite ? fmax(0.2, 0.8 * pow(err, -1.0 / 3.0)) : 0.2);
            if (h < h_min) return 0;
        }
    }
    m->h = h_first > 0.0 ? h_first : h;
    return 1;
}

static void model_reset(Instance *m)
{
    memcpy(m->v, START, sizeof START);
    m->h = 0.0;
    m->initialised = 0;
    model_update(m);
}

static const char *refuse(Instance *m, size_t vr, double value)
{
    if (vr >= N_VARS) return "unknown value reference";
    if ((int)vr == TOL_VR) return value > 0 ? NULL : "tolerance must be > 0";
    if (KIND[vr] == 1 || (KIND[vr] >= 2 && !m->initialised)) return NULL;
    return "value reference not settable now";
}
"""

_LOGGER3 = "fmi3InstanceEnvironment env; fmi3LogMessageCallback log;"
_LOGGER2 = "const fmi2CallbackFunctions *functions; char name[64];"

_FMI3 = r"""
@COMMON@

static Instance *make(fmi3String token, fmi3InstanceEnvironment env, fmi3LogMessageCallback log)
{
    Instance *m;
    if (token && strcmp(token, "@TOKEN@") != 0) {
        if (log) log(env, fmi3Error, "logStatusError", "instantiationToken does not match");
        return NULL;
    }
    m = (Instance *)calloc(1, sizeof(Instance));
    if (!m) return NULL;
    m->env = env;
    m->log = log;
    model_reset(m);
    return m;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
    fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
    fmi3InstanceEnvironment instanceEnvironment, fmi3LogMessageCallback logMessage)
{
    (void)instanceName; (void)resourcePath; (void)visible; (void)loggingOn;
    return make(instantiationToken, instanceEnvironment, logMessage);
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
    fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
    fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
    const fmi3ValueReference requiredIntermediateVariables[],
    size_t nRequiredIntermediateVariables, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3IntermediateUpdateCallback intermediateUpdate)
{
    (void)instanceName; (void)resourcePath; (void)visible; (void)loggingOn;
    (void)earlyReturnAllowed; (void)requiredIntermediateVariables;
    (void)nRequiredIntermediateVariables; (void)intermediateUpdate;
    if (eventModeUsed) {
        if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                                   "this FMU has no event mode");
        return NULL;
    }
    return make(instantiationToken, instanceEnvironment, logMessage);
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
    fmi3Float64 tolerance, fmi3Float64 startTime, fmi3Boolean stopTimeDefined,
    fmi3Float64 stopTime)
{
    Instance *m = (Instance *)instance;
    (void)stopTimeDefined; (void)stopTime;
    if (toleranceDefined && tolerance > 0) m->v[TOL_VR] = tolerance;
    m->v[0] = startTime;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance)
{
    Instance *m = (Instance *)instance;
    m->initialised = 1;
    model_update(m);
    return fmi3OK;
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance) { (void)instance; return fmi3OK; }
fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) { (void)instance; return fmi3OK; }

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *n)
{
    (void)instance;
    *n = NX;
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *n)
{
    (void)instance;
    *n = 0;
    return fmi3OK;
}

fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time)
{
    ((Instance *)instance)->v[0] = time;
    return fmi3OK;
}

fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 states[],
                                   size_t nContinuousStates)
{
    Instance *m = (Instance *)instance;
    if (nContinuousStates != NX) return fail(m, "wrong number of states");
    memcpy(&m->v[X0], states, NX * sizeof(double));
    return fmi3OK;
}

fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 states[],
                                   size_t nContinuousStates)
{
    Instance *m = (Instance *)instance;
    if (nContinuousStates != NX) return fail(m, "wrong number of states");
    memcpy(states, &m->v[X0], NX * sizeof(double));
    return fmi3OK;
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[],
                                             size_t nContinuousStates)
{
    Instance *m = (Instance *)instance;
    if (nContinuousStates != NX) return fail(m, "wrong number of states");
    rhs(m, &m->v[X0], derivatives);
    return fmi3OK;
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[],
                                             size_t nContinuousStates)
{
    Instance *m = (Instance *)instance;
    if (nContinuousStates != NX) return fail(m, "wrong number of states");
    memcpy(nominals, NOMINAL, NX * sizeof(double));
    return fmi3OK;
}

fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[],
                                  size_t nEventIndicators)
{
    (void)eventIndicators;
    if (nEventIndicators != 0) return fail((Instance *)instance, "no event indicators");
    return fmi3OK;
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance,
    fmi3Boolean noSetFMUStatePriorToCurrentPoint, fmi3Boolean *enterEventMode,
    fmi3Boolean *terminateSimulation)
{
    (void)instance; (void)noSetFMUStatePriorToCurrentPoint;
    *enterEventMode = fmi3False;
    *terminateSimulation = fmi3False;
    return fmi3OK;
}

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
    fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsOfContinuousStatesChanged,
    fmi3Boolean *valuesOfContinuousStatesChanged, fmi3Boolean *nextEventTimeDefined,
    fmi3Float64 *nextEventTime)
{
    (void)instance;
    *discreteStatesNeedUpdate = fmi3False;
    *terminateSimulation = fmi3False;
    *nominalsOfContinuousStatesChanged = fmi3False;
    *valuesOfContinuousStatesChanged = fmi3False;
    *nextEventTimeDefined = fmi3False;
    *nextEventTime = 0.0;
    return fmi3OK;
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
    fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
    fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
    fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime)
{
    Instance *m = (Instance *)instance;
    (void)noSetFMUStatePriorToCurrentPoint;
    *eventHandlingNeeded = fmi3False;
    *terminateSimulation = fmi3False;
    *earlyReturn = fmi3False;
    *lastSuccessfulTime = currentCommunicationPoint;
    if (communicationStepSize > 0 && !integrate(m, communicationStepSize))
        return fail(m, "the plant's integration failed (diverged or too many steps)");
    m->v[0] = currentCommunicationPoint + communicationStepSize;
    *lastSuccessfulTime = m->v[0];
    model_update(m);
    return fmi3OK;
}
"""

_FMI2 = r"""
@COMMON@

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
    fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions, fmi2Boolean visible,
    fmi2Boolean loggingOn)
{
    Instance *m;
    (void)fmuResourceLocation; (void)visible; (void)loggingOn; (void)fmuType;
    if (fmuGUID && strcmp(fmuGUID, "@TOKEN@") != 0) {
        if (functions && functions->logger)
            functions->logger(functions->componentEnvironment, instanceName, fmi2Error,
                              "logStatusError", "%s", "the GUID does not match");
        return NULL;
    }
    m = (Instance *)calloc(1, sizeof(Instance));
    if (!m) return NULL;
    m->functions = functions;
    if (instanceName) strncpy(m->name, instanceName, sizeof m->name - 1);
    model_reset(m);
    return m;
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
    fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    Instance *m = (Instance *)c;
    (void)stopTimeDefined; (void)stopTime;
    if (toleranceDefined && tolerance > 0) m->v[TOL_VR] = tolerance;
    m->v[0] = startTime;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    Instance *m = (Instance *)c;
    m->initialised = 1;
    model_update(m);
    return fmi2OK;
}

fmi2Status fmi2EnterEventMode(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) { (void)c; return fmi2OK; }

fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *info)
{
    (void)c;
    info->newDiscreteStatesNeeded = fmi2False;
    info->terminateSimulation = fmi2False;
    info->nominalsOfContinuousStatesChanged = fmi2False;
    info->valuesOfContinuousStatesChanged = fmi2False;
    info->nextEventTimeDefined = fmi2False;
    info->nextEventTime = 0.0;
    return fmi2OK;
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
    fmi2Boolean *enterEventMode, fmi2Boolean *terminateSimulation)
{
    (void)c; (void)noSetFMUStatePriorToCurrentPoint;
    *enterEventMode = fmi2False;
    *terminateSimulation = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time)
{
    ((Instance *)c)->v[0] = time;
    return fmi2OK;
}

fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx)
{
    Instance *m = (Instance *)c;
    if (nx != NX) return fail(m, "wrong number of states");
    memcpy(&m->v[X0], x, NX * sizeof(double));
    return fmi2OK;
}

fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx)
{
    Instance *m = (Instance *)c;
    if (nx != NX) return fail(m, "wrong number of states");
    memcpy(x, &m->v[X0], NX * sizeof(double));
    return fmi2OK;
}

fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real derivatives[], size_t nx)
{
    Instance *m = (Instance *)c;
    if (nx != NX) return fail(m, "wrong number of states");
    rhs(m, &m->v[X0], derivatives);
    return fmi2OK;
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x_nominal[], size_t nx)
{
    Instance *m = (Instance *)c;
    if (nx != NX) return fail(m, "wrong number of states");
    memcpy(x_nominal, NOMINAL, NX * sizeof(double));
    return fmi2OK;
}

fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real eventIndicators[], size_t ni)
{
    (void)eventIndicators;
    if (ni != 0) return fail((Instance *)c, "no event indicators");
    return fmi2OK;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
    fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    Instance *m = (Instance *)c;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (communicationStepSize > 0 && !integrate(m, communicationStepSize))
        return fail(m, "the plant's integration failed (diverged or too many steps)");
    m->v[0] = currentCommunicationPoint + communicationStepSize;
    model_update(m);
    return fmi2OK;
}

"""
