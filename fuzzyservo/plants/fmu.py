"""A plant from outside: an FMU (FMI 2.0 or 3.0), integrated by the loop or stepped.

Simscape, Amesim, Dymola/OpenModelica and Hopsan all export FMUs; :func:`fmu_plant`
makes one the plant of a rig, so every command (simulate, compare, tune, robustness,
calibrate, ...) runs on it exactly as on a composed plant. The FMU is integrated by the
closed loop's own Rosenbrock solver: its right-hand side sets the states and the
command on an FMU instance and reads the derivatives through the FMU's C functions,
called from the compiled loop (:mod:`fuzzyservo.plants._fmi_calls`), not from Python.
Through its co-simulation interface (``interface``) the FMU is stepped instead, once per
control interval by its own solver (the loop's ``plant_advance`` slot): the held command
set, one ``doStep``, the mapped variables read back as the loop's states.

What a rig maps (``plant.fmu`` in a rig file):

* ``input``: the FMU input variable the actuator drives (its unit is the plant input's);
  none for an FMU without inputs (the loop runs, the command drives nothing);
* ``load``: optionally, the input variable a scenario's load drives;
* ``signals``: the loop's signal names and the FMU variables they read (outputs, states,
  locals); an array element is ``name[i]`` (1-based, as Modelica writes it);
* ``interface``: ``model-exchange`` (where offered, the default) or ``co-simulation``;
* the FMU's scalar real parameters are the plant's parameters: a rig may set them (with
  units), fit them and sample them like any parameter.

Not handled: event indicators and time events (a model-exchange FMU declaring event
indicators is refused), explicit dependence on time in model exchange (the instance
stays at t = 0: a plant is autonomous but for its inputs), and loop stages integrated
beside a stepped plant (the valve lag). FMPy (the ``fmi`` extra) reads the model
description and loads the library.
"""

from __future__ import annotations

import atexit
import ctypes
import dataclasses
import re
import shutil
import tempfile
import zipfile
from collections import OrderedDict
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any
from xml.etree import ElementTree

import numpy as np

from fuzzyservo.components.effects import INPUT_EFFECTS, EffectParams
from fuzzyservo.params import quantity
from fuzzyservo.plants import PlantModel
from fuzzyservo.plants._fmi_calls import FUNCTIONS, FUNCTIONS_CS, HANDLES

__all__ = ["FmuPlantError", "fmu_plant"]

#: instances kept alive per plant (one per parameter set a run used lately)
_INSTANCES = 8


class FmuPlantError(ValueError):
    """An FMU that cannot be a plant, or a mapping that does not fit it: one line naming the
    file, the variable and the fix."""


@dataclass(frozen=True)
class _Variable:
    """A real variable of the FMU: value reference, flattened size, unit, start values."""

    name: str
    vr: int
    size: int
    unit: str
    causality: str
    start: tuple[float, ...]
    description: str
    nominal: float = 1.0


def fmu_plant(
    file: str | Path,
    *,
    input: str | None = None,
    load: str | None = None,
    signals: Mapping[str, str] | None = None,
    interface: str | None = None,
) -> PlantModel:
    """The plant of the FMU ``file`` (FMI 2.0 or 3.0): the command drives its input
    variable ``input``, a scenario's load ``load``, and ``signals`` names the loop's
    signals by FMU variable (default: every output, by its own name). ``interface``:
    ``model-exchange`` (integrated by the loop), ``co-simulation`` (stepped once per
    control interval by its own solver) or None (model exchange where the FMU offers
    it). Raises :class:`FmuPlantError` (one line) when the FMU cannot be a plant or a
    name does not fit it. Cached: the same file and mapping give the same plant.
    """
    return _fmu_plant(
        str(Path(file).resolve()), input, load, tuple((signals or {}).items()) or None,
        interface,
    )  # fmt: skip


#: how a rig names an FMU's interfaces (``plant.fmu.interface``)
INTERFACES = ("model-exchange", "co-simulation")


