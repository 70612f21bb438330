"""Command line: parse the arguments, call one public function, print its result.

Every command is a function of the library (``fuzzyservo.compare``, ``margins``,
``robustness`` ...) that returns a result object; here are only the files it reads and
writes, the options it checks and the lines it prints. Every user error becomes one line
on stderr and exit status 2.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import NoReturn

from fuzzyservo.errors import ConfigError, FuzzyservoError
from fuzzyservo.io.jsonfile import write_json
from fuzzyservo.io.paths import find_file as resolve  # a path, or a name under rigs/, studies/
from fuzzyservo.io.paths import output_dir as _out_dir
from fuzzyservo.io.paths import output_file as _out_file
from fuzzyservo.progress import note_compiling, progress_bar, warnings_as_lines
from fuzzyservo.tuning import MAIN_STUDY as DEFAULT_STUDY

DEFAULT_RIG = "dinca_cylinder"
DEFAULT_CONTROLLER = "p_k10"
DEFAULT_DESIGN = "flc2_reshaped"
EXIT_USAGE = 2
EXIT_FAILED_RUN = 1


# --------------------------------------------------------------------------- files
def _load(rig_name: str, controller_names: Sequence[str]):
    """The rig and controllers named (paths, or shipped names: ``load_rig`` finds both)."""
    from fuzzyservo.io.controllers import load_controller
    from fuzzyservo.io.rigs import load_rig

    return load_rig(rig_name), [load_controller(c) for c in controller_names]


def _load_fuzzy(name: str):
    from fuzzyservo.io.evaluation import load_fuzzy_controller

    return load_fuzzy_controller(resolve(name, "studies/controllers", "controller"))


def _checked_duration(rig, duration: float | None) -> float | None:
    """``--duration`` against the rig's sample time (>= a sample, <= what a run holds)."""
    from fuzzyservo.limits import duration_problem

    if duration is not None and duration_problem(duration, rig.sample_time_s):
        raise ConfigError(f"--duration: {duration_problem(duration, rig.sample_time_s)}")
    return duration


def _at_least(low: int, **options: int | None) -> None:
    for name, value in options.items():
        if value is not None and value < low:
            raise ConfigError(f"--{name.replace('_', '-')} must be >= {low}, got {value}")


def _plant_samples(**options: int | None) -> None:
    """Counts of sampled plants within what a run holds (limits.MAX_PLANT_SAMPLES)."""
    from fuzzyservo.limits import plant_samples_problem

    for name, value in options.items():
        if value is not None and plant_samples_problem(value):
            raise ConfigError(f"--{name.replace('_', '-')}: {plant_samples_problem(value)}")


def _json(path: str | None, result) -> None:
    if path:
        write_json(path, result)
        print(f"JSON written to {path}")


# --------------------------------------------------------------------------- commands
def cmd_compare(args: argparse.Namespace) -> int:
    """``compare`` (default: the seed-002 baseline) and ``simulate`` (one controller)."""
    from fuzzyservo.analysis.compare import compare

    out, json_path = _out_dir(args.out), _out_file(args.json, "--json")
    single = args.command == "simulate"
    names = [args.controller] if single else args.controllers or [DEFAULT_CONTROLLER]
    rig, controllers = _load(args.rig, names)
    rig.scenario(args.scenario)
    if single:
        note_compiling()
    result = compare(rig, controllers, args.scenario,
                     duration_s=_checked_duration(rig, args.duration))  # fmt: skip
    print(result.text())
    for problem in result.problems:
        print(problem, file=sys.stderr)
    if out is not None:
        from fuzzyservo.io.outputs import save_comparison

        save_comparison(result, out)
        print(f"plots and signals written to {out}/")
    _json(json_path, result)
    return EXIT_FAILED_RUN if result.failed else 0


def cmd_margins(args: argparse.Namespace) -> int:
    from fuzzyservo.analysis import margins

    json_path = _out_file(args.json, "--json")
    rig, (controller,) = _load(args.rig, [args.controller])
    rig.scenario(args.scenario)
    note_compiling()
    result = margins(rig, controller, args.scenario)
    print(result.text())
    _json(json_path, result)
    return 0


