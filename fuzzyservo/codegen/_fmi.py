"""A fuzzy controller or inference system as a co-simulation FMU (FMI 3.0 or 2.0): the
text of ``modelDescription.xml`` and of the C wrapper around the generated C99
(:func:`~fuzzyservo.codegen.c_sources`, :func:`~fuzzyservo.codegen.system_c_sources`).

What the FMU does (Functional Mock-up Interface 3.0, §4 co-simulation; 2.0, §4):

* a **controller** (inputs ``reference`` and ``measurement``, output ``command`` [V]) is
  sampled every ``sample_period`` [s]: a ``doStep`` that starts at or after the next
  sample time reads the inputs set for its start, runs one sample of the control law
  and holds the command until the next sample (zero-order hold). The gains, the output
  limits and the sample period are tunable parameters; the first sample has error
  rate 0, as in fuzzyservo;
* an **inference system** (any inputs and outputs) has no state: its outputs are
  ``evaluate``'s for the inputs set, whenever they are read. Each input's range is its
  ``min``/``max``; inputs beyond it are clipped by the evaluator, as in fuzzyservo.

All state is in the instance (two instances in one process are independent); the
generated code reads only constant tables. Value reference 0 is time (FMI 3.0).
"""

from __future__ import annotations

import hashlib
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from xml.sax.saxutils import quoteattr

from fuzzyservo.codegen._c import c_sources, identifier, system_c_sources
from fuzzyservo.codegen._fmi_api import COMMON2, COMMON3, FMI2, FMI3
from fuzzyservo.controllers.fuzzy.controller import FUZZY_PARAMS, FuzzyController
from fuzzyservo.controllers.fuzzy.system import FuzzySystem
from fuzzyservo.controllers.layout import slots

FMI_VERSIONS = (2, 3)
_UNITS = {"V": 'kg="1" m="2" s="-3" A="-1"', "s": 's="1"'}
_HUGE = 1.7976931348623157e308


@dataclass(frozen=True)
class FmuVariable:
    """One model variable (its value reference is its index in :attr:`FmuModel.variables`)."""

    name: str
    causality: str  # independent, input, output, parameter
    variability: str  # continuous, discrete, tunable
    start: float | None
    description: str
    min: float | None = None
    max: float | None = None
    unit: str | None = None


@dataclass(frozen=True)
class FmuModel:
    """What an FMU of ``target`` declares and holds: its identifier, variables and C files."""

    identifier: str
    description: str
    variables: tuple[FmuVariable, ...]
    controller: bool
    sample_time_s: float
    c_files: dict[str, str]

    @property
    def token(self) -> str:
        """The instantiation token (GUID): a digest of the generated code."""
        digest = hashlib.sha1("".join(self.c_files.values()).encode()).hexdigest()
        d = digest
        return f"{{{d[:8]}-{d[8:12]}-{d[12:16]}-{d[16:20]}-{d[20:32]}}}"

    def refs(self, causality: str) -> list[int]:
        return [k for k, v in enumerate(self.variables) if v.causality == causality]