@cache
def _fmu_plant(
    file: str,
    input: str | None,
    load: str | None,
    signals: tuple[tuple[str, str], ...] | None,
    interface: str | None = None,
) -> PlantModel:
    md, unzipped, error_scales = _read(file)
    name = Path(file).name
    if interface not in (None, *INTERFACES):
        raise FmuPlantError(f"{name}: interface {interface!r}: choose one of {list(INTERFACES)}")
    stepped = interface == "co-simulation" or (interface is None and md.modelExchange is None)
    offered = md.coSimulation if stepped else md.modelExchange
    if offered is None:
        raise FmuPlantError(
            f"{name}: the FMU has no {'co-simulation' if stepped else 'model exchange'} "
            "interface; export it with one, or name the interface it has"
        )
    if not stepped and int(md.numberOfEventIndicators or 0) > 0:
        raise FmuPlantError(
            f"{name}: the FMU declares {md.numberOfEventIndicators} event indicators; the loop "
            "integrates plants without events: export the plant without them (smooth "
            "switching, no state events)"
        )
    version = int(md.fmiVersion.split(".")[0])
    variables = _variables(md, name)
    # the continuous states, element by element (an array state holds several); a
    # co-simulation FMU's are its own: the loop keeps what it reads after each step
    states = [] if stepped else _states(md)
    elements = [(variables[s], i) for s in states for i in range(variables[s].size)]
    nx = len(elements)

    def element(ref: str, what: str, *, inputs_only: bool = False) -> tuple[_Variable, int]:
        match = re.fullmatch(r"(.+)\[(\d+)\]", ref)
        var_name, index = (match[1], int(match[2]) - 1) if match else (ref, 0)
        var = variables.get(var_name)
        if var is None:
            choices = sorted(v.name for v in variables.values() if not inputs_only
                             or v.causality == "input")  # fmt: skip
            raise FmuPlantError(
                f"{name}: {what} {ref!r} is no real variable of the FMU; choose one of {choices}"
            )
        if inputs_only and var.causality != "input":
            raise FmuPlantError(
                f"{name}: {what} {ref!r} is a {var.causality} variable, not an input; name one "
                "of the FMU's inputs"
            )
        if not 0 <= index < var.size or (var.size > 1 and not match):
            raise FmuPlantError(
                f"{name}: {what} {ref!r}: {var_name} holds {var.size} values; name one as "
                f"{var_name}[1] .. {var_name}[{var.size}]"
            )
        return var, index

    # the inputs: every input variable is set on each call (the unmapped ones at their start)
    input_vars = [v for v in variables.values() if v.causality == "input"]
    offsets = np.cumsum([0] + [v.size for v in input_vars]).tolist()
    at = [-1, -1]
    units = ["1", "N"]
    for slot, ref, what in ((0, input, "input"), (1, load, "load")):
        if ref is None:
            continue
        var, index = element(ref, what, inputs_only=True)
        at[slot] = offsets[input_vars.index(var)] + index
        units[slot] = var.unit
    if signals is None:  # every scalar output by its own name
        signals = tuple(
            (v.name, v.name)
            for v in variables.values()
            if v.causality == "output" and v.size == 1 and v.name.isidentifier()
        )
    reads = []
    for signal, ref in signals:
        if not signal.isidentifier():
            raise FmuPlantError(f"{name}: signal name {signal!r} must be a Python identifier")
        var, index = element(ref, f"signal {signal}")
        reads.append((signal, var, index))
    # the states are signals too (the feedback sensor reads a state): by the name of the
    # signal that reads one, else by their own (``x[2]`` for an array's element)
    named = {(var.name, index): signal for signal, var, index in reads}
    state_names = [
        named.get((var.name, i), var.name if var.size == 1 else f"{var.name}[{i + 1}]")
        for var, i in elements
    ]
    reads += [
        (state, var, i)
        for state, (var, i) in zip(state_names, elements, strict=True)
        if state not in named.values()
    ]

    if stepped:  # the loop keeps what it reads: those values are its states
        state_names = [signal for signal, _, _ in reads]
        elements = [(var, i) for _, var, i in reads]
    parameters = [v for v in variables.values() if v.causality == "parameter" and v.start]
    slots = _slots(parameters)
    params_cls = _params_class(file, slots, (file, input, load, signals, interface))
    binding = _binding(
        nx,
        input_vars,
        [v.start[i] if i < len(v.start) else 0.0 for v in input_vars for i in range(v.size)],
        at,
        reads,
        stepped,
    )
    pool = _Pool(file, md, unzipped, version, nx, parameters, slots, stepped, reads)
    # a state's size: its nominal value where the FMU declares one, else 1; its error
    # scale 1e-6 of that, or the one a plant exported by fuzzyservo carries
    nominal = np.array([var.nominal for var, _ in elements])
    scale = np.array(
        [error_scales.get(var.name, 1e-6 * var.nominal) if var.size == 1 else 1e-6 * var.nominal
         for var, _ in elements]
    )  # fmt: skip
    model = PlantModel(
        type_name="fmu",
        binding=binding,
        params_cls=params_cls,
        states=tuple(state_names),
        signals=tuple(s for s, _, _ in reads),
        signal_units={s: var.unit for s, var, _ in reads},
        # the command and load by identifiers (a data file's column names): u[1] is u_1
        input=(_identifier(input or "u"), units[0]),
        load=(_identifier(load or "load"), units[1]),
        initial_keys={},
        initial_state=lambda params, **_: pool.initial_state(params),
        state_scale=lambda params: scale.copy(),
        typical_state=lambda params: nominal.copy(),
        description=f"FMU {name} ({md.modelName}, FMI {md.fmiVersion} "
        f"{'co-simulation' if stepped else 'model exchange'})",
        # the loop's stages on the command wrap any plant; a stepped one takes no stage
        # the loop would integrate beside it (the spool's lag)
        effects=tuple(e for e in INPUT_EFFECTS if not (stepped and e in _INTEGRATED)),
        mechanics={"force": units[1], "velocity": "1", "position": "1"},
        null_input=lambda params: 0.0,
        effect_scales=None,
        attach=pool.handles,
        recipe=(_fmu_plant, (file, input, load, signals, interface)),
        stepped=stepped,
    )
    return model


