"""Stability margins of the nonlinear closed loop, found by bisection on simulations.

* **Gain margin**: the smallest multiplier ``k`` of the controller output at which the
  loop oscillates (sustained, non-decaying) or diverges. The multiplier sits between the
  controller and the actuator: the controller keeps its own output range (the rig's
  command range when it has none), then ``k·u`` goes through the actuator with its
  limits unchanged, so a saturating loop saturates at the same plant input. For a P
  controller it is exactly ``K → k·K``; for a fuzzy controller it scales ``output_gain``.
* **Delay margin**: the smallest extra loop delay [s] at which the loop oscillates,
  added to the rig's own loop delay (``io_delay`` plus any ``transport_delay``; exact
  within the zero-order hold).

The oscillation detector (:func:`oscillation`) reads the tracking error
``e = feedback − reference`` (feedback unit) after the last reference step (or after the
warm-up when the reference has no step). That stretch is cut in thirds; the first is
dropped (the step response itself), the middle and the last are detrended (a straight
line removed, so slow creep is no oscillation) and the amplitude of each one's dominant
sinusoid is compared: ``sqrt(2·P)``, with ``P`` the power within the main lobe around the
peak of its Hann-windowed periodogram. A sinusoid of amplitude ``A`` measures ``A``;
motion that sensor noise drives through a stable loop is broadband and measures only its
share near the peak. The loop counts as oscillating when

1. the run diverged, failed or drove the plant into an end stop (``diverged``,
   ``step_failure``, ``end_stop``), or
2. the last third's dominant sinusoid is above the floor (default 0.5 % of the
   reference's peak-to-peak range, 1e-3 of its level for a constant reference: well above
   sensor quantisation, so a hunting valve deadband below it is no loss of stability),
   the error crosses its trend line at least 6 times (3 cycles), and the amplitude is at
   least ``ratio`` (0.97) of the middle third's: not decaying.

A saturation limit cycle has a constant amplitude (ratio ≈ 1); a growing oscillation a
ratio above 1; a stable loop near its margin decays by more than 3 % over the many
cycles of a third of a scenario, so the bisection lands within about 1 % below the
linear margin (tests/test_margins.py: 1.892 against 1.909; a ratio of 0.9 gave −2 %,
1.0 −0.4 %, but would call a limit cycle with a little amplitude jitter decaying).
Why the dominant sinusoid and not the peak-to-peak swing: with 1 mV sensor noise, a
fuzzy controller that is steep at zero error jitters the piston by ±2.5 mV at twice its
output (half peak to peak, over thirds of 0.67 s after the seed-002 `steps` scenario's last
step): above the 2.42 mV floor, and the ratio of two such random stretches swings
between 0.1 and 2.3. That is no oscillation; its dominant sinusoid is 1.4 mV. A true
oscillation puts 97-100 % of its power in that lobe (tests/test_margins.py).
On the seed-002 rig 0.9 and 0.97 give the same margins.
The oscillation frequency comes from the trend-line crossings
of the last third (interpolated), ``1/2`` of the crossing rate.

Cost: each bisection step is one simulation of the scenario; a margin to 1 % takes
8-12 runs (bracketing by doubling, then bisection), ``margins`` both about 20.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from fuzzyservo.controllers.base import Controller
from fuzzyservo.display import MetricUnits
from fuzzyservo.results import Result
from fuzzyservo.rig import Rig, Scenario
from fuzzyservo.simulation import bind, simulate
from fuzzyservo.simulation.result import SimResult

_SHOWN = MetricUnits()  # margins do not depend on the output's unit
DEFAULT_RATIO = 0.97
DEFAULT_FLOOR_FRACTION = 0.005
MIN_CROSSINGS = 6
_PAD = 4  # zero padding of the periodogram that finds the dominant tone


@dataclass(frozen=True)
class Oscillation:
    """What :func:`oscillation` found in one run."""

    sustained: bool
    reason: str  # diverged | oscillating | decaying | below_floor | no_cycles
    frequency_hz: float
    amplitude: float  # of the last third's dominant sinusoid [feedback unit]
    ratio: float  # amplitude of the last third over the middle third
    floor: float


@dataclass(frozen=True)
class Margin:
    """One margin: ``value`` the middle of the final ``bracket`` (stable, oscillating)."""

    value: float
    bracket: tuple[float, float]
    frequency_hz: float  # oscillation at the bracket's upper end
    runs: int
    seconds: float
    trials: list[tuple[float, str]] = field(default_factory=list)  # (value, reason) per run


@dataclass(frozen=True)
class Margins(Result):
    """Gain and delay margin of one controller on one rig scenario."""

    rig: str
    controller: str
    scenario: str
    gain: Margin
    delay: Margin
    base_delay_s: float

    def text(self) -> str:
        g, d = self.gain, self.delay
        return (
            f"{self.controller} on {self.rig}, scenario {self.scenario} ({g.runs + d.runs} runs, "
            f"{g.seconds + d.seconds:.1f} s)\n"
            f"  gain margin  {g.value:.4g}  (stable at {g.bracket[0]:.4g}, oscillating at "
            f"{g.bracket[1]:.4g}, {g.frequency_hz:.3g} Hz)\n"
            f"  delay margin {_SHOWN.text('delay_margin_s', d.value)} extra on the rig's "
            f"{_SHOWN.text('delay_margin_s', self.base_delay_s)} ({d.frequency_hz:.3g} Hz at onset)"
        )

    def to_dict(self) -> dict[str, object]:
        """The JSON record: ``gain_margin``, ``oscillation_hz``, ``delay_margin_s`` first."""
        g, d = self.gain, self.delay
        return {
            "gain_margin": _finite(g.value),
            "oscillation_hz": _finite(g.frequency_hz),
            "delay_margin_s": _finite(d.value),
            "delay_oscillation_hz": _finite(d.frequency_hz),
            "rig": self.rig,
            "controller": self.controller,
            "scenario": self.scenario,
            "gain_bracket": [_finite(v) for v in g.bracket],
            "delay_bracket_s": [_finite(v) for v in d.bracket],
            "rig_delay_s": self.base_delay_s,
            "runs": g.runs + d.runs,
            "seconds": round(g.seconds + d.seconds, 3),
            "gain_trials": [{"gain": k, "verdict": r} for k, r in g.trials],
            "delay_trials": [{"delay_s": k, "verdict": r} for k, r in d.trials],
        }


def _finite(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


# --------------------------------------------------------------------------- detector
def oscillation(
    result: SimResult, *, ratio: float = DEFAULT_RATIO, floor: float | None = None
) -> Oscillation:
    """Does ``result`` end in a sustained oscillation (or did it diverge)? See the module
    docstring for the rule; ``floor`` in the feedback unit overrides the default."""
    ref = np.asarray(result.reference, dtype=float)
    span = float(np.nanmax(ref) - np.nanmin(ref))
    if floor is None:
        floor = DEFAULT_FLOOR_FRACTION * span if span > 0 else 1e-3 * max(abs(ref[0]), 1.0)
    err = np.asarray(result.feedback, dtype=float) - ref
    dt = result.sample_time_s
    if result.status in ("diverged", "step_failure", "end_stop"):
        # a loop that swings the piston into an end stop while tracking a reference
        # inside the stroke has lost stability, however few cycles the window holds
        good = err[np.isfinite(err)]
        freq = _crossing_frequency(good[-max(good.size // 3, 2) :], dt)
        reason = "end_stop" if result.status == "end_stop" else "diverged"
        return Oscillation(True, reason, freq, math.inf, math.inf, floor)
    start = _analysis_start(result, span)
    window = err[start:]
    third = window.size // 3
    if third < 4:
        return Oscillation(False, "no_cycles", math.nan, 0.0, 0.0, floor)
    middle, last = _detrend(window[third : 2 * third]), _detrend(window[-third:])
    a_mid, a_last = _tone_amplitude(middle), _tone_amplitude(last)
    r = a_last / a_mid if a_mid > 0 else (math.inf if a_last > 0 else 0.0)
    crossings = _crossings(last)
    freq = _crossing_frequency(last, dt)
    if a_last <= floor:
        return Oscillation(False, "below_floor", freq, a_last, r, floor)
    if crossings.size < MIN_CROSSINGS:
        return Oscillation(False, "no_cycles", freq, a_last, r, floor)
    if r < ratio:
        return Oscillation(False, "decaying", freq, a_last, r, floor)
    return Oscillation(True, "oscillating", freq, a_last, r, floor)


def _analysis_start(result: SimResult, span: float) -> int:
    """Index of the last reference step (a jump of > 5 % of the range), else the warm-up."""
    ref = result.reference
    warm = round(result.warmup_s / result.sample_time_s)
    if span > 0:
        jumps = np.flatnonzero(np.abs(np.diff(ref)) > 0.05 * span)
        if jumps.size and jumps[-1] + 1 >= warm:
            return int(jumps[-1] + 1)
    return warm


def _detrend(x: np.ndarray) -> np.ndarray:
    n = np.arange(x.size, dtype=float)
    slope, icept = np.polyfit(n, x, 1)
    return x - (slope * n + icept)


def _tone_amplitude(x: np.ndarray) -> float:
    """Amplitude of the dominant sinusoid in ``x`` (detrended): ``sqrt(2·P)`` with ``P``
    the power within two bins of the peak of its Hann-windowed periodogram (the window's
    main lobe, zero-padded four times so an off-bin tone is caught whole). A sinusoid of
    amplitude ``A`` gives ``A``; broadband motion only the share near its peak."""
    if x.size < 2 or not np.any(x):
        return 0.0
    pad = _PAD * x.size
    power = np.abs(np.fft.rfft(x * np.hanning(x.size), pad)) ** 2
    k = int(np.argmax(power[1:])) + 1
    share = float(power[max(k - 2 * _PAD, 0) : k + 2 * _PAD + 1].sum() / power.sum())
    return math.sqrt(2.0 * share * float(np.mean(x * x)))


def _crossings(x: np.ndarray) -> np.ndarray:
    """Fractional sample positions where ``x`` changes sign."""
    s = np.signbit(x)
    k = np.flatnonzero(s[1:] != s[:-1])
    return k + x[k] / (x[k] - x[k + 1])


def _crossing_frequency(x: np.ndarray, dt: float) -> float:
    if x.size < 4:
        return math.nan
    c = _crossings(_detrend(x))
    if c.size < 3:
        return math.nan
    return float((c.size - 1) / (2.0 * (c[-1] - c[0]) * dt))


# --------------------------------------------------------------------------- margins
def scaled(rig: Rig, controller: Controller, multiplier: float) -> tuple[Rig, Controller]:
    """``rig`` and ``controller`` with the controller output multiplied by ``multiplier``
    ahead of the actuator (its limits unchanged); the controller keeps its own range."""
    if not controller.has_limits:
        controller = controller.with_limits(*rig.actuator.command_limits)
    actuator = dataclasses.replace(rig.actuator, gain=rig.actuator.gain * multiplier)
    return dataclasses.replace(rig, actuator=actuator), controller


def delayed(rig: Rig, extra_s: float) -> Rig:
    """``rig`` with ``extra_s`` added to its ``transport_delay``."""
    base = float(rig.params.transport_delay_s)
    return rig.with_effect("transport_delay", delay=base + extra_s)


def _runner(
    scenario: str | Scenario | None,
    duration_s: float | None,
    detector: dict,
    trials: list[tuple[float, str]],
    last: dict,
) -> Callable[[Rig, Controller, float], bool]:
    def unstable(rig: Rig, controller: Controller, value: float) -> bool:
        result = simulate(rig, controller, scenario, duration_s=duration_s)
        osc = oscillation(result, **detector)
        trials.append((float(value), osc.reason))
        if osc.sustained:
            last["frequency_hz"] = osc.frequency_hz
        return osc.sustained

    return unstable


def gain_margin(
    rig: Rig,
    controller: Controller,
    scenario: str | Scenario | None = None,
    *,
    rel_tol: float = 0.01,
    max_gain: float = 1000.0,
    duration_s: float | None = None,
    ratio: float = DEFAULT_RATIO,
    floor: float | None = None,
) -> Margin:
    """The smallest output multiplier at which the loop oscillates, to ``rel_tol``.

    ``inf`` when it is still stable at ``max_gain``; below 1 when it already oscillates
    as it is (then the bracket is searched downwards).
    """
    trials: list[tuple[float, str]] = []
    last: dict = {}
    run = _runner(scenario, duration_s, {"ratio": ratio, "floor": floor}, trials, last)
    t0 = time.perf_counter()

    def unstable(k: float) -> bool:
        return run(*scaled(rig, controller, k), k)

    lo, hi = _bracket(unstable, 1.0, lambda v: 2.0 * v, lambda v: 0.5 * v, max_gain, 1e-3)
    while math.isfinite(hi) and lo > 0 and hi / lo > 1.0 + rel_tol:
        mid = math.sqrt(lo * hi)
        if unstable(mid):
            hi = mid
        else:
            lo = mid
    return _margin(lo, hi, trials, last, t0)


def _margin(lo: float, hi: float, trials: list, last: dict, t0: float) -> Margin:
    """The :class:`Margin` of a final bracket ``(lo, hi)``."""
    onset = math.isfinite(hi)
    return Margin(
        value=0.5 * (lo + hi) if onset else math.inf,
        bracket=(lo, hi),
        frequency_hz=last.get("frequency_hz", math.nan) if onset else math.nan,
        runs=len(trials),
        seconds=time.perf_counter() - t0,
        trials=trials,
    )


def delay_margin(
    rig: Rig,
    controller: Controller,
    scenario: str | Scenario | None = None,
    *,
    rel_tol: float = 0.01,
    max_delay_s: float = 1.0,
    duration_s: float | None = None,
    ratio: float = DEFAULT_RATIO,
    floor: float | None = None,
) -> Margin:
    """The smallest extra loop delay [s] at which the loop oscillates, to ``rel_tol``
    (or 1 µs). 0 when it oscillates without extra delay; ``inf`` beyond ``max_delay_s``."""
    trials: list[tuple[float, str]] = []
    last: dict = {}
    run = _runner(scenario, duration_s, {"ratio": ratio, "floor": floor}, trials, last)
    t0 = time.perf_counter()

    def unstable(d: float) -> bool:
        return run(delayed(rig, d), controller, d)

    if unstable(0.0):
        lo, hi = 0.0, 0.0
    else:
        lo, hi = _bracket(
            unstable, rig.sample_time_s, lambda v: 2.0 * v, lambda v: 0.5 * v, max_delay_s, 1e-6
        )
        if not math.isfinite(hi) and lo < rig.sample_time_s:
            lo = 0.0
        while math.isfinite(hi) and hi - lo > max(rel_tol * hi, 1e-6):
            mid = 0.5 * (lo + hi)
            if unstable(mid):
                hi = mid
            else:
                lo = mid
    return _margin(lo, hi, trials, last, t0)


def stable_at(
    rig: Rig,
    controller: Controller,
    scenario: str | Scenario | None = None,
    *,
    multiplier: float = 1.0,
    extra_delay_s: float = 0.0,
    duration_s: float | None = None,
    ratio: float = DEFAULT_RATIO,
    floor: float | None = None,
    noise_seed: int = 0,
) -> bool:
    """One run: True when the loop does not oscillate with its output multiplied by
    ``multiplier`` and ``extra_delay_s`` added to its delay (sensor noise seeded
    ``noise_seed``). A constraint such as ``gain_margin >= 2`` needs only this verdict at
    its bound (one simulation, where the margin's value takes about ten); the robust
    studies and the Monte Carlo ask it on every sampled plant."""
    r, c = scaled(rig, controller, multiplier) if multiplier != 1.0 else (rig, controller)
    if extra_delay_s > 0.0:
        r = delayed(r, extra_delay_s)
    result = simulate(r, c, scenario, duration_s=duration_s, noise_seed=noise_seed)
    return not oscillation(result, ratio=ratio, floor=floor).sustained


def _bracket(
    unstable: Callable[[float], bool],
    start: float,
    up: Callable[[float], float],
    down: Callable[[float], float],
    top: float,
    bottom: float,
) -> tuple[float, float]:
    """``(stable, unstable)`` values around the onset, from ``start`` outwards; ``(lo, inf)``
    when stable up to ``top``, ``(0, hi)`` when unstable down to ``bottom``."""
    if unstable(start):
        hi = start
        while hi > bottom:
            lo = down(hi)
            if not unstable(lo):
                return lo, hi
            hi = lo
        return 0.0, hi
    lo = start
    while lo < top:
        hi = up(lo)
        if unstable(hi):
            return lo, hi
        lo = hi
    return lo, math.inf


def margins(
    rig: Rig,
    controller: Controller,
    scenario: str | Scenario | None = None,
    *,
    rel_tol: float = 0.01,
    duration_s: float | None = None,
    ratio: float = DEFAULT_RATIO,
    floor: float | None = None,
) -> Margins:
    """Gain margin (with the oscillation frequency at onset) and delay margin.

    The two searches are independent: they run side by side in two threads (the
    compiled loop releases the GIL), each run as it runs alone, so the margins are the
    same as one after the other, in about half the time on two cores. A controller
    stepped in Python (an FMU, one instance) or a plant holding state outside the loop (an
    FMU plant: one instance per parameter set, which both searches would share) runs them
    one after the other.
    """
    sc = scenario if isinstance(scenario, Scenario) else rig.scenario(scenario)
    options = {"rel_tol": rel_tol, "duration_s": duration_s, "ratio": ratio, "floor": floor}
    if getattr(controller, "stepped", False) or rig.plant.attach is not None:
        gain = gain_margin(rig, controller, sc, **options)
        delay = delay_margin(rig, controller, sc, **options)
    else:
        # the plant's kernels the runs will use (the scenario's parameters pick the
        # plant's form), compiled here, not in both threads
        bind(rig.plant.for_params(rig.params_for(sc)))
        with ThreadPoolExecutor(max_workers=2) as pool:
            gain_run = pool.submit(gain_margin, rig, controller, sc, **options)
            delay_run = pool.submit(delay_margin, rig, controller, sc, **options)
            gain, delay = gain_run.result(), delay_run.result()
    return Margins(
        rig=rig.name,
        controller=controller.name,
        scenario=sc.name,
        gain=gain,
        delay=delay,
        base_delay_s=float(rig.params.transport_delay_s) + float(rig.io_delay_s),
    )