def cmd_frequency(args: argparse.Namespace) -> int:
    from fuzzyservo.analysis import frequency_response
    from fuzzyservo.io.outputs import save_bode

    out, json_path = _out_dir(args.out), _out_file(args.json, "--json")
    if args.amplitude is not None and not (math.isfinite(args.amplitude) and args.amplitude > 0):
        raise ConfigError(f"--amplitude {args.amplitude}: must be a positive number in the feedback unit")  # fmt: skip
    rig, (controller,) = _load(args.rig, [args.controller])
    scenario = rig.scenario(args.scenario).name
    note_compiling()
    result = frequency_response(rig, controller, amplitude=args.amplitude, scenario=scenario)
    print(result.text())
    if out is not None:
        print(f"Bode plot written to {save_bode(result, out)}")
    _json(json_path, result)
    return 0


def cmd_show(args: argparse.Namespace) -> int:
    from fuzzyservo.controllers.fuzzy.describe import describe_fuzzy
    from fuzzyservo.io.outputs import save_fuzzy_figures

    out = _out_dir(args.out)
    controller = _load_fuzzy(args.controller)
    print(describe_fuzzy(controller))
    save_fuzzy_figures(controller, out, source=args.controller)
    shape = "curve" if len(controller.system.inputs) == 1 else "surface"
    print(f"membership functions and control {shape} written to {out}/")
    return 0


def cmd_export(args: argparse.Namespace) -> int:
    from fuzzyservo.workflows import export_file

    result = export_file(args.controller, fis=args.fis, fcl=args.fcl, c_dir=args.c, st=args.st,
                         fmu=args.fmu, fmi=args.fmi, lut=args.lut, sample_time_s=args.sample_time,
                         real="float" if args.float else "double")  # fmt: skip
    for note in result.notes:
        print(note, file=sys.stderr)
    print(result.text())
    return 0


def cmd_evaluate(args: argparse.Namespace) -> int:
    from fuzzyservo.workflows import evaluate

    _out_file(args.out, "--out", "out.csv")
    source = resolve(args.controller, "studies/controllers", "controller")
    result = evaluate(source, args.inputs, args.semantics)
    for note in result.notes:
        print(note, file=sys.stderr)
    if args.out:
        result.write(args.out)
        s = result.system
        print(f"{len(result.inputs)} row(s) of {s.name!r} ({s.semantics} semantics) written to {args.out}")  # fmt: skip
    else:
        print(result.text())
    return 0


def cmd_tune(args: argparse.Namespace) -> int:
    from fuzzyservo.io.studies import load_study, with_warm_start
    from fuzzyservo.tuning.runner import run_study
    from fuzzyservo.tuning.spec import storage_problem
    from fuzzyservo.workflows import write_study_report

    _at_least(1, trials=args.trials, workers=args.workers, batch_size=args.batch_size)
    _at_least(0, check_samples=args.check_samples)
    _plant_samples(check_samples=args.check_samples)
    if args.storage and storage_problem(args.storage):
        raise ConfigError(f"--storage: {storage_problem(args.storage)}")
    _out_file(args.json, "--json")
    spec = load_study(resolve(args.study, "studies", "study"))
    if args.patience is not None or args.warm_start:
        spec = with_warm_start(spec, args.warm_start, args.patience)
    out = _out_dir(args.out) or Path("out") / spec.name
    _out_dir(str(out))
    total, workers = args.trials or spec.trials, args.workers or spec.workers
    print(f"study {spec.name}: {spec.objective.describe()}; {total} trials, {workers} worker(s)")
    if spec.uncertainty is not None:
        print(f"uncertainty: {spec.uncertainty.describe()}")
    note_compiling()
    try:
        outcome = run_study(spec, out, trials=total, storage=args.storage, workers=workers,
                            cluster=args.cluster, batch_size=args.batch_size,
                            asynchronous=args.asynchronous)  # fmt: skip
    except KeyboardInterrupt:
        print("fuzzyservo: interrupted; completed trials are kept: run the same command to "
              "resume", file=sys.stderr)  # fmt: skip
        return 130
    print(f"storage: {outcome.storage_url}")
    check, bar = args.check_samples, None
    if spec.uncertainty is not None and check != 0:
        n = spec.uncertainty.samples if check is None else check
        print(f"checking the best against the baseline and the template on {n} fresh samples")
        bar = progress_bar((3 - (spec.template == spec.baseline)) * n, "check")  # best, base, tpl
    report, paths = write_study_report(outcome, out, check_samples=check,
                                       progress=bar and bar.update)  # fmt: skip
    if bar is not None:
        bar.close()
    print(report.text())
    print(f"report: {paths['report']}")
    print(f"the command took {_took()} (the optimisation {_took(outcome.wall_s)})")
    _json(args.json, report.to_dict())
    return 0