# the stages on the command the loop integrates as states beside the plant
_INTEGRATED = ("valve_lag",)


# the annotation in which a plant FMU exported by fuzzyservo (codegen/_plant_export.py)
# carries each state's error scale: the local error per unit of tolerance the loop's
# solver allows, so that the FMU runs with the steps its native composition takes
ERROR_SCALE_ANNOTATION = "org.fuzzyservo.error_scale"


def _read(file: str) -> tuple[Any, str, dict[str, float]]:
    """The model description, the folder the FMU is unzipped into (removed at exit) and
    the states' error scales a fuzzyservo annotation gives (:data:`ERROR_SCALE_ANNOTATION`)."""
    try:
        from fmpy import extract, read_model_description
    except ImportError:  # pragma: no cover - the fmi extra is missing
        raise FmuPlantError(
            f"{Path(file).name}: FMU plants need FMPy: pip install 'fuzzyservo[fmi]'"
        ) from None
    if not Path(file).is_file():
        raise FmuPlantError(f"{file}: no such FMU file; give the path of a .fmu file")
    try:
        with zipfile.ZipFile(file) as zf:
            root = ElementTree.fromstring(zf.read("modelDescription.xml"))
        version = root.get("fmiVersion")
        if version not in ("2.0", "3.0"):
            raise FmuPlantError(
                f"{Path(file).name}: FMI {version} is not supported; export FMI 2.0 or 3.0"
            )
        md = read_model_description(file)
    except FmuPlantError:
        raise
    except Exception as exc:  # a bad zip, no or broken XML; FMPy raises plain exceptions
        message = " ".join(str(exc).split())[:200]
        raise FmuPlantError(
            f"{Path(file).name}: not a readable FMU ({message}); export it again"
        ) from None
    folder = tempfile.mkdtemp(prefix="fuzzyservo-fmu-")
    atexit.register(shutil.rmtree, folder, ignore_errors=True)
    return md, extract(file, unzipdir=folder), _error_scales(root)


def _error_scales(root: Any) -> dict[str, float]:
    """State name -> error scale, from ``<Annotation type=...>`` (FMI 3.0) or ``<Tool
    name=...>`` (FMI 2.0) elements named :data:`ERROR_SCALE_ANNOTATION`."""
    out = {}
    for element in root.iter():
        if element.tag in ("Annotation", "Tool") and ERROR_SCALE_ANNOTATION in (
            element.get("type"),
            element.get("name"),
        ):
            for state in element.iter("State"):
                try:
                    value = float(state.get("errorScale", "nan"))
                except ValueError:
                    continue
                if np.isfinite(value) and value > 0:
                    out[state.get("name", "")] = value
    return out