def fmu_model(target: FuzzyController | FuzzySystem, sample_time_s: float) -> FmuModel:
    """The FMU of a controller (its control law) or of an inference system (any inputs and
    outputs); ``sample_time_s`` the controller's sample period, the default step."""
    if not (math.isfinite(sample_time_s) and sample_time_s > 0):
        raise ValueError(f"the sample time must be > 0 s, got {sample_time_s}")
    time = FmuVariable("time", "independent", "continuous", None, "simulation time [s]",
                       unit="s")  # fmt: skip
    if isinstance(target, FuzzySystem):
        variables = [time]
        for v in target.inputs:
            variables.append(FmuVariable(v.name, "input", "continuous", 0.5 * (v.low + v.high),
                                         f"input {v.name}, its range [{v.low:g}, {v.high:g}] "
                                         "(clipped beyond)", v.low, v.high))  # fmt: skip
        for v in target.outputs:
            variables.append(FmuVariable(v.name, "output", "continuous", None,
                                         f"output {v.name}, range [{v.low:g}, {v.high:g}]"))  # fmt: skip
        return FmuModel(identifier(target.name), f"fuzzy inference system {target.name} "
                        f"({target.type}, {target.semantics} semantics)", tuple(variables),
                        False, sample_time_s, system_c_sources(target))  # fmt: skip
    c = target
    e_lo, e_hi = sorted(
        (c.system.inputs[0].low / c.input_gain, c.system.inputs[0].high / c.input_gain)
    )
    law = f"the error e = reference - measurement; the map's range of e is [{e_lo:g}, {e_hi:g}]"
    variables = [
        time,
        FmuVariable("reference", "input", "continuous", 0.0, f"reference r ({law})"),
        FmuVariable("measurement", "input", "continuous", 0.0, "measurement y (feedback)"),
        FmuVariable(
            "command", "output", "discrete", None, "command u, held between samples", unit="V"
        ),
        FmuVariable("input_gain", "parameter", "tunable", c.input_gain, "G_e"),
        FmuVariable("rate_gain", "parameter", "tunable", c.rate_gain, "G_de [s]"),
        FmuVariable("output_gain", "parameter", "tunable", c.output_gain, "G_u"),
        FmuVariable(
            "u_min", "parameter", "tunable", max(c.u_min, -_HUGE), "lower command limit", unit="V"
        ),
        FmuVariable(
            "u_max", "parameter", "tunable", min(c.u_max, _HUGE), "upper command limit", unit="V"
        ),
        FmuVariable(
            "sample_period",
            "parameter",
            "tunable",
            sample_time_s,
            "controller sample period T_s",
            min=1e-300,
            unit="s",
        ),
    ]
    description = f"fuzzy controller {c.name} (form {c.form}, {c.system.type})"
    return FmuModel(identifier(c.name), description, tuple(variables), True, sample_time_s,
                    c_sources(c, sample_time_s))  # fmt: skip


# --------------------------------------------------------------------------- modelDescription
def _number(x: float) -> str:
    return repr(float(x))


def _attrs(**items: object) -> str:
    return "".join(f" {k}={quoteattr(str(v))}" for k, v in items.items() if v is not None)