def cmd_robustness(args: argparse.Namespace) -> int:
    """Monte Carlo of controllers on plants sampled from a study's ``uncertainty:``."""
    from fuzzyservo.io.studies import load_study
    from fuzzyservo.tuning.uncertainty.montecarlo import plan

    _at_least(1, samples=args.samples, workers=args.workers)
    _plant_samples(samples=args.samples)
    if args.gain_margin is not None and not args.gain_margin > 1:
        raise ConfigError(f"--gain-margin must be > 1, got {args.gain_margin}")
    _out_file(args.json, "--json")
    out = _out_dir(args.out)
    rig, controllers = _load(args.rig, args.controllers or [DEFAULT_CONTROLLER])
    study = load_study(resolve(args.uncertainty, "studies", "study"))
    setup = plan(rig, controllers, study, samples=args.samples, seed=args.seed,
                 scenarios=args.scenario)  # fmt: skip
    print(setup.describe())
    note_compiling()
    bar = progress_bar(setup.steps, "robustness")
    result = setup.run(args.gain_margin, progress=bar.update, workers=args.workers,
                       cluster=args.cluster)  # fmt: skip
    bar.close()
    print(result.text())
    if out is not None:
        from fuzzyservo.io.outputs import save_robustness

        save_robustness(result, out)
        print(f"plots written to {out}/")
    _json(args.json, result)
    return EXIT_FAILED_RUN if result.failed and args.strict else 0


def cmd_reproduce(args: argparse.Namespace) -> int:
    from fuzzyservo.io.reproduction import load_reproduction, write_reproduction

    json_path, markdown = _out_file(args.json, "--json"), _out_file(args.markdown, "--markdown")
    note_compiling()
    result = load_reproduction().run(args.seeds or None, sensitivity=not args.rows_only)
    print(result.text())
    for path in write_reproduction(result, json_path=json_path, markdown_path=markdown):
        print(f"written to {path}")
    return 0


def cmd_designer(args: argparse.Namespace) -> int:
    from fuzzyservo.designer import serve

    rig = resolve(args.rig, "rigs", "rig")
    controller = resolve(args.controller, "studies/controllers", "controller")
    serve(rig, controller, port=args.port, host=args.host, out_dir=args.out, show=args.show,
          allow_hosts=tuple(args.allow_host), storages=tuple(args.storage))  # fmt: skip
    return 0


def cmd_fit_valve(args: argparse.Namespace) -> int:
    """Train the seed-003 valve network on a valve-data CSV and write it as JSON."""
    from fuzzyservo.io.valve_data import network_file
    from fuzzyservo.workflows import fit_valve

    _at_least(1, restarts=args.restarts)
    _out_file(args.out, "--out")
    # the rig's own file (a shipped one too) is replaced only when --into-rig asks for it
    if args.rig is None and args.into_rig:
        raise ConfigError("--into-rig needs --rig RIG, the rig whose network file to replace")
    rig_file = network_file(resolve(args.rig, "rigs", "rig")) if args.rig else None
    name = rig_file.name if rig_file else "valve_network.json"
    out = Path(args.out) if args.out else rig_file if args.into_rig else Path("out") / name
    bar = progress_bar(args.restarts, "restarts")
    try:
        result = fit_valve(args.data, out, seed=args.seed, restarts=args.restarts,
                           progress=lambda k: bar.update(1))  # fmt: skip
    finally:
        bar.close()
    print(result.text())
    if rig_file is not None and out.resolve() != rig_file.resolve():
        print(f"the rig reads {rig_file}: use --into-rig to replace it, or point its weights "
              f"at {out}")  # fmt: skip
    return 0