def _variables(md: Any, name: str) -> dict[str, _Variable]:
    """The FMU's real variables by name, array sizes resolved from their dimensions."""
    by_vr = {v.valueReference: v for v in md.modelVariables}
    out = {}
    for v in md.modelVariables:
        if v.type not in ("Real", "Float64") or v.causality == "independent":
            continue
        size = 1
        for dim in v.dimensions:
            size *= (
                int(dim.start) if dim.start is not None else int(by_vr[dim.valueReference].start)
            )
        start = tuple(float(s) for s in str(v.start).split()) if v.start is not None else ()
        unit = v.unit or (v.declaredType.unit if v.declaredType is not None else None) or "1"
        out[v.name] = _Variable(
            v.name, v.valueReference, size, _si_unit(unit, v.name, name), v.causality,
            start, v.description or "", abs(float(v.nominal or 1.0)) or 1.0,
        )  # fmt: skip
    return out


def _identifier(name: str) -> str:
    return re.sub(r"\W+", "_", name).strip("_") or "u"


def _si_unit(unit: str, variable: str, name: str) -> str:
    from fuzzyservo.units import parse_unit

    try:
        parse_unit(unit)
    except ValueError:
        raise FmuPlantError(
            f"{name}: variable {variable} has unit {unit!r}, which fuzzyservo does not read; "
            "export it with an SI unit (e.g. m, Pa, m3/s)"
        ) from None
    return unit


def _states(md: Any) -> list[str]:
    """The continuous states, in the order of the model description's derivatives."""
    return [d.variable.derivative.name for d in md.derivatives if d.variable.derivative is not None]


def _slots(parameters: list[_Variable]) -> list[tuple[str, str, _Variable, int]]:
    """(field name, file key, variable, element) of each real parameter value: a scalar as
    its name, an array element as ``name[i]`` (1-based, flattened row by row)."""
    taken = {f.name for f in dataclasses.fields(EffectParams)}
    out = []
    for v in parameters:
        for i in range(v.size):
            key = v.name if v.size == 1 else f"{v.name}[{i + 1}]"
            field = re.sub(r"\W+", "_", key).strip("_") or "parameter"
            if not field.isidentifier() or field in taken:
                field = f"fmu_{field}"
            while field in taken:
                field += "_"
            taken.add(field)
            out.append((field, key, v, i))
    return out


def _params_class(
    file: str, slots: list[tuple[str, str, _Variable, int]], recipe: tuple[Any, ...]
) -> type:
    """The plant's parameters: the FMU's real parameter values (their start values the
    defaults) after the loop-stage effects' fields. Pickled as the plant's ``recipe`` and
    the values, so a worker process makes the class again."""
    fields = [
        (
            field,
            float,
            quantity(
                key,
                v.unit,
                default=v.start[i] if i < len(v.start) else 0.0,
                doc=v.description or f"FMU parameter {v.name}",
            ),
        )
        for field, key, v, i in slots
    ]
    cls = dataclasses.make_dataclass(
        "FmuParams",
        fields,
        bases=(EffectParams,),
        frozen=True,
        namespace={
            "__doc__": f"Parameters of the FMU plant {Path(file).name} (its units).",
            "__reduce__": lambda self: (
                _fmu_params,
                (recipe, {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}),
            ),
        },
    )
    cls.__module__ = __name__
    cls.__qualname__ = f"FmuParams[{Path(file).name}]"
    return cls


def _fmu_params(recipe: tuple[Any, ...], values: dict[str, Any]) -> Any:
    """Parameters of the FMU plant ``recipe`` (``_fmu_plant``'s arguments) with ``values``."""
    return _fmu_plant(*recipe).params_cls(**values)


def _read_layout(reads: list[tuple[str, _Variable, int]]) -> tuple[list[int], int, list[int]]:
    """How the values ``reads`` names are read at once: the value references (sorted, each
    once), how many numbers they hold (arrays whole), and where each read's value is."""
    read_vrs = sorted({var.vr for _, var, _ in reads})
    sizes = {var.vr: var.size for _, var, _ in reads}
    where = {}  # (vr, index) -> position in the values read
    offset = 0
    for vr in read_vrs:
        for i in range(sizes[vr]):
            where[(vr, i)] = offset + i
        offset += sizes[vr]
    return read_vrs, offset, [where[(var.vr, index)] for _, var, index in reads]