def model_description(model: FmuModel, fmi: int = 3) -> str:
    """``modelDescription.xml`` of ``model`` for FMI ``fmi`` (3 or 2)."""
    if fmi not in FMI_VERSIONS:
        raise ValueError(f"fmi must be one of {list(FMI_VERSIONS)}, got {fmi}")
    units = sorted({v.unit for v in model.variables if v.unit} & set(_UNITS))
    unit_xml = ["  <UnitDefinitions>"]
    unit_xml += [f'    <Unit name="{u}"><BaseUnit {_UNITS[u]}/></Unit>' for u in units]
    unit_xml.append("  </UnitDefinitions>")
    head = _attrs(modelName=model.identifier, description=model.description,
                  generationTool="fuzzyservo", variableNamingConvention="flat")  # fmt: skip
    experiment = f'  <DefaultExperiment startTime="0" stepSize="{_number(model.sample_time_s)}"/>'
    if fmi == 3:
        lines = [
            '<?xml version="1.0" encoding="UTF-8"?>',
            f'<fmiModelDescription fmiVersion="3.0"{head}{_attrs(instantiationToken=model.token)}>',
            f"  <CoSimulation{_attrs(modelIdentifier=model.identifier)} "
            'canHandleVariableCommunicationStepSize="true" hasEventMode="false" '
            'canGetAndSetFMUState="false" canSerializeFMUState="false" '
            'providesIntermediateUpdate="false" canReturnEarlyAfterIntermediateUpdate="false"/>',
            *unit_xml,
            experiment,
            "  <ModelVariables>",
        ]
        for vr, v in enumerate(model.variables):
            start = None if v.start is None else _number(v.start)
            lo = None if v.min is None else _number(v.min)
            hi = None if v.max is None else _number(v.max)
            initial = "calculated" if v.causality == "output" else None
            variability = "continuous" if v.causality == "independent" else v.variability
            lines.append(
                f"    <Float64{_attrs(name=v.name, valueReference=vr, causality=v.causality, variability=variability, initial=initial, description=v.description, unit=v.unit, min=lo, max=hi, start=start)}/>"
            )
        lines += ["  </ModelVariables>", "  <ModelStructure>"]
        lines += [f'    <Output valueReference="{vr}"/>' for vr in model.refs("output")]
        lines += [f'    <InitialUnknown valueReference="{vr}"/>' for vr in model.refs("output")]
        lines += ["  </ModelStructure>", "</fmiModelDescription>"]
        return "\n".join(lines) + "\n"
    files = "".join(f'<File name="{f}"/>' for f in c_file_names(model.c_files))
    lines = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f'<fmiModelDescription fmiVersion="2.0"{head}{_attrs(guid=model.token)}>',
        f"  <CoSimulation{_attrs(modelIdentifier=model.identifier)} "
        'canHandleVariableCommunicationStepSize="true" canGetAndSetFMUstate="false" '
        'canSerializeFMUstate="false">',
        f"    <SourceFiles>{files}</SourceFiles>",
        "  </CoSimulation>",
        *unit_xml,
        experiment,
        "  <ModelVariables>",
    ]
    index = {}
    for vr, v in enumerate(model.variables):
        if v.causality == "independent":
            continue
        index[vr] = len(index) + 1
        real = _attrs(unit=v.unit, min=None if v.min is None else _number(v.min),
                      max=None if v.max is None else _number(v.max),
                      start=None if v.start is None else _number(v.start))  # fmt: skip
        variability = v.variability if v.causality != "parameter" else "tunable"
        initial = {"output": "calculated", "parameter": "exact"}.get(v.causality)
        lines += [f"    <ScalarVariable{_attrs(name=v.name, valueReference=vr, causality=v.causality, variability=variability, initial=initial, description=v.description)}>",
                  f"      <Real{real}/>", "    </ScalarVariable>"]  # fmt: skip
    outputs = "".join(f'<Unknown index="{index[vr]}"/>' for vr in model.refs("output"))
    lines += ["  </ModelVariables>", "  <ModelStructure>",
              f"    <Outputs>{outputs}</Outputs>",
              f"    <InitialUnknowns>{outputs}</InitialUnknowns>",
              "  </ModelStructure>", "</fmiModelDescription>"]  # fmt: skip
    return "\n".join(lines) + "\n"


def c_file_names(c_files: Mapping[str, str]) -> list[str]:
    """The C files an FMU's ``sources/`` folder compiles: the generated ones and ``fmu.c``."""
    return [f for f in c_files if f.endswith(".c")] + ["fmu.c"]


def sources_folder(
    c_files: Mapping[str, str], wrapper_text: str, identifier: str, fmi: int
) -> dict[str, str]:
    """An FMU's ``sources/`` folder: the generated C, the FMI wrapper ``fmu.c`` and (FMI
    3.0) ``buildDescription.xml`` naming them."""
    files = {**c_files, "fmu.c": wrapper_text}
    if fmi == 3:
        sources = "".join(f'<SourceFile name="{f}"/>' for f in c_file_names(c_files))
        files["buildDescription.xml"] = (
            '<?xml version="1.0" encoding="UTF-8"?>\n<fmiBuildDescription fmiVersion="3.0">\n'
            f'  <BuildConfiguration modelIdentifier="{identifier}">\n'
            f'    <SourceFileSet language="C99">{sources}</SourceFileSet>\n'
            '    <Library name="m"/>\n  </BuildConfiguration>\n</fmiBuildDescription>\n'
        )
    return files


# --------------------------------------------------------------------------- C wrapper
def fmu_sources(model: FmuModel, fmi: int = 3) -> dict[str, str]:
    """The files of the FMU's ``sources/`` folder: the generated C, the FMI wrapper
    ``fmu.c`` and (FMI 3.0) ``buildDescription.xml``."""
    if fmi not in FMI_VERSIONS:
        raise ValueError(f"fmi must be one of {list(FMI_VERSIONS)}, got {fmi}")
    return sources_folder(model.c_files, wrapper(model, fmi), model.identifier, fmi)


