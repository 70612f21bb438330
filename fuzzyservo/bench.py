"""``fuzzyservo bench``: speed of the compiled loop against the scipy reference, same run.

Each case is run after a warm-up (compilation) several times; the median wall time is
compared with the median of the reference path (``solve_ivp`` LSODA at rtol 1e-6 over
every control interval, with the same compiled right-hand side), and the accuracy is
measured against a tight reference (rtol 1e-9). Benchmarks are not tests: nothing
here asserts a time.
"""

from __future__ import annotations

import math
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from fuzzyservo.progress import ProgressBar

import numpy as np

from fuzzyservo.errors import ConfigError, did_you_mean
from fuzzyservo.io.paths import data_root
from fuzzyservo.results import Result
from fuzzyservo.simulation import SimResult, simulate
from fuzzyservo.simulation.reference import simulate_reference


@dataclass(frozen=True)
class BenchCase:
    """One benchmark: a rig, a controller, a scenario, a simulated duration."""

    name: str
    rig_file: str
    controller_file: str
    scenario: str
    duration_s: float
    description: str = ""


@dataclass(frozen=True)
class BenchResult:
    name: str
    median_s: float
    reference_s: float
    ratio: float
    runs: int
    reference_runs: int
    simulated_s: float
    integration_steps: int
    error: dict[str, float] = field(default_factory=dict)
    description: str = ""
    extra: dict[str, float] = field(default_factory=dict)

    @classmethod
    def once(
        cls,
        name: str,
        description: str,
        wall_s: float,
        *,
        simulated_s: float = 0.0,
        error: dict[str, float] | None = None,
        extra: dict[str, float] | None = None,
    ) -> BenchResult:
        """A case timed by one run with no reference path (calibrate, margins, studies):
        its wall time is the median, and ``extra`` carries it as ``wall_s`` too."""
        return cls(
            name=name,
            description=description,
            simulated_s=simulated_s,
            median_s=wall_s,
            reference_s=math.nan,
            ratio=math.nan,
            runs=1,
            reference_runs=0,
            integration_steps=0,
            error=error or {},
            extra={"wall_s": wall_s, **(extra or {})},
        )

    def to_dict(self) -> dict:
        return {
            **self.extra,
            "name": self.name,
            "description": self.description,
            "simulated_s": self.simulated_s,
            "median_s": self.median_s,
            "reference_s": self.reference_s,
            "ratio": self.ratio,
            "runs": self.runs,
            "reference_runs": self.reference_runs,
            "integration_steps": self.integration_steps,
            "error": self.error,
        }


CASES = (
    BenchCase(
        "dinca_pulses_p10",
        "rigs/dinca_cylinder.yaml",
        "studies/controllers/p_k10.yaml",
        "pulses",
        20.0,
        "seed 002 rig (20 ms I/O delay, 1 mV noise, 16-bit ADC, 3.2 ms spool), P K=10, 1 V pulses, 20 s simulated at 100 Hz",
    ),
    BenchCase(
        "dinca_pulses_flc2",
        "rigs/dinca_cylinder.yaml",
        "studies/controllers/flc2_reshaped.yaml",
        "pulses",
        20.0,
        "seed 002 rig, FLC2 (reshaped inputs, translated outputs), 20 s simulated at 100 Hz",
    ),
    BenchCase(
        "ehs160_steps_p",
        "rigs/ehs160_motor.yaml",
        "studies/controllers/p_kb0105.yaml",
        "steps",
        5.0,
        "seed 000 rig, P Kb=0.105, velocity steps, 5 s simulated at 1 kHz",
    ),
    BenchCase(
        "hydroprax_steps_pi",
        "rigs/hydroprax_pdcv.yaml",
        "studies/controllers/pi_hydroprax.yaml",
        "steps",
        10.5,
        "seed 003 rig, PI Kp=450 Ki=0.011, 0-0.1 m steps, 10.5 s simulated at 1 kHz",
    ),
    BenchCase(
        "ahc_cylinder_steps_p",
        "rigs/ahc_cylinder.yaml",
        "studies/controllers/p_ahc_cylinder.yaml",
        "steps_10mpa",
        3.5,
        "seed 001 wave simulator, P K=40, 100 mm steps at 10 MPa, 3.5 s simulated at 1 kHz",
    ),
    BenchCase(
        "ahc_motor_heave_p",
        "rigs/ahc_motor.yaml",
        "studies/controllers/p_ahc_motor.yaml",
        "heave",
        40.0,
        "seed 001 compensator, P K=2, heave compensation, 40 s simulated at 1 kHz",
    ),
)


