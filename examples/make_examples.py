"""Regenerate the example data files in ``examples/`` from fuzzyservo's own models.

    python examples/make_examples.py [--out FOLDER]     (default: this script's folder)

Nothing here is measured: every file is a run of the shipped rigs (seeded noise), and
regenerates to the bit whatever code numba, numpy and OpenBLAS pick for the CPU. Only
glibc's exp, pow and tanh differ by CPU (their versions for CPUs without FMA are a last
bit apart now and then), and the friction run is a stick-slip record, where a last bit
moves where the piston sticks by up to one step of the 16-bit position converter: on
such a CPU it regenerates to what its loop resolves (``tests/test_examples.py`` states
the tolerances).

``run_dinca_friction.csv``
    A "measured" run for ``fuzzyservo calibrate``: seed 002's rig
    (``rigs/dinca_cylinder.yaml``) under its P controller K = 10 (``p_k10``) on the
    ``pulses`` scenario, with one effect the rig file does not declare switched on:
    Coulomb friction of 300 N (about 6 % of the stall force). Recorded at the loop's
    100 Hz like a logger would: the reference and the position in cm, the converter
    current in mA, the chamber pressures in bar, with white noise of 5 µm on the
    position and 0.05 bar on the pressures (noise seed 7). Calibration should name
    ``coulomb_friction`` and fit about 300 N.
``valve_hydroprax.csv``
    Valve data for ``fuzzyservo fit-valve`` (seed 003's measurement, from the model):
    300 operating points of the Hydroprax valve of ``rigs/hydroprax_pdcv.yaml`` (the
    ``characteristic_valve``: seed 003 eq. 7 with the orifice law per edge), supply
    pressure uniform in 0.3-1.05 × nominal, command uniform in ±U_max, chamber
    pressures uniform between tank and supply (seed 3).
``pd_valve_inputs.csv``
    A table of inputs (``e``, ``de``) for ``fuzzyservo evaluate examples/pd_valve.fis``.

``pd_valve.fis`` is written by hand (see its header), not by this script.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from fuzzyservo.calibration.synthetic import synthetic_run
from fuzzyservo.io.controllers import load_controller
from fuzzyservo.io.measured import write_measured
from fuzzyservo.io.paths import find_file
from fuzzyservo.io.rigs import load_rig
from fuzzyservo.io.valve_data import write_valve_csv
from fuzzyservo.params import pack

HERE = Path(__file__).resolve().parent


def measured_run(path: Path) -> Path:
    """``run_dinca_friction.csv``: seed 002, P K = 10, ``pulses``, 300 N Coulomb friction."""
    rig = load_rig(find_file("dinca_cylinder", "rigs", "rig"))
    controller = load_controller(find_file("p_k10", "studies/controllers", "controller"))
    noise = {"y": 5e-6, "p_a": 0.05e5, "p_b": 0.05e5}
    effects = {"coulomb_friction": {"force": 300.0}}
    data = synthetic_run(rig, controller, "pulses", effects, noise, seed=7)
    units = {"ref": "cm", "i": "mA", "y": "cm", "p_a": "bar", "p_b": "bar"}
    return write_measured(path, data, units)


def valve_data(path: Path, n: int = 300, seed: int = 3) -> Path:
    """``valve_hydroprax.csv``: ``n`` operating points of seed 003's valve, its port flows
    computed by the rig's own compiled plant (its signals ``q_a``, ``q_b`` at each state),
    written in bar, V and l/min."""
    rig = load_rig(find_file("hydroprax_pdcv", "rigs", "rig"))
    model, params = rig.plant, rig.params
    rng = np.random.default_rng(seed)
    u_max, p_t = params.valve__control_voltage_max, params.supply__tank_pressure
    p_s = rng.uniform(0.3, 1.05, n) * params.supply__supply_pressure
    u = rng.uniform(-1.0, 1.0, n) * u_max
    p_a = p_t + rng.uniform(0.0, 1.0, n) * (p_s - p_t)
    p_b = p_t + rng.uniform(0.0, 1.0, n) * (p_s - p_t)
    x = model.initial_state(params)
    at = {name: model.states.index(name) for name in ("p_s", "p_a", "p_b")}
    q_a, q_b = model.signals.index("q_a"), model.signals.index("q_b")
    packed, out = pack(params), np.empty(len(model.signals))
    flows = np.empty((n, 2))
    for k in range(n):
        x[at["p_s"]], x[at["p_a"]], x[at["p_b"]] = p_s[k], p_a[k], p_b[k]
        model.kernels.plant_signals(x, u[k], 0.0, packed, out)
        flows[k] = out[q_a], out[q_b]
    return write_valve_csv(path, np.column_stack([p_s, u, p_a, p_b, flows]))


def fis_inputs(path: Path) -> Path:
    """``pd_valve_inputs.csv``: a grid of (e, de) over the example system's ranges."""
    e, de = np.meshgrid(np.linspace(-1, 1, 5), np.linspace(-1, 1, 3))
    rows = "".join(f"{a:g},{b:g}\n" for a, b in zip(e.ravel(), de.ravel(), strict=True))
    path.write_text("e,de\n" + rows, encoding="utf-8")
    return path


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    ap.add_argument("--out", type=Path, default=HERE, help="folder to write (default: examples/)")
    out = ap.parse_args(argv).out
    out.mkdir(parents=True, exist_ok=True)
    for path in (
        fis_inputs(out / "pd_valve_inputs.csv"),
        valve_data(out / "valve_hydroprax.csv"),
        measured_run(out / "run_dinca_friction.csv"),
    ):
        print(f"written {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