def _model_code(model: FmuModel) -> str:
    """The instance's model functions: reset, update (system) and sample (controller)."""
    p = model.identifier
    n_in = len(model.refs("input"))
    if not model.controller:
        inputs, outputs = model.refs("input"), model.refs("output")
        return "\n".join([
            "static void model_init(Instance *m) { (void)m; }",
            "static void model_sample(Instance *m) { (void)m; }",
            "static void model_update(Instance *m)",
            "{",
            f"    double x[{n_in}], y[{len(outputs)}];",
            *(f"    x[{k}] = m->v[{vr}];" for k, vr in enumerate(inputs)),
            f"    {p}_evaluate(&m->s, x, y);",
            *(f"    m->v[{vr}] = y[{k}];" for k, vr in enumerate(outputs)),
            "}",
            "#define PERIOD_VR (-1)",
        ])  # fmt: skip
    names = {v.name: vr for vr, v in enumerate(model.variables)}
    fill = [f"    k[{k}] = m->v[{names[s.name]}];" for k, s in enumerate(slots(FUZZY_PARAMS))
            if s.name in names]  # fmt: skip
    fill.append(f"    k[{FUZZY_PARAMS.sample_time}] = m->v[{names['sample_period']}];")
    return "\n".join([
        f"static void model_init(Instance *m) {{ {p}_init(&m->s); }}",
        "static void model_update(Instance *m) { (void)m; }",
        "static void model_sample(Instance *m)",
        "{",
        f"    double k[{p.upper()}_PARAMS];",
        f"    {p}_defaults(k);",
        *fill,
        f"    m->v[{names['command']}] = {p}_law(&m->s, k, m->v[{names['reference']}], "
        f"m->v[{names['measurement']}]);",
        "}",
        f"#define PERIOD_VR {names['sample_period']}",
    ])  # fmt: skip


def wrapper(model: FmuModel, fmi: int = 3) -> str:
    """``fmu.c``: the FMI functions around the generated code (module docstring)."""
    v = model.variables
    start = ", ".join(_number(x.start) if x.start is not None else "0" for x in v)
    kinds = ", ".join({"input": "1", "parameter": "2"}.get(x.causality, "0") for x in v)
    api = FMI3 if fmi == 3 else FMI2
    body = (_CORE + (_FMI3 if fmi == 3 else _FMI2)).replace("@MODEL@", _model_code(model))
    body = body.replace("@ADVANCE@", _ADVANCE).replace("@COMMON@", COMMON3 if fmi == 3 else COMMON2)
    body = body.replace("@P@", model.identifier).replace("@NV@", str(len(v)))
    body = body.replace("@START@", start).replace("@KINDS@", kinds)
    body = body.replace("@INCLUDE@", f'#include "fmi{fmi}Functions.h"')
    body = body.replace("@TOKEN@", model.token).replace("@CONTROLLER@", str(int(model.controller)))
    return body + _stubs(api, body)


def _stubs(api: str, done: str) -> str:
    """Every function of ``api`` not defined in ``done``: arguments unused, an error."""
    out = []
    for line in api.splitlines():
        m = re.match(r"^(\w+) (\w+)\((.*)\)$", line)
        if not m or re.search(rf"\b{m[2]}\s*\(", done):
            continue
        names = [re.findall(r"(\w+)\s*(?:\[\])?\s*$", a)[0] for a in m[3].split(",")]
        unused = " ".join(f"(void){n};" for n in names)
        result = {"void": "", "fmi3Instance": " return NULL;", "fmi2Component": " return NULL;"}
        ret = result.get(m[1], f" return {m[1][:4]}Error;")
        out.append(f"{line}\n{{\n    {unused}{ret}\n}}\n")
    return "\n/* not supported by this FMU */\n" + "\n".join(out)


_CORE = r"""/* FMI co-simulation wrapper generated by fuzzyservo (do not edit): the instance holds
   every variable by value reference, the generated code's state and the next sample time. */
#include <stdlib.h>
#include <string.h>
#include <math.h>
#include "@P@.h"
@INCLUDE@

#define N_VARS @NV@
#define IS_CONTROLLER @CONTROLLER@

static const double START[N_VARS] = { @START@ };
/* 1: an input, 2: a tunable parameter, 0: not settable */
static const int KIND[N_VARS] = { @KINDS@ };
"""

