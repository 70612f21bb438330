"""The result of a closed-loop run: every signal, the command, the saturation flag, a status."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class SimResult:
    """Sampled record of a closed-loop run (one row per control sample).

    All arrays have the length of ``t``. Plant signals are SI (units in ``units``).
    ``reference`` and ``feedback`` are in the rig's feedback unit (V), ``command`` is
    the controller output (V), ``actuator`` the plant input after the actuator
    (e.g. valve current [A]), ``saturated`` true where the actuator sits at a limit.
    ``measured`` is the feedback as the controller saw it (sensor noise and ADC
    quantisation; ``feedback`` is the true reading). ``reference_output`` is the reference mapped to the judged output's unit through
    the feedback sensor, so ``output`` and ``reference_output`` compare directly.

    ``status``: ``ok``; ``end_stop`` (the run finished but the piston hit a stop);
    ``cavitation`` (the run finished but a chamber pressure fell below the oil's vapour
    pressure, which the model does not describe: simulation/validity.py);
    ``diverged`` or ``step_failure`` (the run stopped; samples after ``message``'s
    time are NaN).

    ``end_stop_s``: when the piston first sat beyond an end stop (None if it never did);
    kept when a later check (cavitation) sets ``status``. ``resolution``: the smallest
    change of ``output`` the feedback sensor resolves (its ADC step, else its noise;
    0 when it declares neither or senses another signal), ``resolution_source`` says
    which (:attr:`fuzzyservo.rig.LinearSensor.resolution`); the step metrics are not
    computed on motion below it.
    """

    rig: str
    scenario: str
    controller: str
    t: np.ndarray
    reference: np.ndarray
    reference_output: np.ndarray
    feedback: np.ndarray
    output: np.ndarray
    command: np.ndarray
    actuator: np.ndarray
    saturated: np.ndarray
    signals: dict[str, np.ndarray]
    units: dict[str, str]
    output_name: str
    actuator_name: str
    actuator_limits: tuple[float, float]
    sample_time_s: float
    warmup_s: float = 0.0
    status: str = "ok"
    message: str = ""
    integration_steps: int = 0
    display_units: dict[str, str] = field(default_factory=dict)
    actuator_unit: str = ""  # SI unit of the plant input (``actuator``)
    measured: np.ndarray | None = None
    end_stop_s: float | None = None
    resolution: float = 0.0
    resolution_source: str = ""

    @property
    def ok(self) -> bool:
        """True when the run completed (``ok``, ``end_stop`` or ``cavitation``); only
        ``ok`` is a physically valid run."""
        return self.status in ("ok", "end_stop", "cavitation")

    @property
    def output_unit(self) -> str:
        return self.units[self.output_name]

    def columns(self) -> dict[str, np.ndarray]:
        """Every sampled signal by a column name that carries its unit (``t_s``,
        ``ref_V``, ``p3_Pa``, ...): the CSV a run is written to."""
        act = f"{self.actuator_name}_{self.units.get(self.actuator_name, 'SI')}"
        cols = {"t_s": self.t, "ref_V": self.reference, "feedback_V": self.feedback,
                "u_V": self.command, act: self.actuator,
                "saturated": self.saturated.astype(float)}  # fmt: skip
        for name, values in self.signals.items():
            unit = self.units[name].replace("/", "_").replace("^", "").replace("*", "")
            cols[f"{name}_{unit}"] = values
        return cols

    def signal(self, name: str) -> np.ndarray:
        """A plant signal, or one of reference/feedback/command/actuator/output."""
        extra = {
            "reference": self.reference,
            "reference_output": self.reference_output,
            "feedback": self.feedback,
            "measured": self.feedback if self.measured is None else self.measured,
            "command": self.command,
            "actuator": self.actuator,
            "output": self.output,
        }
        if name in extra:
            return extra[name]
        return self.signals[name]
