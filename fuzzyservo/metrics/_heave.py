"""Heave-compensation metric: how much of the platform motion the load no longer sees."""

from __future__ import annotations

import numpy as np


def compensation_pct(wave: np.ndarray, load: np.ndarray) -> float:
    """``100·(1 − rms(load motion) / rms(wave motion))`` [%].

    ``wave`` is the platform (ship) height and ``load`` the load's absolute height over
    the same samples [m]. Motion is taken about each signal's mean, so a constant
    offset of the load (where it hangs) does not count. 100 % is a load held perfectly
    still, 0 % a load that moves with the ship (no compensation); seed 001 §1 cites
    more than 80 % as what only active compensation reaches. NaN when the wave does not
    move or a sample is not finite.
    """
    wave = np.asarray(wave, dtype=float)
    load = np.asarray(load, dtype=float)
    if wave.shape != load.shape:
        raise ValueError(
            f"wave and load must have the same shape, but got {wave.shape} and {load.shape}"
        )
    if wave.size == 0 or not (np.isfinite(wave).all() and np.isfinite(load).all()):
        return float("nan")
    rms_wave = float(np.std(wave))
    if rms_wave == 0.0:
        return float("nan")
    return 100.0 * (1.0 - float(np.std(load)) / rms_wave)


#: Signals of a result that make it a heave-compensation run: (wave, load).
HEAVE_SIGNALS = ("z_wave", "z_load")


def heave_metrics(result) -> dict[str, float]:
    """``{"compensation_pct": …}`` after the warm-up when the result has the wave and load
    signals (plant ``ahc_motor``) and the wave moves; empty otherwise."""
    wave_name, load_name = HEAVE_SIGNALS
    if wave_name not in result.signals or load_name not in result.signals:
        return {}
    keep = result.t >= result.warmup_s
    if not np.ptp(result.signals[wave_name][keep]) > 0:
        return {}
    return {
        "compensation_pct": compensation_pct(
            result.signals[wave_name][keep], result.signals[load_name][keep]
        )
    }