def accuracy(fast: SimResult, tight: SimResult) -> dict[str, float]:
    """Largest deviation of the fast path from the tight reference, in engineering units."""
    err: dict[str, float] = {}
    out = fast.output_name
    unit = fast.units[out]
    dev = float(np.nanmax(np.abs(fast.output - tight.output)))
    if unit == "m":
        err["position_mm"] = dev * 1e3
    else:
        err[f"{out}_{unit.replace('/', '_')}"] = dev
    pressures = [k for k in fast.signals if fast.units.get(k) == "Pa"]
    if pressures:
        err["pressure_bar"] = max(
            float(np.nanmax(np.abs(fast.signals[k] - tight.signals[k]))) / 1e5 for k in pressures
        )
    return err


def _median_time(fn: Callable[[], object], runs: int) -> tuple[float, object]:
    times, last = [], None
    for _ in range(runs):
        t0 = time.perf_counter()
        last = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), last


FUZZY_EVAL = "fuzzy_eval"
STUDY = "study_dinca_flc"
ROBUST_STUDY = "study_dinca_robust"
CALIBRATE = "calibrate_dinca"
CALIBRATE_SEGMENTS = "calibrate_segments"
MARGINS = "margins"
FMU_PLANT = "dinca_fmu_me_p10"
COMPILE = "compile"