def _binding(
    nx: int,
    inputs: list[_Variable],
    starts: list[float],
    at: list[int],
    reads: list[tuple[str, _Variable, int]],
    stepped: bool = False,
) -> str:
    """The plant slots of the closed loop for an FMU: calls through the handle block. It
    names no file, model or FMI version, so FMUs of the same layout (2.0 and 3.0 exports
    of one model) share one compiled loop."""
    read_vrs, offset, picks = _read_layout(reads)
    tables = f"""
_NX = {nx}
_VR_IN = np.array({[v.vr for v in inputs]!r}, dtype=np.uint32)
_INPUTS = np.array({starts!r}, dtype=np.float64)
_AT = np.array({at!r}, dtype=np.int64)
_VR_OUT = np.array({read_vrs!r}, dtype=np.uint32)
_N_OUT = {offset}
_PICK = np.array({picks!r}, dtype=np.int64)
"""
    if stepped:
        return _STEPPED.format(module=__name__, tables=tables)
    return f"""
# generated by {__name__} for a model-exchange FMU
import numpy as np

from fuzzyservo._jit import njit
from fuzzyservo.plants._fmi_calls import H_GET_REAL, derivatives, reals, set_point
{tables}

@njit(cache=True)
def plant_rhs(x, u, f_ext, p, dx):
    status = set_point(p, x, _NX, _VR_IN, _INPUTS, _AT, u, f_ext)
    status = max(status, derivatives(p, dx, _NX))
    if status > 1:  # error or discard: the loop sees a diverged step
        dx[:_NX] = np.nan


@njit(cache=True)
def plant_signals(x, u, f_ext, p, out):
    status = set_point(p, x, _NX, _VR_IN, _INPUTS, _AT, u, f_ext)
    values = np.empty(_N_OUT)
    status = max(status, reals(p, H_GET_REAL, _VR_OUT, values, _N_OUT))
    for k in range(_PICK.size):
        out[k] = values[_PICK[k]] if status <= 1 else np.nan


@njit(cache=True)
def plant_in_end_stop(x, p):
    return False
"""


