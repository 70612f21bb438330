"""Replay a measured run on a rig model: the same input, the data's initial state, the
model's channels on the data's time grid.

Closed loop (a controller is given): the recorded reference ``ref`` drives the
controller at the rig's sample time. Open loop: the recorded valve current ``i`` (or
command ``u``) is applied through the actuator, held between samples at the data's
sample period. The initial state takes every state the data shows at its first sample
(position, pressures, speed); the rest comes from the rig file.

With controller gains declared unknown and the controller's output ``u`` [V] in the
record, the gains are fitted on it first (calibration/gains.py) and then held; a ``feedback`` column (in the feedback sensor's unit) says what the
controller read, else the recorded ``y`` through the feedback sensor. A recorded ``load`` (a force on a cylinder, a torque on a motor, in the plant's load
unit) is applied as the scenario's load in both modes. A recorded ``force`` is compared
with the loads' force on the actuator (``f_loads``, what a load cell between rod and
load reads); ``f_hyd`` with the hydraulic force p_A·A_A − p_B·A_B.

The record is split in time: the first 70 % trains (parameters are fitted on it), the
last 30 % is held out (fit % is reported on it), as MATLAB's System Identification
Toolbox users split estimation and validation data. A channel whose held-out part does
not move (peak to peak within its noise level) has no fit % (it divides by that
spread): :meth:`Scored.still_channels`; a record with no channel that moves there is
refused (calibration/run.py).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from types import MappingProxyType

import numpy as np

from fuzzyservo.calibration.gains import fit_from_log
from fuzzyservo.calibration.residuals import noise_floor
from fuzzyservo.controllers.base import Controller
from fuzzyservo.controllers.classical import OpenLoop
from fuzzyservo.display import display_scale
from fuzzyservo.errors import DataError
from fuzzyservo.measured import Measured
from fuzzyservo.rig import Rig, Scenario
from fuzzyservo.signals import Sampled
from fuzzyservo.simulation import DEFAULT_TOL, Resets, simulate
from fuzzyservo.simulation.closed_loop import NO_RESETS
from fuzzyservo.simulation.result import SimResult

VALIDATION_FRACTION = 0.3
INPUT_SIGNALS = ("t", "ref", "u", "i", "load")  # what drives a replay; never a compared channel
ALIASES = {"force": "f_loads"}  # data signal -> the model signal it is compared with
DIVERGED_COST = 1e12  # cost of a run that failed (noise-variance units)


class Scored:
    """Costs of model channels against measured ones, shared by a replay of one record
    and of several (joint.py). Needs ``channels``, ``measured``, ``sigma`` and ``split``
    (first held-out sample)."""

    per_record: Mapping[str, tuple[float, float]] = MappingProxyType({})  # joint.py
    values: Mapping[str, tuple[float, ...]] = MappingProxyType({})

    def costs(self, model: dict[str, np.ndarray]) -> tuple[float, float]:
        """:meth:`cost` on (training, held-out)."""
        return self.cost(model, slice(0, self.split)), self.cost(model, slice(self.split, None))

    def cost(self, model: dict[str, np.ndarray], part: slice) -> float:
        """Mean squared residual in units of each channel's noise variance, averaged over
        channels: the maximum-likelihood criterion for white Gaussian measurement noise,
        so a channel weighs by how precisely it was measured. A perfect model scores 1."""
        total = 0.0
        for channel in self.channels:
            e = (self.measured(channel)[part] - model[channel][part]) / self.sigma[channel]
            if not np.isfinite(e).all():
                return DIVERGED_COST
            total += float(e @ e) / e.size
        return total / len(self.channels)

    def residual_vector(self, model: dict[str, np.ndarray]) -> np.ndarray:
        """Training residuals scaled so that their sum of squares is the training cost."""
        part = slice(0, self.split)
        parts = []
        for channel in self.channels:
            e = self.measured(channel)[part] - model[channel][part]
            e = e / (self.sigma[channel] * np.sqrt(e.size * len(self.channels)))
            parts.append(np.where(np.isfinite(e), e, np.sqrt(DIVERGED_COST / e.size)))
        return np.concatenate(parts)

    def noise_cost(self) -> float:
        """The cost a perfect model leaves: 1 (white noise of the estimated level)."""
        return 1.0

    def still_channels(self) -> dict[str, float]:
        """The channels whose held-out part does not move, with their peak-to-peak there:
        constant, or within the channel's noise level ``sigma`` (what its sensor
        resolves). Their fit % (``‖y − ȳ‖`` in the denominator) is undefined."""
        out = {}
        for channel in self.channels:
            held = np.asarray(self.measured(channel)[self.split :], dtype=float)
            held = held[np.isfinite(held)]
            spread = float(np.ptp(held)) if held.size else 0.0
            if spread == 0.0 or spread <= self.sigma[channel]:
                out[channel] = spread
        return out

    def sources(self) -> str:
        """The data files, as the messages name them."""
        records = getattr(self, "records", (self,))
        return ", ".join(str(r.data.source) for r in records)

    def held_out_words(self) -> str:
        """Where the held-out part is, in words (``the last 30 %, from t = 2.8 s``)."""
        share = f"{100 * VALIDATION_FRACTION:g} %"
        records = getattr(self, "records", (self,))
        if len(records) > 1:
            return f"each record's last {share}"
        return f"the last {share}, from t = {self.split_s:.4g} s"

    def still_words(self, still: Mapping[str, float]) -> str:
        """``y (0 mm peak to peak, noise level 0.005 mm), ...`` for ``still`` channels."""
        parts = []
        for channel, spread in still.items():
            unit, k = display_scale(self.data.units[channel])
            parts.append(
                f"{channel} ({k * spread:.3g} {unit} peak to peak, "
                f"noise level {k * self.sigma[channel]:.3g} {unit})"
            )
        return ", ".join(parts)


@dataclass(frozen=True, eq=False)
class Replay(Scored):
    """A measured run ready to be replayed on variants of one rig.

    ``channels``: data signal -> model signal compared; ``drive``: the data signal that
    drives the run (``ref``, ``i`` or ``u``); ``split``: first held-out sample.
    """

    data: Measured
    controller: Controller
    scenario: Scenario
    sample_time_s: float
    channels: dict[str, str]
    drive: str
    mode: str
    split: int
    # gains fitted on the logged command u: gain -> (value, lower, upper); its fit %
    logged_gains: dict[str, tuple[float, float, float]] = field(default_factory=dict)
    logged_fit: float = float("nan")
    # a segmented replay (calibration/segments.py): the states set from the record at
    # each segment's start, the segments' length and the words that say so
    resets: Resets = NO_RESETS
    segment_s: float = float("nan")
    segment_words: str = ""

    @property
    def t(self) -> np.ndarray:
        """Data time from the first sample [s]."""
        return self.data.t - self.data.t[0]

    @property
    def split_s(self) -> float:
        return float(self.t[self.split])

    def measured(self, channel: str) -> np.ndarray:
        return self.data.signals[channel]

    def simulate(
        self,
        rig: Rig,
        controller: Controller | None = None,
        duration_s: float | None = None,
        *,
        tol: float = DEFAULT_TOL,
    ) -> SimResult:
        """The replayed run on ``rig``: the data's input, sample time and initial state;
        through ``controller`` (e.g. with fitted gains) instead of the replay's own;
        integrated at ``tol`` (:func:`~fuzzyservo.simulation.closed_loop.simulate`)."""
        replay_rig = dataclasses.replace(rig, sample_time_s=self.sample_time_s, initial={})
        return simulate(replay_rig, controller or self.controller, self.scenario,
                        duration_s=duration_s, tol=tol, resets=self.resets)  # fmt: skip

    @cached_property
    def training_s(self) -> float:
        """How far a replay must run to cover the training part [s]: the last training
        sample and one controller period past it."""
        end = float(self.t[self.split - 1]) + 2.0 * self.sample_time_s
        return min(end, self.scenario.duration_s)

    def run(
        self,
        rig: Rig,
        controller: Controller | None = None,
        *,
        training: bool = False,
        tol: float = DEFAULT_TOL,
    ) -> tuple[dict[str, np.ndarray], str]:
        """Model channels on the data grid (NaN where the run failed) and the run's status.
        ``training``: run only as far as the training part (fits look at nothing else);
        the held-out samples are then NaN. ``tol``: the integration tolerance."""
        result = self.simulate(rig, controller, self.training_s if training else None, tol=tol)
        t = self.t[: self.split] if training else self.t
        out = {}
        for channel, signal in self.channels.items():
            values = result.signal(signal)
            full = np.full(self.t.size, np.nan)
            if np.isfinite(values).all():
                full[: t.size] = np.interp(t, result.t, values)
            out[channel] = full
        return out, result.status

    @cached_property
    def sigma(self) -> dict[str, float]:
        """Noise level of each channel, estimated from the data (residuals.noise_floor)."""
        sigma = {}
        for channel in self.channels:
            y = self.measured(channel)
            # quantised or noise-free data: never weigh a channel infinitely
            sigma[channel] = max(noise_floor(y), 1e-6 * float(np.std(y)), 1e-300)
        return sigma

    def recorded(self, name: str) -> np.ndarray:
        """A recorded signal (an input too) on the data grid."""
        return np.asarray(self.data.signals[name], dtype=float)

    def with_controller(self, controller: Controller) -> Replay:
        """This replay through ``controller`` (e.g. with fitted gains)."""
        return dataclasses.replace(self, controller=controller)

    def with_values(self, fitted: Mapping[str, float]) -> Replay:
        """A single record has no per-record values (joint.py): itself."""
        return self

    def whole(self) -> Replay:
        """This replay run through from the record's start, never restarted: what the
        overlays and the fit % show (a segmented one's is calibration/segments.py's)."""
        if not len(self.resets.at):
            return self
        return dataclasses.replace(self, resets=NO_RESETS, segment_s=float("nan"),
                                   segment_words="")  # fmt: skip


def make_replay(rig: Rig, data: Measured, controller: Controller | None = None) -> Replay:
    """A replay of ``data`` on ``rig``: closed loop through ``controller``, else open loop."""
    from fuzzyservo.calibration.plausibility import check_against_rig

    plant = rig.plant
    channels = _channels(rig, data)
    check_against_rig(rig, data, channels)
    if not channels:
        raise DataError(
            f"{data.source}: no signal the model computes (the data has {sorted(data.signals)}; "
            f"the model gives y, {', '.join(plant.signals)}); name the measured output column y_<unit>"
        )
    t = data.t - data.t[0]
    if controller is not None:
        if "ref" not in data.signals:
            raise DataError(
                f"{data.source}: a closed-loop replay needs the reference column ref_<unit>; "
                "add it, or leave out --controller to replay open loop from i or u"
            )
        reference = _reference_volts(rig, data)
        sample_time = rig.sample_time_s
        drive, mode = "ref", f"closed loop through {controller.name}"
    else:
        drive = "i" if "i" in data.signals else "u" if "u" in data.signals else ""
        if not drive:
            raise DataError(
                f"{data.source}: an open-loop replay needs the valve current i_<unit> or the "
                "command u_V; add one, or give --controller and a ref_<unit> column"
            )
        values = data.signals[drive]
        if drive == "i":
            reference = values / rig.actuator.gain  # back to command volts
        else:
            reference = np.asarray(values, dtype=float)
        controller = OpenLoop(gain=1.0, name="recorded input")
        sample_time = data.sample_period_s
        mode = f"open loop from the recorded {drive}"
    controller = controller.with_limits(*rig.actuator.command_limits)
    split = round((1.0 - VALIDATION_FRACTION) * t.size)
    logged: dict[str, tuple[float, float, float]] = {}
    logged_fit = float("nan")
    if drive == "ref" and controller.gain_bounds() and _logs_controller(rig, data, sample_time):
        # the logged command pins the unknown gains; the output alone sees only their
        # product with the plant's flow gain
        controller, logged, logged_fit = fit_from_log(
            controller,
            np.asarray(reference, dtype=float),
            _reading(rig, data),
            np.asarray(data.signals["u"], dtype=float),
            sample_time,
            split,
        )
        mode += f" (gains fitted on the logged u: {logged_fit:.1f} % held-out fit)"
    n = round((t[-1] + data.sample_period_s) / sample_time)
    extra = {}
    if "load" in data.signals:
        extra["load"] = Sampled(times_s=t, values=_load(rig, data))
    scenario = Scenario(
        name="replay",
        duration_s=n * sample_time,
        reference=Sampled(times_s=t, values=np.asarray(reference, dtype=float)),
        **extra,
        initial=_initial(rig, data, channels),
        description=f"replay of {data.source}",
        noise=False,  # the data carry the rig's own noise; the model replays noise-free
    )
    return Replay(
        data=data,
        controller=controller,
        scenario=scenario,
        sample_time_s=sample_time,
        channels=channels,
        drive=drive,
        mode=mode,
        split=split,
        logged_gains=logged,
        logged_fit=logged_fit,
    )


def _logs_controller(rig: Rig, data: Measured, sample_time_s: float) -> bool:
    """The record holds the controller's output ``u`` [V] and the measurement it read
    (a ``feedback`` column in the feedback unit, or the sensed output ``y``), one sample
    per controller period."""
    reads = data.units.get("feedback") == rig.feedback.unit or (
        "y" in data.signals and rig.feedback.signal == rig.output
    )
    return (
        data.units.get("u") == "V"
        and reads
        and abs(data.sample_period_s - sample_time_s) <= 1e-3 * sample_time_s
    )


def _reading(rig: Rig, data: Measured) -> np.ndarray:
    """What the controller read: the recorded ``feedback`` (e.g. a load cell's normalised
    force), else the recorded output through the feedback sensor."""
    if data.units.get("feedback") == rig.feedback.unit:
        return np.asarray(data.signals["feedback"], dtype=float)
    return np.asarray(rig.feedback.read(data.signals["y"]), dtype=float)


def _channels(rig: Rig, data: Measured) -> dict[str, str]:
    """Data signal -> model signal: ``y`` is the rig's output, others match by name."""
    plant = rig.plant
    out = {}
    for name, unit in data.units.items():
        if name in INPUT_SIGNALS:
            continue
        signal = rig.output if name == "y" else name
        alias = ALIASES.get(name)
        if alias in plant.signals and unit == plant.signal_units[alias]:
            signal = alias  # a normalised force (unit 1) is not compared with one in N
        if signal not in plant.signals:
            continue
        if unit != plant.signal_units[signal]:
            raise DataError(
                f"{data.source}: column {name!r} is in {unit} but the model's {signal} is in "
                f"{plant.signal_units[signal]}; rename the column with a unit of that kind"
            )
        out[name] = signal
    return out


