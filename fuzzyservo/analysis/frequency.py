"""Closed-loop frequency response of the nonlinear loop by stepped sines (MATLAB
``frestimate`` with a ``frest.Sinestream``).

For each frequency one simulation: the reference holds the operating point for
``settle_s`` (the loop moves there from the rig's initial state), then a sine of
``amplitude`` around it. The first ``discard_periods`` periods, and at least
``discard_s``, are dropped (the transient); over the following ``measure_periods`` whole periods the fundamental of the
feedback and of the reference are fitted by least squares (sine, cosine, offset and a
straight line, so a slow drift does not leak into the fundamental), and
``H = Y₁/R₁``. Both are sampled at the control instants, so for a linear plant ``H``
is the sampled-data closed loop ``T(e^{jωT})`` (tests/test_margins.py).
The −3 dB bandwidth is the first frequency where ``|H|`` falls 3 dB below its value at
the lowest frequency (MATLAB ``bandwidth``), interpolated in log frequency.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fuzzyservo.controllers.base import Controller
from fuzzyservo.results import Result
from fuzzyservo.rig import Rig, Scenario
from fuzzyservo.signals import Signal
from fuzzyservo.simulation import simulate


@dataclass(frozen=True)
class SteppedSine(Signal):
    """``operating`` until ``start_s``, then ``operating + amplitude·sin(2πf(t − start_s))``."""

    operating: float
    amplitude: float
    frequency_hz: float
    start_s: float = 0.0

    def sample(self, t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        tau = np.maximum(t - self.start_s, 0.0)
        return self.operating + self.amplitude * np.sin(2 * np.pi * self.frequency_hz * tau)


@dataclass(frozen=True)
class FrequencyResponse(Result):
    """Closed-loop response feedback/reference at each frequency."""

    rig: str
    controller: str
    operating_point: float
    amplitude: float
    frequency_hz: np.ndarray
    response: np.ndarray  # complex H
    statuses: tuple[str, ...]

    @property
    def magnitude_db(self) -> np.ndarray:
        return 20 * np.log10(np.abs(self.response))

    @property
    def phase_deg(self) -> np.ndarray:
        return np.degrees(np.unwrap(np.angle(self.response)))

    @property
    def bandwidth_hz(self) -> float:
        """First −3 dB crossing relative to the lowest frequency; NaN if none."""
        mag = self.magnitude_db - self.magnitude_db[0]
        below = np.flatnonzero(mag <= -3.0)
        if below.size == 0 or below[0] == 0:
            return math.nan
        k = below[0]
        lf = np.log10(self.frequency_hz[k - 1 : k + 1])
        frac = (-3.0 - mag[k - 1]) / (mag[k] - mag[k - 1])
        return float(10 ** (lf[0] + frac * (lf[1] - lf[0])))

    @property
    def phase_at_bandwidth_deg(self) -> float:
        bw = self.bandwidth_hz
        if not math.isfinite(bw):
            return math.nan
        return float(np.interp(np.log10(bw), np.log10(self.frequency_hz), self.phase_deg))

    def text(self) -> str:
        """The table ``fuzzyservo frequency`` prints: gain and phase by frequency."""
        lines = [
            f"{self.controller} on {self.rig}: closed loop around {self.operating_point:.4g}, "
            f"amplitude {self.amplitude:.3g}",
            f"  {'f [Hz]':>9} {'|T| [dB]':>9} {'phase [deg]':>11}",
        ]
        for f, mag, ph in zip(self.frequency_hz, self.magnitude_db, self.phase_deg, strict=True):
            lines.append(f"  {f:9.3g} {mag:9.2f} {ph:11.1f}")
        lines.append(f"  -3 dB bandwidth {self.bandwidth_hz:.3g} Hz, phase there "
                     f"{self.phase_at_bandwidth_deg:.1f} deg")  # fmt: skip
        return "\n".join(lines)

    def to_dict(self) -> dict[str, object]:
        def num(v: float) -> float | None:
            return float(v) if math.isfinite(v) else None

        return {
            "frequency_hz": [float(f) for f in self.frequency_hz],
            "magnitude_db": [num(v) for v in self.magnitude_db],
            "phase_deg": [num(v) for v in self.phase_deg],
            "bandwidth_hz": num(self.bandwidth_hz),
            "phase_at_bandwidth_deg": num(self.phase_at_bandwidth_deg),
            "rig": self.rig,
            "controller": self.controller,
            "operating_point": self.operating_point,
            "amplitude": self.amplitude,
            "statuses": list(self.statuses),
        }


def default_frequencies(rig: Rig, n: int = 20) -> np.ndarray:
    """Log-spaced from 0.1 Hz to a fifth of the sample rate (below Nyquist's half)."""
    return np.logspace(-1, math.log10(0.2 / rig.sample_time_s), n)


def frequency_response(
    rig: Rig,
    controller: Controller,
    frequencies_hz: np.ndarray | None = None,
    *,
    amplitude: float | None = None,
    operating_point: float | None = None,
    scenario: str | Scenario | None = None,
    settle_s: float | None = None,
    discard_periods: int = 3,
    discard_s: float = 1.0,
    measure_periods: int = 5,
) -> FrequencyResponse:
    """Stepped-sine closed-loop response around ``operating_point`` (feedback unit; default
    the scenario's reference at t = 0) with ``amplitude`` (default 10 % of the scenario's
    reference range). ``settle_s`` defaults to the scenario's warm-up (at least 1 s); the
    transient dropped is ``discard_periods`` periods but at least ``discard_s``."""
    sc = scenario if isinstance(scenario, Scenario) else rig.scenario(scenario)
    t_sc = np.arange(round(sc.duration_s / rig.sample_time_s)) * rig.sample_time_s
    ref_sc = sc.reference.sample(t_sc)
    op = float(ref_sc[0]) if operating_point is None else float(operating_point)
    span = float(np.ptp(ref_sc))
    amp = (0.1 * span if span > 0 else 0.01 * max(abs(op), 1.0)) if amplitude is None else amplitude
    settle = max(sc.warmup_s, 1.0) if settle_s is None else float(settle_s)
    freqs = default_frequencies(rig) if frequencies_hz is None else np.asarray(frequencies_hz)
    dt = rig.sample_time_s
    response, statuses = [], []
    for f in freqs:
        period = 1.0 / f
        discard = max(discard_periods * period, discard_s)
        duration = settle + discard + measure_periods * period + dt
        run = Scenario(
            name=f"sine_{f:.4g}Hz",
            duration_s=duration,
            reference=SteppedSine(op, amp, float(f), settle),
            load=sc.load,
            overrides=sc.overrides,
            initial=sc.initial,
        )
        result = simulate(rig, controller, run)
        statuses.append(result.status)
        start = settle + discard
        n_meas = round(measure_periods * period / dt)
        k0 = math.ceil(start / dt - 1e-9)
        sl = slice(k0, k0 + n_meas)
        t = result.t[sl]
        y, r = result.feedback[sl], result.reference[sl]
        if not result.ok or not np.isfinite(y).all() or t.size < 4:
            response.append(complex(math.nan, math.nan))
            continue
        response.append(_fundamental(t, y, f) / _fundamental(t, r, f))
    return FrequencyResponse(
        rig=rig.name,
        controller=controller.name,
        operating_point=op,
        amplitude=float(amp),
        frequency_hz=np.asarray(freqs, dtype=float),
        response=np.asarray(response, dtype=complex),
        statuses=tuple(statuses),
    )


def _fundamental(t: np.ndarray, x: np.ndarray, f: float) -> complex:
    """Complex amplitude ``c`` of ``x ≈ Im(c·e^{jωt}) + a + b·t`` (least squares)."""
    w = 2 * np.pi * f
    tt = t - t[0]
    basis = np.column_stack([np.sin(w * t), np.cos(w * t), np.ones_like(t), tt])
    (s, c, _, _), *_ = np.linalg.lstsq(basis, x, rcond=None)
    return complex(s, c)
