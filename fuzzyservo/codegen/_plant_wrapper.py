"""A plant's C model as an FMU for model exchange and co-simulation (FMI 3.0 or 2.0):
the text of ``modelDescription.xml``, of the FMI wrapper ``fmu.c`` around the model's
``plant_rhs``/``plant_signals`` (:mod:`fuzzyservo.plants.c_source`), and the build.

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

from fuzzyservo.codegen._fmi import _attrs, _number, _stubs, c_file_names, sources_folder
from fuzzyservo.codegen._fmi_api import COMMON2, COMMON3, FMI2, FMI3
from fuzzyservo.codegen._fmu import FmuBuild, build_binary, fmi_headers
from fuzzyservo.codegen._plant_wrapper_c import CORE, FMI2_PLANT, FMI3_PLANT, LOGGER2, LOGGER3
from fuzzyservo.plants.fmu import ERROR_SCALE_ANNOTATION
from fuzzyservo.simulation import ROS34PW2
from fuzzyservo.units import parse_unit


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
    # each state's local error per unit of tolerance in the loop that made the model,
    # written as a fuzzyservo annotation (plants/fmu.py reads it back); () for none
    error_scales: tuple[float, ...] = ()

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
        dims = unit.exponents()
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
        lines += ["  </ModelStructure>", *_annotation(model, "Annotations", "Annotation", "type"),
                  "</fmiModelDescription>"]  # fmt: skip
        return "\n".join(lines) + "\n"
    files = "".join(f'<File name="{f}"/>' for f in c_file_names(model.c_files))
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
        *_annotation(model, "VendorAnnotations", "Tool", "name"),
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
    return "\n".join(lines) + "\n"


def _annotation(model: PlantFmuModel, outer: str, inner: str, key: str) -> list[str]:
    """The states' error scales as a fuzzyservo annotation (:data:`ERROR_SCALE_ANNOTATION`):
    FMI 3.0's ``<Annotations><Annotation type=...>`` closes the model description, FMI 2.0's
    ``<VendorAnnotations><Tool name=...>`` comes before the variables."""
    if not model.error_scales:
        return []
    states = [
        f"        <State{_attrs(name=s.name, errorScale=repr(float(e)))}/>"
        for s, e in zip(model.states, model.error_scales, strict=True)
    ]
    return [f"  <{outer}>", f"    <{inner}{_attrs(**{key: ERROR_SCALE_ANNOTATION})}>",
            "      <States>", *states, "      </States>", f"    </{inner}>", f"  </{outer}>"]  # fmt: skip


def _num(x: object) -> str | None:
    return None if x is None else _number(float(x))  # type: ignore[arg-type]


# --------------------------------------------------------------------------- sources
def plant_fmu_sources(model: PlantFmuModel, fmi: int = 3) -> dict[str, str]:
    """The files of the FMU's ``sources/`` folder: the model's C, the FMI wrapper
    ``fmu.c`` and (FMI 3.0) ``buildDescription.xml``."""
    return sources_folder(model.c_files, plant_wrapper(model, fmi), model.identifier, fmi)


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
        "@TYPICAL@": _array(model.typical), "@TOKEN@": model.token, "@STAGES@": str(ROS34PW2.stages),
        "@GAMMA@": _number(ROS34PW2.gamma), "@A_U@": _array(ROS34PW2.a),
        "@C_U@": _array(ROS34PW2.c), "@M_U@": _array(ROS34PW2.m), "@E_U@": _array(ROS34PW2.e),
    }  # fmt: skip
    logger = LOGGER3 if fmi == 3 else LOGGER2
    body = CORE.replace("LOGGER_FIELDS", logger) + (FMI3_PLANT if fmi == 3 else FMI2_PLANT)
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
