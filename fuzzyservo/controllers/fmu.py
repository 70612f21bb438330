"""A controller from outside: a co-simulation FMU (FMI 2.0 or 3.0) run through FMPy.

The FMU is stepped at the loop's sample rate: at sample k the reference and the
measurement are set on its inputs, ``doStep(t_k, T_s)`` is called and its command
output read, which the loop then limits and holds like any controller's command. It is
not compiled into the loop: :func:`fuzzyservo.simulation.simulate` runs such a
controller sample by sample in Python around the compiled plant integrator.

An FMU that declares a parameter ``sample_period`` (as ``fuzzyservo export --fmu``
writes) gets the loop's sample time there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from fuzzyservo._jit import njit
from fuzzyservo.controllers.base import Controller
from fuzzyservo.controllers.kinds import KIND_FMU
from fuzzyservo.errors import require

__all__ = ["FmuController", "FmuSession"]


@njit(cache=True)
def _not_compiled(cp: np.ndarray, cs: np.ndarray, r: float, y: float) -> float:
    """An FMU has no compiled kernel: NaN (the stepped loop calls the FMU instead)."""
    return np.nan


@dataclass(frozen=True)
class FmuController(Controller):
    """A co-simulation FMU ``file`` whose inputs ``reference`` and ``measurement`` and
    output ``command`` (variable names) make a controller; ``sample_time_s`` its sample
    period (None: whatever the loop's is), output limits [V] applied after it."""

    file: str
    reference: str = "reference"
    measurement: str = "measurement"
    command: str = "command"
    sample_time_s: float | None = None
    u_min: float = -np.inf
    u_max: float = np.inf
    name: str = "fmu"
    description: str = field(default="", compare=False)

    kind = KIND_FMU
    kernel = staticmethod(_not_compiled)
    #: not compiled into the loop: simulate runs it sample by sample
    stepped: ClassVar[bool] = True

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.sample_time_s is not None and not (
            math.isfinite(self.sample_time_s) and self.sample_time_s > 0
        ):
            raise ValueError(f"sample_time_s must be > 0 s, got {self.sample_time_s}")

    def pack(self, sample_time_s: float) -> tuple[np.ndarray, np.ndarray]:
        return np.array([self.u_min, self.u_max]), np.zeros(1)

    def check_sample_time(self, sample_time_s: float) -> None:
        """ValueError unless the loop samples at the FMU's period."""
        if self.sample_time_s is not None and abs(self.sample_time_s - sample_time_s) > (
            1e-9 * sample_time_s
        ):
            raise ValueError(
                f"FMU controller {self.name!r} samples every {self.sample_time_s:g} s, the "
                f"loop every {sample_time_s:g} s; give the rig's sample time in the "
                "controller file (or none)"
            )

    def start(self, sample_time_s: float) -> FmuSession:
        """A fresh instance of the FMU, initialised at t = 0, stepped every ``sample_time_s``."""
        self.check_sample_time(sample_time_s)
        return FmuSession(self, sample_time_s)

    def init(self, sample_time_s: float) -> Any:  # type: ignore[override]
        """The state of :meth:`step`: a running FMU instance."""
        return self.start(sample_time_s)

    def step(self, state: Any, r: float, y: float) -> tuple[float, Any]:  # type: ignore[override]
        """One sample: the FMU's command for ``r`` and ``y``, limited; the state is the
        instance itself (stepped in place)."""
        return state.step(r, y), state


class FmuSession:
    """One instance of a controller FMU (FMPy), stepped sample by sample."""

    def __init__(self, controller: FmuController, sample_time_s: float):
        require("fmpy", "fmi", "an FMU controller (run through FMPy)")
        from fmpy import extract, read_model_description

        path = Path(controller.file)
        if not path.is_file():
            raise ValueError(f"FMU file {path} not found; check the controller's file: key")
        md = read_model_description(str(path))
        if md.coSimulation is None:
            raise ValueError(f"{path.name}: not a co-simulation FMU; export it for co-simulation")
        variables = {v.name: v for v in md.modelVariables}
        inputs = [v.name for v in md.modelVariables if v.causality == "input"]
        outputs = [v.name for v in md.modelVariables if v.causality == "output"]
        for role, wanted, allowed in (
            ("reference", controller.reference, inputs),
            ("measurement", controller.measurement, inputs),
            ("command", controller.command, outputs),
        ):
            if wanted not in allowed:
                kind = "input" if role != "command" else "output"
                raise ValueError(
                    f"{path.name}: {role} variable {wanted!r} is not an {kind} of the FMU "
                    f"(its {kind}s: {allowed}); map {role}: to one of them"
                )
        self.v3 = md.fmiVersion.startswith("3")
        self.dt = sample_time_s
        self.lo, self.hi = controller.u_min, controller.u_max
        self.inputs = [variables[controller.reference].valueReference,
                       variables[controller.measurement].valueReference]  # fmt: skip
        self.output = [variables[controller.command].valueReference]
        self._dir = extract(str(path))
        if self.v3:
            from fmpy.fmi3 import FMU3Slave as Slave
        else:
            from fmpy.fmi2 import FMU2Slave as Slave
        self.fmu = Slave(guid=md.guid, unzipDirectory=self._dir, instanceName=controller.name,
                         modelIdentifier=md.coSimulation.modelIdentifier)  # fmt: skip
        self.fmu.instantiate()
        self._set = self.fmu.setFloat64 if self.v3 else self.fmu.setReal
        self._get = self.fmu.getFloat64 if self.v3 else self.fmu.getReal
        if self.v3:
            self.fmu.enterInitializationMode(startTime=0.0)
        else:
            self.fmu.setupExperiment(startTime=0.0)
            self.fmu.enterInitializationMode()
        period = variables.get("sample_period")
        if period is not None and period.causality == "parameter":
            self._set([period.valueReference], [float(sample_time_s)])
        self.fmu.exitInitializationMode()
        self.k = 0

    def step(self, r: float, y: float) -> float:
        """Set the inputs, step the FMU over one sample, return its command (limited)."""
        self._set(self.inputs, [float(r), float(y)])
        self.fmu.doStep(self.k * self.dt, self.dt)
        self.k += 1
        u = float(self._get(self.output)[0])
        return min(max(u, self.lo), self.hi)

    def close(self) -> None:
        """Terminate and free the instance, and remove its extracted files."""
        import shutil

        self.fmu.terminate()
        self.fmu.freeInstance()
        shutil.rmtree(self._dir, ignore_errors=True)