def _timed_command(args: list[str], cache: Path, cwd: Path) -> tuple[float, list[str]]:
    """Wall seconds of ``fuzzyservo <args>`` in a new process with numba's cache in
    ``cache``, and its compile lines (``compiled <what> in <s> s``). Raises
    RuntimeError with the command's last output line when it fails."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    t0 = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-m", "fuzzyservo", *args], cwd=cwd, env=env, capture_output=True,
        text=True, check=False,
    )  # fmt: skip
    wall = time.perf_counter() - t0
    if done.returncode != 0:
        last = (done.stderr.strip() or done.stdout.strip() or "no output").splitlines()[-1]
        raise RuntimeError(f"bench compile: fuzzyservo {' '.join(args)} failed: {last}")
    return wall, [
        ln.strip() for ln in done.stderr.splitlines() if ln.strip().startswith("compiled ")
    ]


def _compile_seconds(lines: list[str]) -> float:
    return sum(float(ln.rsplit(" in ", 1)[1].split()[0]) for ln in lines)


def run_compile_case(root: Path | None = None, *, calibrate: bool = True) -> BenchResult:
    """What compiling costs a user, each command in a new process, with numba's cache
    emptied first (a fresh install): the first ``simulate dinca_cylinder p_k10`` (wall,
    everything included) against the same command warm; a rig never run before (seed 002's
    with a spring added: a new composition) first and warm; and with
    ``calibrate``, a whole-library calibration of the friction example on that rig, first
    (empty cache) and warm. The same machine, one run."""
    root = root or data_root()
    rig = root / "rigs" / "dinca_cylinder.yaml"
    controller = root / "studies" / "controllers" / "p_k10.yaml"
    extra: dict[str, float] = {}
    with tempfile.TemporaryDirectory(prefix="fuzzyservo-bench-compile-") as folder:
        tmp = Path(folder)
        new_rig = tmp / "dinca_spring.yaml"  # a rig the package does not ship
        seal = ("    seal:\n      type: spring\n      parameters:\n"
                "        stiffness: {value: 10, unit: N/m, source: bench}\n")  # fmt: skip
        text = rig.read_text(encoding="utf-8").replace("    guides:\n", seal + "    guides:\n", 1)
        new_rig.write_text(text.replace("name: dinca_cylinder", "name: dinca_spring", 1), "utf-8")
        cache = tmp / "cache"

        def simulate(path: Path) -> tuple[float, list[str]]:
            return _timed_command(["simulate", str(path), str(controller), "--out",
                                   str(tmp / "out")], cache, tmp)  # fmt: skip

        first, lines = simulate(rig)
        warm, _ = simulate(rig)
        new_first, new_lines = simulate(new_rig)
        new_warm, _ = simulate(new_rig)
        extra.update(
            first_s=first, first_compile_s=_compile_seconds(lines), warm_s=warm,
            new_rig_s=new_first, new_rig_warm_s=new_warm, new_rig_compile_s=_compile_seconds(new_lines),
            new_rig_extra_s=new_first - new_warm,
        )  # fmt: skip
        if calibrate:
            shutil.rmtree(cache)
            record = root / "examples" / "run_dinca_friction.csv"
            args = ["calibrate", str(new_rig), str(record), "--out", str(tmp / "cal")]
            cold, cal_lines = _timed_command(args, cache, tmp)
            hot, _ = _timed_command(args, cache, tmp)
            extra.update(calibrate_cold_s=cold, calibrate_warm_s=hot,
                         calibrate_extra_s=cold - hot, calibrate_compile_s=_compile_seconds(cal_lines))  # fmt: skip
    return BenchResult.once(
        COMPILE,
        "compile cost, empty cache, new processes: first simulate, a new composition, calibrate",
        extra["first_s"],
        extra=extra,
    )


def run_calibrate_case(
    root: Path | None = None, *, workers: int = 2, segments: bool = False
) -> BenchResult:
    """``calibrate`` with the whole effect library on a 30 s, 100 Hz seed-002 run
    (P K=10, `pulses`) with Coulomb friction of 300 N undeclared, 5 µm and 0.05 bar of
    noise, each round's candidates fitted on ``workers`` processes (the command's
    default is one per core; the result is the same on any number); the issue's budget
    is 12 s on the 2-core machine with nothing else running. ``segments``: on the
    segmented replay (``calibrate --segments``; measuring its horizon included)."""
    from fuzzyservo.calibration.candidates import candidate_effects
    from fuzzyservo.calibration.replay import make_replay
    from fuzzyservo.calibration.search import search_effects
    from fuzzyservo.calibration.segments import probe_rigs, segmented
    from fuzzyservo.calibration.synthetic import synthetic_run
    from fuzzyservo.io.controllers import load_controller
    from fuzzyservo.io.rigs import load_rig

    root = root or data_root()
    rig = load_rig(root / "rigs" / "dinca_cylinder.yaml")
    controller = load_controller(root / "studies" / "controllers" / "p_k10.yaml")
    noise = {"y": 5e-6, "p_s": 5e3, "p_t": 5e3, "p_a": 5e3, "p_b": 5e3}
    data = synthetic_run(
        rig, controller, "pulses", {"coulomb_friction": {"force": 300.0}}, noise, duration_s=30.0
    )
    t0 = time.perf_counter()
    replay = make_replay(rig, data, controller)
    if segments:
        replay = segmented(replay, rig, probe_rigs(rig, candidate_effects(rig)))
    outcome = search_effects(replay, rig, workers=workers)
    wall = time.perf_counter() - t0
    runs = sum(c.evaluations for r in outcome.rounds for c in r.candidates)
    return BenchResult.once(
        CALIBRATE_SEGMENTS if segments else CALIBRATE,
        "calibrate, whole library, 30 s of seed-002 data at 100 Hz (Coulomb friction undeclared)"
        + (f", on {replay.segment_words}" if segments else ""),
        wall,
        simulated_s=30.0,
        error={"fitted_force_n": outcome.added[0].params["force"] if outcome.added else math.nan},
        extra={
            "replays": runs,
            "replay_ms": 1e3 * wall / max(runs, 1),
            "added": [c.name for c in outcome.added],
            "budget_s": 12.0,  # issue 40: on the 2-core machine, nothing else running
            "workers": workers,
        },
    )


def run_margins_case(root: Path | None = None) -> BenchResult:
    """``margins dinca_cylinder p_k10``: gain and delay margin by bisection on the 22 s
    `pulses` scenario (after one compiling run)."""
    from fuzzyservo.analysis import margins
    from fuzzyservo.io.controllers import load_controller
    from fuzzyservo.io.rigs import load_rig

    root = root or data_root()
    rig = load_rig(root / "rigs" / "dinca_cylinder.yaml")
    controller = load_controller(root / "studies" / "controllers" / "p_k10.yaml")
    simulate(rig, controller, "pulses")  # compile
    t0 = time.perf_counter()
    m = margins(rig, controller, "pulses")
    wall = time.perf_counter() - t0
    runs = m.gain.runs + m.delay.runs
    return BenchResult.once(
        MARGINS,
        "margins of P K=10 on the seed-002 rig (pulses, 22 s per run)",
        wall,
        simulated_s=22.0 * runs,
        error={"gain_margin": m.gain.value, "delay_margin_s": m.delay.value},
        extra={"simulations": runs, "ms_per_simulation": 1e3 * wall / runs},
    )


def run_fmu_plant_case(root: Path | None = None, *, runs: int = 7) -> BenchResult:
    """Seed 002's plant exported as an FMU (FMI 3.0, :func:`~fuzzyservo.workflows.export_plant`)
    and run back as the rig's plant for model exchange, against the native composition:
    P K=10 on `pulses`, 20 s, medians of ``runs`` runs each after a compiling run. The
    error columns: the largest position difference (relative to the stroke travelled) and
    the difference in integration steps."""
    import tempfile

    from fuzzyservo.io.controllers import load_controller
    from fuzzyservo.io.rigs import load_rig
    from fuzzyservo.workflows import export_plant

    root = root or data_root()
    rig = load_rig(root / "rigs" / "dinca_cylinder.yaml")
    controller = load_controller(root / "studies" / "controllers" / "p_k10.yaml")
    with tempfile.TemporaryDirectory() as tmp:
        export_plant(rig, Path(tmp) / "dinca_cylinder_plant.fmu", fmi=3)
        fmu_rig = load_rig(Path(tmp) / "dinca_cylinder_plant.yaml")
        timed = {}
        for key, r in (("native", rig), ("fmu", fmu_rig)):
            simulate(r, controller, "pulses", duration_s=20.0)  # compile / warm caches
            timed[key] = _median_time(
                lambda r=r: simulate(r, controller, "pulses", duration_s=20.0), runs
            )
    (native_s, native), (fmu_s, fmu) = timed["native"], timed["fmu"]
    span = float(np.ptp(native.output))
    return BenchResult(
        name=FMU_PLANT,
        description="seed 002 plant as an FMI 3.0 model-exchange FMU in the compiled loop, "
        "P K=10, 20 s of pulses at 100 Hz, against the native composition",
        simulated_s=20.0,
        median_s=fmu_s,
        reference_s=native_s,
        ratio=native_s / fmu_s,
        runs=runs,
        reference_runs=runs,
        integration_steps=fmu.integration_steps,
        error={
            "position": float(np.max(np.abs(fmu.output - native.output))) / span,
            "steps": float(fmu.integration_steps - native.integration_steps),
        },
        extra={"wall_s": fmu_s, "native_ms": 1e3 * native_s, "slowdown": fmu_s / native_s},
    )


def run_study_case(
    *, trials: int = 300, workers: int = 2, root: Path | None = None, study: str = "dinca_flc"
) -> BenchResult:
    """``trials`` trials of ``studies/<study>.yaml`` from scratch on ``workers`` processes.

    Reports the wall time and how the trials' time (summed over the workers) splits:
    simulation (the trial's simulations and metrics), sampler, building the controllers,
    and storage (the rest of each trial: writing it, and the storage reads outside the
    sampler); for a robust study also the simulations per second of wall time and the
    sampled plants its pruned or failed trials skipped.
    """
    import tempfile

    from fuzzyservo.io.studies import load_study
    from fuzzyservo.tuning.outcome import time_split
    from fuzzyservo.tuning.runner import run_study

    root = root or data_root()
    spec = load_study(root / "studies" / f"{study}.yaml")
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        outcome = run_study(spec, Path(tmp), trials=trials, workers=workers, progress=False)
        wall = time.perf_counter() - t0
    split = time_split(outcome)
    line = outcome.timeline
    limit = outcome.sim_time_s / workers
    told = outcome.trials_complete + outcome.trials_pruned
    return BenchResult.once(
        ROBUST_STUDY if spec.uncertainty is not None else STUDY,
        f"{trials} trials of studies/{study}.yaml on {workers} worker processes, SQLite storage",
        wall,
        error={
            "best_objective": outcome.best.values[0],
            "baseline_objective": outcome.baseline.values[0],
        },
        extra={
            "trials": told,
            "workers": workers,
            "simulation_s": outcome.sim_time_s,
            # the physical limit: the trials' simulations (margin checks included) spread
            # over the workers with nothing else to do
            "limit_s": limit,
            "of_limit": wall / limit if limit > 0 else math.nan,
            "trials_per_s": told / wall,
            "trials_pruned": outcome.trials_pruned,
            "simulations": outcome.simulations,
            "simulations_per_s": outcome.simulations / wall,
            "samples_skipped": outcome.samples_skipped,
            **{f"{k}_s": v for k, v in split.items()},
            **{
                k: line.get(k, math.nan)
                for k in ("startup_s", "trials_s", "finish_s", "idle_s", "parent_wait_s")
            },
        },
    )


def run_robust_study_case(
    *, trials: int = 300, workers: int = 2, root: Path | None = None
) -> BenchResult:
    """``studies/dinca_robust.yaml`` from scratch: ``trials`` trials, each on the study's 8
    sampled plants and 2 scenarios (delay and noise on) plus its gain-margin checks;
    trials/s and simulations/s against the wall."""
    return run_study_case(trials=trials, workers=workers, root=root, study="dinca_robust")


def run_fuzzy_eval(
    controller_file: str = "studies/controllers/flc2_reshaped.yaml",
    *,
    points: int = 10_000,
    timed_calls: int = 300,
    runs: int = 7,
    root: Path | None = None,
) -> BenchResult:
    """Compiled evaluator against ``skfuzzy`` ``ControlSystemSimulation.compute``.

    Times one evaluation of each (median over ``runs`` batches; scikit-fuzzy on
    ``timed_calls`` inputs), and reports the largest deviation over ``points`` random
    inputs drawn from 1.5× the input ranges (so some lie outside and are clipped), as a
    fraction of the output span.
    """
    from fuzzyservo.controllers.fuzzy.skfuzzy_adapter import SkfuzzyReference
    from fuzzyservo.io.controllers import load_controller

    root = root or data_root()
    controller = load_controller(root / controller_file)
    system = controller.system
    x = random_inputs(system, points)
    e = x[:, 0]
    de = x[:, 1] if x.shape[1] > 1 else None
    controller.curve(e[:10], None if de is None else de[:10])  # compile
    fast_times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        fast = controller.curve(e, de)
        fast_times.append((time.perf_counter() - t0) / points)
    reference_runs = max(1, runs // 2)
    with SkfuzzyReference(system) as ref:
        ref_times = []
        for _ in range(reference_runs):
            t0 = time.perf_counter()
            for row in x[:timed_calls]:
                ref.compute(*row)
            ref_times.append((time.perf_counter() - t0) / timed_calls)
        slow = ref.compute_many(x)
    span = system.output.high - system.output.low
    median_s = statistics.median(fast_times)
    reference_s = statistics.median(ref_times)
    return BenchResult(
        name=FUZZY_EVAL,
        description=f"one evaluation of {controller.name} against skfuzzy compute(), {points} random inputs",
        simulated_s=0.0,
        median_s=median_s,
        reference_s=reference_s,
        ratio=reference_s / median_s,
        runs=runs,
        reference_runs=reference_runs,
        integration_steps=0,
        error={
            "max_deviation_of_span": float(
                np.max(np.abs(fast / controller.output_gain - slow)) / span
            )
        },
    )


def random_inputs(system, points: int, seed: int = 2024) -> np.ndarray:
    """Uniform random inputs over 1.5× each input range (a sixth of them outside it)."""
    rng = np.random.default_rng(seed)
    cols = []
    for var in system.inputs:
        mid, half = 0.5 * (var.low + var.high), 0.5 * (var.high - var.low)
        cols.append(rng.uniform(mid - 1.5 * half, mid + 1.5 * half, points))
    return np.column_stack(cols)


def run_case(
    case: BenchCase, *, runs: int = 7, reference_runs: int = 3, root: Path | None = None
) -> BenchResult:
    """Warm up, time the compiled loop and the reference, and measure the accuracy."""
    from fuzzyservo.io.controllers import load_controller
    from fuzzyservo.io.rigs import load_rig

    root = root or data_root()
    rig = load_rig(root / case.rig_file)
    controller = load_controller(root / case.controller_file)
    simulate(rig, controller, case.scenario, duration_s=case.duration_s)  # compile / warm caches
    median_s, fast = _median_time(
        lambda: simulate(rig, controller, case.scenario, duration_s=case.duration_s), runs
    )
    reference_s, _ = _median_time(
        lambda: simulate_reference(
            rig, controller, case.scenario, duration_s=case.duration_s, rtol=1e-6
        ),
        reference_runs,
    )
    tight = simulate_reference(
        rig, controller, case.scenario, duration_s=case.duration_s, rtol=1e-9
    )
    return BenchResult(
        name=case.name,
        description=case.description,
        simulated_s=case.duration_s,
        median_s=median_s,
        reference_s=reference_s,
        ratio=reference_s / median_s,
        runs=runs,
        reference_runs=reference_runs,
        integration_steps=fast.integration_steps,
        error=accuracy(fast, tight),
    )


def duration_text(seconds: float) -> str:
    """A wall time in µs, ms or s."""
    if seconds < 1e-3:
        return f"{seconds * 1e6:.2f}µs"
    if seconds < 1.0:
        return f"{seconds * 1e3:.2f}ms"
    return f"{seconds:.3f}s"


@dataclass(frozen=True)
class BenchOptions:
    """How long each case runs: timed runs, reference runs, a study's trials and workers."""

    runs: int = 7
    reference_runs: int = 3
    study_trials: int = 300
    workers: int = 2


def _line(r: BenchResult, template: str | None) -> str:
    """A case's row after its name: the timings against the reference, or for a case
    timed once (``template``, over its ``extra`` figures) its wall time and figures."""
    errors = ", ".join(f"{k} {v:.3g}" for k, v in r.error.items())
    if template is None:
        return (f"{duration_text(r.median_s):>10} {duration_text(r.reference_s):>10} "
                f"{r.ratio:>6.0f}×  {errors}")  # fmt: skip
    x = {**r.extra, "errors": errors}
    if "added" in x:
        x["added"] = ", ".join(x["added"]) or "none"
    row = template.format(**x)
    if "calibrate_cold_s" in x:
        row += (f"; calibrate on it, empty cache {x['calibrate_cold_s']:.1f} s, warm "
                f"{x['calibrate_warm_s']:.1f} s: +{x['calibrate_extra_s']:.1f} s (goal ≤ 10 s)")  # fmt: skip
    return f"{duration_text(x['wall_s']):>10} {'':>10} {'':>7}  " + row


_STUDY_TIMES = (
    "wall = startup {startup_s:.1f} s + trials {trials_s:.1f} s (workers idle {idle_s:.1f} s "
    "in all; the parent waited {parent_wait_s:.1f} s for them) + finish {finish_s:.1f} s; simulation {simulation_s:.1f} s, on {workers} workers "
    "at least {limit_s:.1f} s: {of_limit:.2f}× that (goal ≤ 1.15×); sampler {sampler_s:.1f} s, "
    "storage {storage_s:.1f} s, building {building_s:.2f} s; {errors}"
)
_STUDY_LINE = "{trials} trials on {workers} workers, {trials_per_s:.1f} trials/s; " + _STUDY_TIMES
_ROBUST_STUDY_LINE = (
    "{trials} trials on {workers} workers ({trials_pruned} pruned, {samples_skipped} sampled "
    "plants skipped), {trials_per_s:.1f} trials/s, {simulations} simulations, "
    "{simulations_per_s:.0f} simulations/s; " + _STUDY_TIMES
)
_MARGINS_LINE = "{simulations} simulations of 22 s, {ms_per_simulation:.0f} ms each; {errors}"
_CALIBRATE_LINE = (
    "wall_s {wall_s:.1f} (budget {budget_s:.0f} s) on {workers} workers; {replays} replays "
    "of 30 s, {replay_ms:.0f} ms of wall time each; added {added}; {errors}"
)
_COMPILE_LINE = (
    "first simulate dinca_cylinder p_k10 {first_s:.1f} s wall (compiling {first_compile_s:.1f} s; "
    "goal ≤ 20 s), warm {warm_s:.1f} s; a new composition {new_rig_s:.1f} s, warm "
    "{new_rig_warm_s:.1f} s: +{new_rig_extra_s:.1f} s (goal ≤ 3 s)"
)
_FMU_LINE = (
    "median of the FMU plant; the native composition {native_ms:.0f} ms: {slowdown:.2f}× "
    "(goal ≤ 3×); {errors}"
)

#: every case by name, in the order ``benchmark`` runs them: how to run it, and the
#: template of its row for a case timed once (None: timed against the reference)
REGISTRY: dict[str, tuple[Callable[[BenchOptions], BenchResult], str | None]] = {
    FUZZY_EVAL: (lambda o: run_fuzzy_eval(runs=o.runs), None),
    **{
        c.name: (lambda o, c=c: run_case(c, runs=o.runs, reference_runs=o.reference_runs), None)
        for c in CASES
    },
    STUDY: (lambda o: run_study_case(trials=o.study_trials, workers=o.workers), _STUDY_LINE),
    CALIBRATE: (lambda o: run_calibrate_case(workers=o.workers), _CALIBRATE_LINE),
    CALIBRATE_SEGMENTS: (
        lambda o: run_calibrate_case(workers=o.workers, segments=True),
        _CALIBRATE_LINE,
    ),
    MARGINS: (lambda o: run_margins_case(), _MARGINS_LINE),
    FMU_PLANT: (lambda o: run_fmu_plant_case(runs=o.runs), _FMU_LINE),
    COMPILE: (lambda o: run_compile_case(), _COMPILE_LINE),
    ROBUST_STUDY: (
        lambda o: run_robust_study_case(trials=o.study_trials, workers=o.workers),
        _ROBUST_STUDY_LINE,
    ),
}


@dataclass(frozen=True)
class BenchReport(Result):
    """The cases run, in order; ``text()`` is the table ``fuzzyservo bench`` prints."""

    results: tuple[BenchResult, ...]

    def text(self) -> str:
        lines = [f"{'case':<20} {'median':>10} {'reference':>10} {'ratio':>7}  error"]
        lines += [f"{r.name:<20} {_line(r, REGISTRY[r.name][1])}" for r in self.results]
        lines.append(
            "reference: scipy solve_ivp (LSODA, rtol 1e-6) per control interval, or skfuzzy compute();"
        )
        lines.append(
            "error: largest deviation from solve_ivp at rtol 1e-9, or from compute() (fraction of output span)"
        )
        return "\n".join(lines)

    def to_dict(self) -> dict:
        return {"cases": [r.to_dict() for r in self.results]}


def benchmark(
    cases: Sequence[str] | None = None,
    options: BenchOptions | None = None,
    progress: ProgressBar | None = None,
) -> BenchReport:
    """Run the named cases of :data:`REGISTRY` (default: all) in order; ``progress``
    shows each case's name while it runs and counts it when done."""
    options = options or BenchOptions()
    wanted = list(cases or REGISTRY)
    unknown = [c for c in wanted if c not in REGISTRY]
    if unknown:
        raise ConfigError(
            f"unknown bench case {unknown[0]!r}; {did_you_mean(unknown[0], REGISTRY)}"
            f"known: {', '.join(REGISTRY)}"
        )
    results = []
    for name in wanted:
        if progress is not None:
            progress.set_description(name)
        results.append(REGISTRY[name][0](options))
        if progress is not None:
            progress.update(1)
    return BenchReport(tuple(results))