# what both FMI versions' instances do alike: reset to the start values, and one
# communication step (a controller samples when its period is due, the FMU may be stepped
# faster; an inference system at every step; v[0] is the time)
_ADVANCE = r"""static void model_reset(Instance *m)
{
    memcpy(m->v, START, sizeof START);
    model_init(m);
    m->next_sample = 0;
}

static const char *refuse(Instance *m, size_t vr, double value)
{
    (void)m;
    if (vr >= N_VARS || KIND[vr] == 0) return "value reference not settable";
    if ((int)vr == PERIOD_VR && !(value > 0)) return "sample_period must be > 0";
    return NULL;
}

static void advance(Instance *m, double t, double h)
{
#if IS_CONTROLLER
    double ts = m->v[PERIOD_VR], eps = 1e-9 * ts;
    if (t + eps >= m->next_sample) {
        model_sample(m);
        m->next_sample += ts;
        if (m->next_sample <= t + eps) m->next_sample = t + ts;
    }
#else
    model_sample(m);
#endif
    m->v[0] = t + h;
}
"""

_FMI3 = r"""
typedef struct {
    @P@_state s;
    double v[N_VARS];
    double next_sample;
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
} Instance;

@MODEL@
@ADVANCE@
@COMMON@

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
    fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
    fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
    const fmi3ValueReference requiredIntermediateVariables[],
    size_t nRequiredIntermediateVariables, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3IntermediateUpdateCallback intermediateUpdate)
{
    Instance *m;
    (void)instanceName; (void)resourcePath; (void)visible; (void)loggingOn;
    (void)earlyReturnAllowed; (void)requiredIntermediateVariables;
    (void)nRequiredIntermediateVariables; (void)intermediateUpdate;
    if (instantiationToken && strcmp(instantiationToken, "@TOKEN@") != 0) {
        if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                                   "instantiationToken does not match this FMU's");
        return NULL;
    }
    if (eventModeUsed) {
        if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                                   "this FMU has no event mode");
        return NULL;
    }
    m = (Instance *)calloc(1, sizeof(Instance));
    if (!m) return NULL;
    m->env = instanceEnvironment;
    m->log = logMessage;
    model_reset(m);
    return m;
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
    fmi3Float64 tolerance, fmi3Float64 startTime, fmi3Boolean stopTimeDefined,
    fmi3Float64 stopTime)
{
    Instance *m = (Instance *)instance;
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    m->v[0] = startTime;
    m->next_sample = startTime;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance)
{
    model_update((Instance *)instance);
    return fmi3OK;
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
    fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
    fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
    fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime)
{
    Instance *m = (Instance *)instance;
    double t = currentCommunicationPoint;
    (void)noSetFMUStatePriorToCurrentPoint;
    advance(m, t, communicationStepSize);
    *eventHandlingNeeded = fmi3False;
    *terminateSimulation = fmi3False;
    *earlyReturn = fmi3False;
    *lastSuccessfulTime = t + communicationStepSize;
    return fmi3OK;
}
"""

_FMI2 = r"""
typedef struct {
    @P@_state s;
    double v[N_VARS];
    double next_sample;
    const fmi2CallbackFunctions *functions;
    char name[64];
} Instance;

@MODEL@
@ADVANCE@
@COMMON@

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
    fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions, fmi2Boolean visible,
    fmi2Boolean loggingOn)
{
    Instance *m;
    (void)fmuResourceLocation; (void)visible; (void)loggingOn;
    if (fmuType != fmi2CoSimulation || (fmuGUID && strcmp(fmuGUID, "@TOKEN@") != 0)) {
        if (functions && functions->logger)
            functions->logger(functions->componentEnvironment, instanceName, fmi2Error,
                              "logStatusError", "%s", "co-simulation only; the GUID must match");
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
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    m->v[0] = startTime;
    m->next_sample = startTime;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    model_update((Instance *)c);
    return fmi2OK;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
    fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    Instance *m = (Instance *)c;
    double t = currentCommunicationPoint;
    (void)noSetFMUStatePriorToCurrentPoint;
    advance(m, t, communicationStepSize);
    return fmi2OK;
}

"""