def _reference_volts(rig: Rig, data: Measured) -> np.ndarray:
    """The recorded reference in the feedback unit: volts as recorded, or through the sensor."""
    fb = rig.feedback
    ref = np.asarray(data.signals["ref"], dtype=float)
    unit = data.units["ref"]
    if unit == "V" or unit == fb.unit:  # as the controller reads it (V, or e.g. a force in 1)
        return ref
    if unit == rig.plant.signal_units[fb.signal]:
        return np.asarray(fb.read(ref))
    raise DataError(
        f"{data.source}: column 'ref' is in {unit}; give it in {fb.unit} (the feedback reading) "
        f"or in {rig.plant.signal_units[fb.signal]} (the sensed {fb.signal})"
    )


def _load(rig: Rig, data: Measured) -> np.ndarray:
    """The recorded load force (or torque) in the plant's load unit, SI."""
    name, si_unit = rig.plant.load
    unit = data.units["load"]
    if unit != si_unit:
        raise DataError(
            f"{data.source}: column 'load' is in {unit} but the plant's load ({name}) is in "
            f"{si_unit}; give it in {si_unit} (measured: columns can scale it, e.g. "
            "{as: load_N, from: tf})"
        )
    return np.asarray(data.signals["load"], dtype=float)


def _initial(rig: Rig, data: Measured, channels: dict[str, str]) -> dict[str, float]:
    """The initial state the data shows: first samples of every channel that is a state."""
    initial = dict(rig.initial)
    for channel, signal in channels.items():
        for kw, _unit in rig.plant.initial_keys.values():
            if kw.startswith(signal + "_"):
                initial[kw] = float(data.signals[channel][0])
                if signal.startswith("p") and signal[1:].isdigit():
                    # a measured chamber pressure replaces the chamber mass the rig gives
                    initial.pop(f"m{signal[1:]}_kg", None)
    return initial
