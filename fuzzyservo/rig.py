"""A rig: a plant with its parameters, sensors, actuator, sample time and scenarios.

Typed and frozen; :mod:`fuzzyservo.io.rigs` builds it from a rig file.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from fuzzyservo.components.effects import LIBRARY, Scales, fixed_defaults
from fuzzyservo.errors import ConfigError, did_you_mean
from fuzzyservo.params import check
from fuzzyservo.plants import PlantModel
from fuzzyservo.signals import Constant, Signal

if TYPE_CHECKING:
    from fuzzyservo.measured import ColumnScaling


@dataclass(frozen=True)
class LinearSensor:
    """``reading = offset + gain · signal / ratio`` [V] (e.g. seed 002 eq. 19:
    U_R = 5.75 V + 0.1936 V/cm · y; seed 000: 3.44 V/rad after the 7.5 gear).

    What the controller sees is :meth:`measure`: the reading plus white noise of
    standard deviation ``noise_std`` (in the reading's unit), quantised by an ADC of
    ``adc_bits`` over ``adc_lower .. adc_upper`` (step = range / 2^bits; 0 bits: none).
    """

    signal: str
    offset: float = 0.0
    gain: float = 1.0
    ratio: float = 1.0
    unit: str = "V"
    noise_std: float = 0.0
    adc_bits: int = 0
    adc_lower: float = 0.0
    adc_upper: float = 0.0

    def __post_init__(self) -> None:
        if self.gain == 0 or self.ratio == 0:
            raise ValueError(f"sensor on {self.signal!r}: gain and ratio must not be zero")
        if not self.noise_std >= 0:
            raise ValueError(f"sensor on {self.signal!r}: noise must be >= 0, got {self.noise_std}")
        if self.adc_bits and not (0 < self.adc_bits <= 32 and self.adc_lower < self.adc_upper):
            raise ValueError(
                f"sensor on {self.signal!r}: an ADC needs 1..32 bits and `lower < upper`, "
                f"but got (bits={self.adc_bits}, lower={self.adc_lower}, upper={self.adc_upper})"
            )

    @property
    def adc_step(self) -> float:
        """The ADC's quantisation step (range / 2^bits) [reading unit]; 0 without an ADC."""
        if not self.adc_bits:
            return 0.0
        return (self.adc_upper - self.adc_lower) / 2.0**self.adc_bits

    @property
    def resolution(self) -> tuple[float, str]:
        """The smallest change of the sensed signal this acquisition resolves [signal
        unit] and what sets it: the ADC's step, else the noise's standard deviation;
        ``(0.0, "")`` for a sensor that declares neither."""
        if self.adc_bits:
            where = f"{self.adc_bits} bits over {self.adc_lower:g}..{self.adc_upper:g} {self.unit}"
            return self.adc_step / abs(self.slope), f"the feedback ADC's step, {where}"
        if self.noise_std > 0:
            noise = f"{self.noise_std:g} {self.unit} rms"
            return self.noise_std / abs(self.slope), f"the feedback sensor's noise, {noise}"
        return 0.0, ""

    @property
    def slope(self) -> float:
        """Reading per unit of the sensed signal (gain / ratio)."""
        return self.gain / self.ratio

    def read(self, value: np.ndarray | float) -> np.ndarray | float:
        return self.offset + self.slope * value

    def invert(self, reading: np.ndarray | float) -> np.ndarray | float:
        return (reading - self.offset) / self.slope

    def measure(self, value: np.ndarray, noise: np.ndarray) -> np.ndarray:
        """What the acquisition delivers for ``value``: the reading plus ``noise``
        (already scaled, reading unit), quantised (:func:`~fuzzyservo.components.sensor.adc`)."""
        from fuzzyservo.components.sensor import adc

        reading = np.asarray(self.read(value), dtype=float) + noise
        return adc(reading, self.adc_lower, self.adc_upper, self.adc_step)


@dataclass(frozen=True)
class Actuator:
    """Command-to-plant-input stage: ``a = clip(gain·u, lower, upper)`` (seed 002: the
    voltage-current converter, 10 mA/V, ±30 mA)."""

    name: str
    gain: float
    lower: float
    upper: float
    unit: str

    def __post_init__(self) -> None:
        if self.gain == 0:
            raise ValueError(f"actuator {self.name!r}: gain must not be zero")
        if not self.lower < self.upper:
            raise ValueError(
                f"actuator {self.name!r}: `lower < upper` must hold, but got "
                f"(lower={self.lower}, upper={self.upper})"
            )

    @property
    def rated(self) -> float:
        """The largest plant input it can apply [A or V]."""
        return max(abs(self.lower), abs(self.upper))

    @property
    def command_limits(self) -> tuple[float, float]:
        """The command range [V] that maps onto the actuator limits."""
        a, b = self.lower / self.gain, self.upper / self.gain
        return (min(a, b), max(a, b))


@dataclass(frozen=True)
class Scenario:
    """A run to simulate: reference (feedback unit), load (plant load unit), duration.

    ``warmup_s``: metrics ignore what happens before (e.g. the move from the initial
    position to the first command level). ``overrides``: parameter values (SI, by field
    name) this scenario changes, e.g. a supply pressure. ``initial``: initial-state
    keywords of the plant. ``noise``: False runs it with noise-free sensors (their
    quantisation stays).
    """

    name: str
    duration_s: float
    reference: Signal
    load: Signal = field(default_factory=Constant)
    warmup_s: float = 0.0
    overrides: dict[str, float] = field(default_factory=dict)
    initial: dict[str, float] = field(default_factory=dict)
    description: str = ""
    noise: bool = True

    def __post_init__(self) -> None:
        if not self.duration_s > 0:
            raise ValueError(
                f"scenario {self.name!r}: duration must be > 0 s, got {self.duration_s}"
            )
        if not 0 <= self.warmup_s < self.duration_s:
            raise ValueError(
                f"scenario {self.name!r}: warmup must lie in [0, duration), got {self.warmup_s} s"
            )


@dataclass(frozen=True)
class MeasuredFormat:
    """How a rig's measured-data files are read (the rig file's ``measured:`` section).

    ``columns``: plain column name -> ``<signal>_<unit>`` (see :mod:`fuzzyservo.io.measured`);
    ``scaling``: plain column name -> how its raw numbers become the mapped unit;
    ``sample_period_s``: rebuild time as n·period (None: use the time column);
    ``resample``: average repeated stamps onto a uniform grid; ``skip_lines``: lines
    above the header (a DAQ's preamble); ``names``: the column names of a file without
    a header line; ``drop``: columns to leave out (dates, comments).
    """

    columns: dict[str, str] = field(default_factory=dict)
    sample_period_s: float | None = None
    resample: bool = False
    scaling: dict[str, ColumnScaling] = field(default_factory=dict)
    skip_lines: int = 0
    names: tuple[str, ...] = ()
    drop: tuple[str, ...] = ()


@dataclass(frozen=True)
class Rig:
    """A servo system ready to simulate.

    ``effects``: names of the effects (components/effects.py) the rig declares, their
    parameters live in ``params``. ``unknowns``: parameter field -> (lower, upper) SI
    bounds of values the rig file marks as unknown (``fit: [lo, hi]``), which
    calibration fits. ``measured``: how its data files are read. ``io_delay_s``: the
    loop's input-output latency (computation and conversion), from the sample of the
    feedback to the command reaching the actuator: the loop's ``io_delay`` stage, in
    series with the ``transport_delay`` effect (the stages: ``simulation/_loop.py``).
    """

    name: str
    plant: PlantModel
    params: Any
    feedback: LinearSensor
    actuator: Actuator
    sample_time_s: float
    output: str
    scenarios: dict[str, Scenario]
    initial: dict[str, float] = field(default_factory=dict)
    sensors: dict[str, LinearSensor] = field(default_factory=dict)
    display_units: dict[str, str] = field(default_factory=dict)
    title: str = ""
    source: str = ""
    path: str = ""
    effects: tuple[str, ...] = ()
    unknowns: dict[str, tuple[float, float]] = field(default_factory=dict)
    measured: MeasuredFormat | None = None
    io_delay_s: float = 0.0

    def __post_init__(self) -> None:
        if not self.sample_time_s > 0:
            raise ValueError(f"sample_time must be > 0 s, got {self.sample_time_s}")
        if not self.io_delay_s >= 0:
            raise ValueError(f"io_delay must be >= 0 s, got {self.io_delay_s}")
        if self.feedback.signal not in self.plant.states:
            raise ValueError(
                f"feedback signal {self.feedback.signal!r} is not a state of "
                f"{self.plant.type_name}; choose one of {list(self.plant.states)}"
            )
        for sensor in self.sensors.values():
            if sensor.signal not in self.plant.signals and sensor.signal not in self.plant.states:
                raise ValueError(
                    f"sensor signal {sensor.signal!r} is not a signal of {self.plant.type_name}; "
                    f"choose one of {list(self.plant.signals)}"
                )
        if self.output not in self.plant.signals:
            raise ValueError(
                f"output {self.output!r} is not a signal of {self.plant.type_name}; "
                f"choose one of {list(self.plant.signals)}"
            )

    def scenario(self, name: str | None = None) -> Scenario:
        """The named scenario (the first one when ``name`` is None)."""
        if name is None:
            return next(iter(self.scenarios.values()))
        if name not in self.scenarios:
            raise ConfigError(
                f"unknown scenario {name!r}; {did_you_mean(name, self.scenarios)}this rig has "
                f"{', '.join(self.scenarios)}",
                file=self.path or None,
                key="scenarios",
            )
        return self.scenarios[name]

    def params_for(self, scenario: Scenario) -> Any:
        """The plant parameters with the scenario's overrides applied (and re-checked)."""
        if not scenario.overrides:
            return self.params
        new = dataclasses.replace(self.params, **scenario.overrides)
        check(new)
        return new

    def with_params(self, **changes: float) -> Rig:
        """A copy with plant parameters changed (by field name, SI)."""
        new = dataclasses.replace(self.params, **changes)
        check(new)
        return dataclasses.replace(self, params=new)

    def scales(self) -> Scales:
        """Sizes of this rig that effect bounds scale with (components/effects.py)."""
        return self.plant.scales(self.params, self.actuator.rated, self.sample_time_s)

    def with_effect(self, name: str, **values: float) -> Rig:
        """A copy with effect ``name`` declared: ``values`` by parameter key (SI); fixed
        parameters not given take their library default."""
        if name not in LIBRARY:
            raise KeyError(
                f"unknown effect {name!r}; {did_you_mean(name, LIBRARY)}choose one of {sorted(LIBRARY)}"
            )
        refusal = self.plant.refusal(name)
        if refusal:
            raise ValueError(refusal)
        effect = LIBRARY[name]
        changes = fixed_defaults(name, self.params, self.scales(), values)
        changes.update({p.field: float(values[p.key]) for p in effect.params if p.key in values})
        unknown = set(values) - {p.key for p in effect.params}
        if unknown:
            raise KeyError(
                f"effect {name!r} has no parameter {sorted(unknown)[0]!r}; "
                f"it has {[p.key for p in effect.params]}"
            )
        rig = self.with_params(**changes)
        effects = self.effects if name in self.effects else (*self.effects, name)
        return dataclasses.replace(rig, effects=effects)

    def effect_values(self, name: str) -> dict[str, float]:
        """The declared parameters of effect ``name`` by key (SI)."""
        return {p.key: float(getattr(self.params, p.field)) for p in LIBRARY[name].params}


def compose_rig(
    name: str,
    components: dict[str, tuple[str, dict[str, float]] | tuple[str, dict[str, float], str]],
    *,
    feedback: LinearSensor,
    actuator: Actuator,
    sample_time_s: float,
    scenarios: dict[str, Scenario] | list[Scenario],
    output: str = "y",
    initial: dict[str, float] | None = None,
    sensors: dict[str, LinearSensor] | None = None,
    title: str = "",
    io_delay_s: float = 0.0,
) -> Rig:
    """A rig composed in code, as a rig file's ``plant.components`` does.

    ``components``: instance name -> (component type, parameter values by key, SI), and
    optionally its axis (a circuit of several actuators on one supply: each valve, line,
    actuator and load names its axis); the types are those of
    ``fuzzyservo/components/library`` (:func:`component_types`).
    ``initial``: initial-state keys (``position``, ``pressure_a``, ...) in SI;
    ``io_delay_s`` the loop's I/O delay (a rig file's ``controller.io_delay``). Raises
    ``ValueError`` naming the instance and key when something does not fit.
    """
    from fuzzyservo.plants.composed import compose

    plant = compose(
        tuple((inst, type_name, *axis) for inst, (type_name, _, *axis) in components.items())
    )
    by_key = {f.metadata["key"]: f.name for f in dataclasses.fields(plant.params_cls)
              if "key" in f.metadata and not f.metadata.get("effect")}  # fmt: skip
    values = {}
    for inst, (_, given, *_) in components.items():
        for key, value in given.items():
            field_name = by_key.get(f"{inst}.{key}")
            if field_name is None:
                known = sorted(k.partition(".")[2] for k in by_key if k.startswith(f"{inst}."))
                raise ValueError(f"{inst}.{key}: unknown parameter; {inst} has {known}")
            values[field_name] = float(value)
    missing = [
        f.metadata["key"]
        for f in dataclasses.fields(plant.params_cls)
        if "key" in f.metadata and f.default is dataclasses.MISSING and f.name not in values
    ]
    if missing:
        raise ValueError(f"{missing[0]}: missing; give a value in {_unit_of(plant, missing[0])}")
    params = plant.params_cls(**values)
    check(params)
    if isinstance(scenarios, list):
        scenarios = {s.name: s for s in scenarios}
    unknown = set(initial or {}) - {kw for kw, _ in plant.initial_keys.values()}
    if unknown:
        raise ValueError(
            f"initial: unknown key {sorted(unknown)[0]!r}; this composition takes "
            f"{sorted(kw for kw, _ in plant.initial_keys.values())}"
        )
    return Rig(
        name=name,
        title=title,
        plant=plant,
        params=params,
        feedback=feedback,
        actuator=actuator,
        sample_time_s=sample_time_s,
        output=output,
        scenarios=scenarios,
        initial=dict(initial or {}),
        sensors=dict(sensors or {}),
        io_delay_s=io_delay_s,
    )


def _unit_of(plant: PlantModel, key: str) -> str:
    for f in dataclasses.fields(plant.params_cls):
        if f.metadata.get("key") == key:
            return f.metadata["unit"]
    return "SI"


def component_types() -> dict[str, str]:
    """Every component type a rig can compose, with what it models."""
    from fuzzyservo.components.declare import registry

    return {name: f"{c.role}: {c.doc}" for name, c in sorted(registry().items())}