def cmd_calibrate(args: argparse.Namespace) -> int:
    from fuzzyservo.calibration import prepare
    from fuzzyservo.io.calibration_report import write_calibration
    from fuzzyservo.io.controllers import load_controller
    from fuzzyservo.io.measured import read_rig_data
    from fuzzyservo.io.rigs import load_rig

    out = _out_dir(args.out)
    _out_file(args.json, "--json")
    _at_least(0, max_effects=args.max_effects, bootstrap_draws=args.bootstrap_draws)
    _at_least(1, workers=args.workers)
    rig = load_rig(resolve(args.rig, "rigs", "rig"))
    controller = (load_controller(resolve(args.controller, "studies/controllers", "controller"))
                  if args.controller else None)  # fmt: skip
    effects = [e.strip() for e in args.effects.split(",") if e.strip()] if args.effects else None
    records = [read_rig_data(d, rig.measured, resample=args.resample) for d in args.data]
    setup = prepare(rig, records[0] if len(records) == 1 else records, controller, effects=effects,
                    per_record=(args.per_record or "").split(","), segments=args.segments)  # fmt: skip
    print(setup.describe())
    bar = progress_bar(setup.steps(args.max_effects), "candidates")
    try:
        result = setup.run(max_effects=args.max_effects, workers=args.workers, cluster=args.cluster,
                           progress=lambda name: (bar.set_postfix_str(name), bar.update(1)),
                           bootstrap_draws=args.bootstrap_draws)  # fmt: skip
    finally:
        bar.close()
    stem = Path(args.data[0]).stem + (f"+{len(args.data) - 1}" if len(args.data) > 1 else "")
    out = out or _out_dir(str(Path("out") / f"calibrate_{rig.name}_{stem}"))
    paths = write_calibration(result, out, ", ".join(Path(d).name for d in args.data))
    print(f"report: {paths['report']}")
    if "rig" in paths:
        print(f"calibrated rig: {paths['rig']}")
    rig_path = {"calibrated_rig": str(paths["rig"])} if "rig" in paths else {}
    _json(args.json, result.to_dict() | rig_path)  # summary.json
    print(f"the command took {_took()} (the search {_took(result.outcome.seconds)})")
    print(result.text())  # the verdict last: what an engineer reads first
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    from fuzzyservo.bench import REGISTRY, BenchOptions, benchmark

    options = BenchOptions(args.runs, args.reference_runs, args.study_trials, args.workers)
    _at_least(1, runs=args.runs, reference_runs=args.reference_runs,
              study_trials=args.study_trials, workers=args.workers)  # fmt: skip
    _out_file(args.json, "--json")
    bar = progress_bar(len(args.case or REGISTRY), "bench")
    report = benchmark(args.case, options, progress=bar)
    bar.close()
    print(report.text())
    _json(args.json, report)
    return 0


# --------------------------------------------------------------------------- parser
class _Parser(argparse.ArgumentParser):
    """argparse with its errors on one line (what, and where to read the usage)."""

    def error(self, message: str) -> NoReturn:
        import re

        from fuzzyservo.errors import did_you_mean

        choice = re.search(r"invalid choice: '([^']*)' \(choose from (.*)\)", message)
        if choice:  # a misspelt command or choice: name the closest
            hint = did_you_mean(choice.group(1), re.findall(r"'([^']*)'", choice.group(2)))
            message = message.replace("(choose from", f"({hint}choose from") if hint else message
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message}; see {self.prog} --help\n")


