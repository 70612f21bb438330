"""Bode plot of a closed-loop frequency response (analysis/frequency.py)."""

from __future__ import annotations

import math

import numpy as np
from matplotlib.figure import Figure


def bode_figure(response) -> Figure:
    """Magnitude [dB] and phase [deg] against frequency [Hz], with the −3 dB bandwidth."""
    fig = Figure(figsize=(7.5, 6.0), layout="constrained")
    ax_m, ax_p = fig.subplots(2, 1, sharex=True)
    f = np.asarray(response.frequency_hz)
    ax_m.semilogx(f, response.magnitude_db, "o-", ms=3)
    ax_p.semilogx(f, response.phase_deg, "o-", ms=3)
    bw = response.bandwidth_hz
    if math.isfinite(bw):
        for ax in (ax_m, ax_p):
            ax.axvline(bw, color="0.5", ls="--", lw=0.8)
        ax_m.axhline(response.magnitude_db[0] - 3.0, color="0.5", ls=":", lw=0.8)
        ax_m.annotate(f"−3 dB: {bw:.3g} Hz", (bw, response.magnitude_db[0] - 3.0),
                      textcoords="offset points", xytext=(5, 5), fontsize=8)  # fmt: skip
    ax_m.set_ylabel("magnitude [dB]")
    ax_p.set_ylabel("phase [deg]")
    ax_p.set_xlabel("frequency [Hz]")
    for ax in (ax_m, ax_p):
        ax.grid(True, which="both", alpha=0.3)
    fig.suptitle(
        f"{response.controller} on {response.rig}: closed loop around "
        f"{response.operating_point:.4g}, amplitude {response.amplitude:.3g} (stepped sines)"
    )
    return fig