class _Pool:
    """Initialised instances of one FMU, one per parameter set (the last :data:`_INSTANCES`
    used): model exchange in continuous-time mode at t = 0; co-simulation ready to step
    from t = 0, and initialised again for every run (:meth:`handles`)."""

    def __init__(
        self,
        file: str,
        md: Any,
        unzipped: str,
        version: int,
        nx: int,
        params: list[_Variable],
        slots: list[tuple[str, str, _Variable, int]],
        stepped: bool = False,
        reads: list[tuple[str, _Variable, int]] | None = None,
    ) -> None:
        self.file, self.md, self.unzipped, self.version, self.nx = file, md, unzipped, version, nx
        self.params, self.slots, self.stepped, self.reads = params, slots, stepped, reads or []
        self.instances: OrderedDict[tuple[float, ...], tuple[Any, np.ndarray]] = OrderedDict()

    def _get(self, params: Any) -> tuple[tuple[float, ...], Any, np.ndarray]:
        key = tuple(float(getattr(params, field)) for field, *_ in self.slots)
        if key in self.instances:
            self.instances.move_to_end(key)
            return key, *self.instances[key]
        fmu = self._new()
        x0 = self._initialise(fmu, key)
        self.instances[key] = (fmu, x0)
        if len(self.instances) > _INSTANCES:
            _, (old, _) = self.instances.popitem(last=False)
            old.terminate()
            old.freeInstance()
        return key, fmu, x0

    def _new(self) -> Any:
        from fmpy.fmi2 import FMU2Model, FMU2Slave
        from fmpy.fmi3 import FMU3Model, FMU3Slave

        kinds = {(2, False): FMU2Model, (3, False): FMU3Model, (2, True): FMU2Slave,
                 (3, True): FMU3Slave}  # fmt: skip
        interface = self.md.coSimulation if self.stepped else self.md.modelExchange
        fmu = kinds[(self.version, self.stepped)](
            guid=self.md.guid,
            unzipDirectory=self.unzipped,
            modelIdentifier=interface.modelIdentifier,
            instanceName=f"plant{len(self.instances)}",
        )
        fmu.instantiate()
        return fmu

    def _initialise(self, fmu: Any, key: tuple[float, ...]) -> np.ndarray:
        """Parameters set, initialisation done: the states (model exchange) or the values
        read (co-simulation) at t = 0."""
        arrays = {v.vr: list(v.start) + [0.0] * (v.size - len(v.start)) for v in self.params}
        for (_, _, v, i), value in zip(self.slots, key, strict=True):
            arrays[v.vr][i] = value
        vrs = list(arrays)
        values = [x for vr in vrs for x in arrays[vr]]
        try:
            if self.version == 2:
                fmu.setupExperiment(startTime=0.0)
                if vrs:
                    fmu.setReal(vrs, values)
                fmu.enterInitializationMode()
                fmu.exitInitializationMode()
                while not self.stepped and fmu.newDiscreteStates()[0]:
                    pass
            else:
                if vrs:
                    fmu.setFloat64(vrs, values)
                fmu.enterInitializationMode(startTime=0.0)
                fmu.exitInitializationMode()
                while not self.stepped and fmu.updateDiscreteStates()[0]:
                    pass
            if self.stepped:
                vrs_out, n_out, picks = _read_layout(self.reads)
                got = (fmu.getReal(vrs_out) if self.version == 2
                       else fmu.getFloat64(vrs_out, nValues=n_out))  # fmt: skip
                return np.array([got[k] for k in picks], dtype=float)
            fmu.enterContinuousTimeMode()
            x0 = np.zeros(self.nx)
            if self.nx:
                fmu.getContinuousStates(x0.ctypes.data_as(ctypes.POINTER(ctypes.c_double)), self.nx)
        except Exception as exc:  # FMPy raises FMICallException for a failed call
            raise FmuPlantError(
                f"{Path(self.file).name}: the FMU failed to initialise ({exc}); check the "
                "parameters the rig sets"
            ) from None
        return x0

    def initial_state(self, params: Any) -> np.ndarray:
        """The FMU's continuous states (co-simulation: the values read) after
        initialisation with ``params``."""
        return self._get(params)[2].copy()

    def handles(self, params: Any) -> np.ndarray:
        """The handle block :mod:`~fuzzyservo.plants._fmi_calls` reads at the end of ``p``:
        the instance initialised with ``params``, the addresses of its C functions and
        the time 0. A co-simulation instance is reset and initialised again: a run
        steps it from t = 0."""
        key, fmu, _ = self._get(params)
        if self.stepped:
            fmu.reset()
            self._initialise(fmu, key)
        functions = (FUNCTIONS_CS if self.stepped else FUNCTIONS)[self.version]
        addresses = [self.version, fmu.component] + [
            ctypes.cast(getattr(fmu.dll, f), ctypes.c_void_p).value for f in functions
        ]
        block = np.array([*addresses, 0.0], dtype=np.float64)
        assert block.size == HANDLES and all(
            int(b) == a for b, a in zip(block[:-1], addresses, strict=True)
        )
        return block


# The plant slots of a co-simulation FMU: the loop's states are the values it reads after
# each step, which plant_advance makes (the right-hand side is never integrated).
_STEPPED = """
# generated by {module} for a co-simulation FMU
import numpy as np

from fuzzyservo._jit import njit
from fuzzyservo.plants._fmi_calls import H_GET_REAL, do_step, reals, set_inputs
{tables}

@njit(cache=True)
def plant_advance(x, u, f_ext, p, duration):
    status = set_inputs(p, _VR_IN, _INPUTS, _AT, u, f_ext)
    status = max(status, do_step(p, duration))
    values = np.empty(_N_OUT)
    status = max(status, reals(p, H_GET_REAL, _VR_OUT, values, _N_OUT))
    for k in range(_PICK.size):
        x[k] = values[_PICK[k]] if status <= 1 else np.nan
    return 1 if status <= 1 else 0


@njit(cache=True)
def plant_rhs(x, u, f_ext, p, dx):
    for k in range(_PICK.size):
        dx[k] = 0.0


@njit(cache=True)
def plant_signals(x, u, f_ext, p, out):
    for k in range(_PICK.size):
        out[k] = x[k]


@njit(cache=True)
def plant_in_end_stop(x, p):
    return False
"""