def _seconds(text: str) -> float:
    """A ``--duration``: a finite number of seconds above zero."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a positive number of seconds, got {text}")
    return value


def _port(text: str) -> int:
    """A ``--port``: a TCP port number (0: any free port)."""
    from fuzzyservo.limits import port_problem

    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a port number") from None
    if port_problem(value):
        raise argparse.ArgumentTypeError(port_problem(value))
    return value


def _arg(*names: str, **options) -> tuple[tuple[str, ...], dict]:
    return names, options


RIG = _arg("rig", help="rig file or name under rigs/")
CONTROLLER = _arg("controller", help="controller file or name under studies/controllers/")
FUZZY = "fuzzy controller file (YAML or .fis) or name"
SCENARIO = _arg("--scenario", help="scenario of the rig (default: its first)")
SIM = [  # simulate and compare
    _arg("--scenario", help="scenario of the rig file (default: its first)"),
    _arg("--duration", type=_seconds, help="simulated time [s] (default: the scenario's)"),
    _arg("--out", default="out", help="folder for plots and CSV signals (default: out)"),
    _arg("--json", metavar="FILE", help="also write the results as JSON"),
]
CLUSTER = _arg("--cluster", metavar="tcp://HOST:PORT",
               help="compute on this Dask scheduler's workers (extra: fuzzyservo[cluster])")  # fmt: skip
TUNE = [
    _arg("study", nargs="?", default=DEFAULT_STUDY,
         help=f"study file or name under studies/ (default: {DEFAULT_STUDY})"),
    _arg("--trials", type=int, help="complete trials the study should hold (default: the study's)"),
    _arg("--storage",
         help="Optuna storage URL, e.g. postgresql://user@host/db (default: SQLite in --out)"),
    _arg("--workers", type=int, help="local worker processes (default: the study's, else 1)"),
    CLUSTER,
    _arg("--batch-size", type=int, help="trials in flight (default: the study's, else 4)"),
    _arg("--async", dest="asynchronous", action="store_true",
         help="each worker runs its own Optuna loop on the shared storage: not reproducible"),
    _arg("--out", help="output folder (default: out/<study name>)"),
    _arg("--json", metavar="FILE", help="also write summary.json here"),
    _arg("--patience", type=int,
         help="stop when the best has not improved for this many trials (default: the study's)"),
    _arg("--warm-start", action="append", default=[], metavar="CONTROLLER",
         help="try this controller's numbers first (a previous best, a named controller; repeat)"),
    _arg("--check-samples", type=int, metavar="N",
         help="robust studies: compare the best with the baseline and the template on N fresh "
         "sampled plants in the report (default: the study's sample count; 0: skip)"),
]  # fmt: skip
ROBUSTNESS = [
    RIG,
    _arg("controllers", nargs="+", help="controller files or names"),
    _arg("--samples", type=int, default=200, help="sampled plants (default: 200)"),
    _arg("--uncertainty", default=DEFAULT_STUDY,
         help=f"study whose 'uncertainty:' section is sampled (default: {DEFAULT_STUDY})"),
    _arg("--seed", type=int, default=None,
         help="sampling seed (default: the one a study report's check uses, so both draw the "
         "same plants; not the study's)"),
    _arg("--gain-margin", type=float, default=2.0,
         help="check on every sample that the loop holds this gain margin (default: 2)"),
    _arg("--scenario", action="append", help="scenario (repeat; default: the study's)"),
    _arg("--out", default="out", help="folder for the plots (default: out)"),
    _arg("--json", metavar="FILE", help="also write the table as JSON"),
    _arg("--strict", action="store_true", help="exit 1 when any sample fails"),
    _arg("--workers", type=int, default=1, help="local processes sharing the samples (default: 1)"),
    CLUSTER,
]  # fmt: skip
EXPORT = [
    _arg("controller", help=f"{FUZZY} under studies/controllers/, any .fis/.fcl system, a rig"),
    _arg("--fis", metavar="FILE", help="the .fis file to write"),
    _arg("--fcl", metavar="FILE", help="the IEC 61131-7 FCL file to write"),
    _arg("--c", metavar="DIR", help="write <name>.c and <name>.h (C99) into DIR"),
    _arg("--st", metavar="FILE", help="the IEC 61131-3 Structured Text file to write"),
    _arg("--fmu", metavar="FILE", help="the FMU to write (FILE.fmu): a controller's "
         "co-simulation, a rig's plant for model exchange and co-simulation"),
    _arg("--fmi", type=int, choices=(2, 3), default=3, help="FMI version of --fmu (default: 3)"),
    _arg("--lut", type=int, metavar="N",
         help="code with a lookup table of N points per input instead of the evaluator; "
         "prints its largest error"),
    _arg("--float", action="store_true", help="single precision (default: double)"),
    _arg("--sample-time", type=float, default=0.01, metavar="S",
         help="controller sample time [s] for the error rate and form pi (default: 0.01)"),
]  # fmt: skip
EVALUATE = [
    _arg("controller", help=".fis, .fcl or fuzzy controller file, or a name"),
    _arg("inputs", help="CSV with one column per input variable, named like it"),
    _arg("--semantics", choices=("skfuzzy", "matlab"),
         help="skfuzzy (sampled universes) or matlab (evalfis: exact membership, 101 output "
         "points); default: the file's (skfuzzy unless it says otherwise)"),
    _arg("--out", metavar="OUT.csv", help="write the outputs here (default: print)"),
]  # fmt: skip
DESIGNER = [
    _arg("rig", nargs="?", default=DEFAULT_RIG, help=f"rig file or name (default: {DEFAULT_RIG})"),
    _arg("controller", nargs="?", default=DEFAULT_DESIGN,
         help=f"{FUZZY} (default: {DEFAULT_DESIGN})"),
    _arg("--port", type=_port, default=5006,
         help="port, 1-65535 (default: 5006; 0: any free port)"),
    _arg("--host", default="127.0.0.1", help="address to listen on (default: 127.0.0.1)"),
    _arg("--out", default="out/designer",
         help="the only folder the app writes to (default: out/designer)"),
    _arg("--show", action="store_true", help="open the page in the web browser"),
    _arg("--allow-host", action="append", default=[], metavar="NAME",
         help="also answer pages that reach the designer by this host name (repeat; default: "
         "127.0.0.1, localhost and --host only)"),
    _arg("--storage", action="append", default=[], metavar="URL",
         help="a database server URL the page may open studies from (repeat; SQLite files in "
         "the designer's folders need none)"),
]  # fmt: skip
FREQUENCY = [
    RIG,
    CONTROLLER,
    _arg("--scenario", help="scenario giving operating point and load (default: first)"),
    _arg("--amplitude", type=float,
         help="sine amplitude, feedback unit (default: 10 %% of the reference range)"),
    _arg("--out", default="out", help="folder for the Bode plot (default: out)"),
    _arg("--json", metavar="FILE", help="also write the response as JSON"),
]  # fmt: skip
BENCH = [
    _arg("--json", metavar="FILE", help="write the figures as JSON"),
    _arg("--case", action="append", help="run only this case (repeatable)"),
    _arg("--runs", type=int, default=7, help="timed runs per case (median reported)"),
    _arg("--reference-runs", type=int, default=3, help="timed runs of the reference path"),
    _arg("--study-trials", type=int, default=300, help="trials of the study case (default: 300)"),
    _arg("--workers", type=int, default=2,
         help="worker processes of the study and calibrate cases (default: 2)"),
]  # fmt: skip
CALIBRATE = [
    _arg("rig", help="rig file or name in rigs/"),
    _arg("data", nargs="+",
         help="measured data: CSV with <signal>_<unit> columns, or .mat; several files are "
         "calibrated together (shared effects and unknowns)"),
    _arg("--per-record", help="comma-separated rig-file keys of unknowns (fit: [lower, "
         "upper]) fitted once per data file, e.g. bias_current (default: all shared)"),
    _arg("--controller",
         help="replay closed loop through this controller from the data's ref column "
         "(default: open loop from the recorded i or u)"),
    _arg("--out", help="output folder (default out/calibrate_<rig>_<data>)"),
    _arg("--json", help="also write the summary JSON here"),
    _arg("--effects", help="comma-separated candidate effects (default: the whole library but entrained_air)"),
    _arg("--max-effects", type=int, default=2, help="effects to add at most (default 2)"),
    _arg("--bootstrap-draws", type=int,
         help="surrogate records of each round's null (default 200; 0: Bonferroni alone)"),
    _arg("--workers", type=int, default=os.cpu_count() or 1,
         help="processes that fit a round's candidates in parallel (default: one per core)"),
    _arg("--resample", action="store_true", help="resample uneven or repeated time stamps"),
    _arg("--segments", action="store_true", help="fit on segments restarted from the recorded state"),
    CLUSTER,
]  # fmt: skip
FIT_VALVE = [
    _arg("data", help="CSV with columns p_s_bar, u_c_V, p_a_bar, p_b_bar, q_a_l_min, q_b_l_min"),
    _arg("--out", metavar="FILE",
         help="network JSON to write (default: out/<the file name the rig gives>, "
         "else out/valve_network.json)"),
    _arg("--rig", help="rig whose network_valve weights file to write (with --into-rig; "
         "default: none)"),
    _arg("--seed", type=int, default=0, help="seed of the split and restarts (default: 0)"),
    _arg("--restarts", type=int, default=6, help="random restarts (default: 6)"),
    _arg("--into-rig", action="store_true",
         help="replace the network file the rig names (default: write out/<that file name>)"),
]  # fmt: skip
REPRODUCE = [
    _arg("seeds", nargs="*", help="seeds: 000, 001, 002, 003 (default: all)"),
    _arg("--json", metavar="FILE", help="write {rows, assumptions, explanations} as JSON"),
    _arg("--markdown", metavar="FILE", help="write the tables as Markdown (docs/reproduction.md)"),
    _arg("--rows-only", action="store_true", help="skip the sensitivity and explanation runs"),
]  # fmt: skip
COMMANDS = [  # name, help, function, arguments
    ("simulate", "simulate one controller on a rig scenario", cmd_compare, [RIG, CONTROLLER, *SIM]),
    ("compare", "compare controllers on a rig scenario: table, plots, JSON", cmd_compare, [
        _arg("rig", nargs="?", default=DEFAULT_RIG,
             help=f"rig file or name (default: {DEFAULT_RIG})"),
        _arg("controllers", nargs="*",
             help=f"controller files or names (default: {DEFAULT_CONTROLLER})"), *SIM]),
    ("tune", "run (or resume) a tuning study and report against the baseline", cmd_tune, TUNE),
    ("robustness", "Monte Carlo of controllers on sampled plants: distributions, failures, worst "
     "sample", cmd_robustness, ROBUSTNESS),
    ("show", "a fuzzy controller: terms, rules, membership functions and control curve", cmd_show,
     [_arg("controller", help=f"{FUZZY} under studies/controllers/"),
      _arg("--out", default="out", help="folder for the PNG figures (default: out)")]),
    ("export", "a fuzzy controller as .fis, FCL, C99, Structured Text or FMU; a rig's plant as an "
     "FMU", cmd_export, EXPORT),
    ("evaluate", "evaluate a fuzzy system on a table of inputs (what evalfis does)", cmd_evaluate,
     EVALUATE),
    ("designer", "web app: shape a fuzzy controller and watch the loop respond", cmd_designer,
     DESIGNER),
    ("margins", "gain and delay margin of the nonlinear loop", cmd_margins,
     [RIG, CONTROLLER, SCENARIO,
      _arg("--json", metavar="FILE", help="also write the margins as JSON")]),
    ("frequency", "closed-loop frequency response by stepped sines", cmd_frequency, FREQUENCY),
    ("bench", "speed of the compiled loop against the scipy reference path", cmd_bench, BENCH),
    ("calibrate", "replay measured data on a rig, trace the residual to missing effects, add them",
     cmd_calibrate, CALIBRATE),
    ("fit-valve", "train the seed-003 valve network on a valve-data CSV", cmd_fit_valve, FIT_VALVE),
    ("reproduce", "the seeds' observations on the model: seed against model, assumptions' "
     "sensitivity, explanation runs, validity", cmd_reproduce, REPRODUCE),
]  # fmt: skip


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="fuzzyservo",
        description="Design, simulate and tune controllers for electro-hydraulic servo systems.",
    )
    from fuzzyservo import __version__

    parser.add_argument("--version", action="version", version=f"fuzzyservo {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name, text, func, arguments in COMMANDS:
        p = sub.add_parser(name, help=text)
        for names, options in arguments:
            p.add_argument(*names, **options)
        p.set_defaults(func=func)
    return parser


_STARTED = [time.perf_counter()]


def _took(seconds: float | None = None) -> str:
    """``seconds`` (default: the time since :func:`main` started, the command's own) as text."""
    from fuzzyservo.display import elapsed_text

    return elapsed_text(time.perf_counter() - _STARTED[0] if seconds is None else seconds)


def main(argv: Sequence[str] | None = None) -> int:
    _STARTED[0] = time.perf_counter()
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return EXIT_USAGE
    try:
        with warnings_as_lines():
            return args.func(args)
    except FuzzyservoError as exc:
        print(f"fuzzyservo: error: {exc.as_option()}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("fuzzyservo: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # output piped into head & co.
        sys.stderr.close()
        return 0
    except OSError as exc:  # a file fault no writer or reader named: still one line
        from fuzzyservo.atomic import file_error

        print(f"fuzzyservo: error: {file_error(exc.filename, exc, 'use')}", file=sys.stderr)
        return EXIT_USAGE


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
