"""Command line: argument parsing wiring files -> simulation -> metrics -> tables, plots, JSON.

No numerics here. Every user error becomes one line on stderr and exit status 2.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import NoReturn

from fuzzyservo.errors import ConfigError, FuzzyservoError
from fuzzyservo.io.jsonfile import json_ready, write_json
from fuzzyservo.tuning import MAIN_STUDY as DEFAULT_STUDY

DEFAULT_RIG = "dinca_cylinder"
DEFAULT_CONTROLLER = "p_k10"
DEFAULT_DESIGN = "flc2_reshaped"
EXIT_USAGE = 2
EXIT_FAILED_RUN = 1


# --------------------------------------------------------------------------- files
def resolve(name: str, folder: str, what: str) -> Path:
    """A path as given, or a bare name looked up as ``<folder>/<name>.yaml`` (here, then in the checkout)."""
    from fuzzyservo.io.paths import find_file

    return find_file(name, folder, what)


def _load(rig_name: str, controller_names: Sequence[str]):
    from fuzzyservo.io.controllers import load_controller
    from fuzzyservo.io.rigs import load_rig

    rig = load_rig(resolve(rig_name, "rigs", "rig"))
    controllers = [
        load_controller(resolve(c, "studies/controllers", "controller")) for c in controller_names
    ]
    return rig, controllers


def _scenario_name(rig, scenario: str | None) -> str:
    if scenario is None:
        return next(iter(rig.scenarios))
    if scenario not in rig.scenarios:
        raise ConfigError(
            f"unknown scenario {scenario!r}; this rig has {', '.join(rig.scenarios)}",
            file=rig.path,
            key="scenarios",
        )
    return scenario


def _out_dir(path: str | None, option: str = "--out") -> Path | None:
    """The output folder ``path``: refused when a file of that name is in the way."""
    if path is None:
        return None
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise ConfigError(
            f"{option} {path}: is a file, not a folder; name a folder (new or existing)"
        )
    return out


def _out_file(path: str | None, option: str) -> str | None:
    """An output file ``path``: refused when it names a folder."""
    if path is not None and Path(path).is_dir():
        raise ConfigError(
            f"{option} {path}: is a folder; give a file name such as {Path(path) / 'out.json'}"
        )
    return path


def _checked_duration(rig, duration: float | None) -> float | None:
    """``--duration`` checked against the rig's sample time (at least one sample, at most
    what a run holds in memory)."""
    from fuzzyservo.limits import duration_problem

    if duration is not None and duration_problem(duration, rig.sample_time_s):
        raise ConfigError(f"--duration: {duration_problem(duration, rig.sample_time_s)}")
    return duration


def _note_compiling() -> None:
    """One line before a long silent compile (first run after install or a kernel change)."""
    from fuzzyservo._jit import cache_is_cold

    if cache_is_cold():
        print(
            "compiling the simulation kernels (first run only, after an install or a change; "
            "about a minute, cached afterwards)",
            file=sys.stderr,
            flush=True,
        )


def _at_least_one(**options: int) -> None:
    for name, value in options.items():
        if value < 1:
            raise ConfigError(f"--{name.replace('_', '-')} must be >= 1, got {value}")


# --------------------------------------------------------------------------- output
def _fmt(value: float | None) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "n/a"
    if abs(value) < 1e-9:  # rounding noise (e.g. 1e-14 % overshoot of a creeping response)
        return "0"
    mag = abs(value)
    if 1e-3 <= mag < 1e5:
        return f"{value:.4g}"
    return f"{value:.3e}"


def metrics_table(
    names: Sequence[str],
    rows: Sequence[dict[str, float]],
    unit_notes: dict[str, str],
    metrics: Sequence[str] | None = None,
) -> str:
    """A plain-text table: one row per metric (``metrics``, default all), one column per controller."""
    from fuzzyservo.metrics import METRIC_NAMES

    header = ["metric", *names]
    shown = METRIC_NAMES if metrics is None else metrics
    lines = [[f"{m}{unit_notes.get(m, '')}", *(_fmt(r.get(m)) for r in rows)] for m in shown]
    widths = [max(len(row[i]) for row in [header, *lines]) for i in range(len(header))]
    out = ["  ".join(h.ljust(w) for h, w in zip(header, widths, strict=True))]
    out.append("  ".join("-" * w for w in widths))
    out += ["  ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)) for row in lines]
    return "\n".join(out)


def _unit_notes(result) -> dict[str, str]:
    unit = result.output_unit
    return {"sse_abs": f" [{unit}]", "iae": f" [{unit}·s]", "ise": f" [{unit}²·s]", "itae": f" [{unit}·s²]",
            "peak_command": " [V]"}  # fmt: skip


def _write_csv(path: Path, result) -> None:
    import numpy as np

    cols = {"t_s": result.t, "ref_V": result.reference, "feedback_V": result.feedback, "u_V": result.command,
            f"{result.actuator_name}_{result.units.get(result.actuator_name, 'SI')}": result.actuator,
            "saturated": result.saturated.astype(float)}  # fmt: skip
    for name, values in result.signals.items():
        cols[f"{name}_{result.units[name].replace('/', '_').replace('^', '').replace('*', '')}"] = (
            values
        )
    data = np.column_stack(list(cols.values()))
    np.savetxt(path, data, delimiter=",", header=",".join(cols), comments="", fmt="%.9g")


def _report_runs(rig, scenario: str, results, out: Path | None, json_path: str | None) -> int:
    from fuzzyservo.metrics import METRIC_NAMES, applicable_metrics, heave_metrics, result_metrics

    metrics = [result_metrics(r) for r in results]
    print(
        f"rig {rig.name} · scenario {scenario} · {rig.scenarios[scenario].description}".rstrip(" ·")
    )
    shown = applicable_metrics(results[0])
    print(
        metrics_table(
            [r.controller for r in results],
            [m.aggregate for m in metrics],
            _unit_notes(results[0]),
            shown,
        )
    )
    if len(shown) < len(METRIC_NAMES):
        left_out = ", ".join(m for m in METRIC_NAMES if m not in shown)
        print(
            f"not shown: {left_out} (step metrics; this scenario's reference is tracked, not stepped)"
        )
    heave = [heave_metrics(r) for r in results]
    if any(heave):
        print(
            "compensation_pct [%]  "
            + "  ".join(
                f"{r.controller}: {_fmt(h.get('compensation_pct'))}"
                for r, h in zip(results, heave, strict=True)
            )
        )
    failed = 0
    for r in results:
        if r.status != "ok":
            print(f"{r.controller}: status {r.status}: {r.message}", file=sys.stderr)
            failed += not r.ok
    if out is not None:
        from fuzzyservo import plots

        out.mkdir(parents=True, exist_ok=True)
        fig = plots.response_figure(list(results))
        plots.save(fig, out / f"{rig.name}_{scenario}_response.png")
        for r in results:
            _write_csv(out / f"{rig.name}_{scenario}_{r.controller}.csv", r)
        print(f"plots and signals written to {out}/")
    if json_path:
        payload = {
            "rig": rig.name,
            "scenario": scenario,
            "runs": [
                {
                    "controller": r.controller,
                    "status": r.status,
                    "message": r.message,
                    **m.to_dict(),
                    **h,
                }
                for r, m, h in zip(results, metrics, heave, strict=True)
            ],
        }
        write_json(json_path, payload)
        print(f"JSON written to {json_path}")
    return EXIT_FAILED_RUN if failed else 0


# --------------------------------------------------------------------------- commands
def cmd_simulate(args: argparse.Namespace) -> int:
    from fuzzyservo.simulation import simulate

    out, json_path = _out_dir(args.out), _out_file(args.json, "--json")
    rig, (controller,) = _load(args.rig, [args.controller])
    scenario = _scenario_name(rig, args.scenario)
    _note_compiling()
    result = simulate(rig, controller, scenario, duration_s=_checked_duration(rig, args.duration))
    return _report_runs(rig, scenario, [result], out, json_path)


def cmd_compare(args: argparse.Namespace) -> int:
    from fuzzyservo.simulation import simulate

    out, json_path = _out_dir(args.out), _out_file(args.json, "--json")
    rig, controllers = _load(args.rig, args.controllers or [DEFAULT_CONTROLLER])
    scenario = _scenario_name(rig, args.scenario)
    duration = _checked_duration(rig, args.duration)
    names = [c.name for c in controllers]
    if len(set(names)) != len(names):
        raise ConfigError(
            f"two controllers share a name ({names}); give each file a distinct 'name'"
        )
    results = [simulate(rig, c, scenario, duration_s=duration) for c in controllers]
    return _report_runs(rig, scenario, results, out, json_path)


def cmd_margins(args: argparse.Namespace) -> int:
    from fuzzyservo.analysis import margins

    json_path = _out_file(args.json, "--json")
    rig, (controller,) = _load(args.rig, [args.controller])
    scenario = _scenario_name(rig, args.scenario)
    _note_compiling()
    m = margins(rig, controller, scenario)
    g, d = m.gain, m.delay
    print(f"{controller.name} on {rig.name}, scenario {scenario} ({g.runs + d.runs} runs, "
          f"{g.seconds + d.seconds:.1f} s)")  # fmt: skip
    print(f"  gain margin  {g.value:.4g}  (stable at {g.bracket[0]:.4g}, oscillating at "
          f"{g.bracket[1]:.4g}, {g.frequency_hz:.3g} Hz)")  # fmt: skip
    print(f"  delay margin {d.value * 1e3:.4g} ms extra on the rig's "
          f"{m.base_delay_s * 1e3:.4g} ms ({d.frequency_hz:.3g} Hz at onset)")  # fmt: skip
    if json_path:
        write_json(json_path, m.to_dict())
        print(f"JSON written to {json_path}")
    return 0


def cmd_frequency(args: argparse.Namespace) -> int:
    from fuzzyservo.analysis import frequency_response

    out, json_path = _out_dir(args.out), _out_file(args.json, "--json")
    if args.amplitude is not None and not (math.isfinite(args.amplitude) and args.amplitude > 0):
        raise ConfigError(
            f"--amplitude {args.amplitude}: must be a positive number in the feedback unit"
        )
    rig, (controller,) = _load(args.rig, [args.controller])
    scenario = _scenario_name(rig, args.scenario)
    _note_compiling()
    fr = frequency_response(rig, controller, amplitude=args.amplitude, scenario=scenario)
    print(f"{controller.name} on {rig.name}: closed loop around {fr.operating_point:.4g}, "
          f"amplitude {fr.amplitude:.3g}")  # fmt: skip
    print(f"  {'f [Hz]':>9} {'|T| [dB]':>9} {'phase [deg]':>11}")
    for f, mag, ph in zip(fr.frequency_hz, fr.magnitude_db, fr.phase_deg, strict=True):
        print(f"  {f:9.3g} {mag:9.2f} {ph:11.1f}")
    print(
        f"  -3 dB bandwidth {fr.bandwidth_hz:.3g} Hz, phase there {fr.phase_at_bandwidth_deg:.1f} deg"
    )
    if out is not None:
        from fuzzyservo.plots import bode_figure, save

        path = save(bode_figure(fr), out / f"bode_{rig.name}_{controller.name}.png")
        print(f"Bode plot written to {path}")
    if json_path:
        write_json(json_path, fr.to_dict())
        print(f"JSON written to {json_path}")
    return 0


def _load_fuzzy(name: str):
    from fuzzyservo.controllers.fuzzy import FuzzyController
    from fuzzyservo.io.controllers import load_controller

    path = resolve(name, "studies/controllers", "controller")
    controller = load_controller(path)
    if not isinstance(controller, FuzzyController):
        raise ConfigError(
            f"is a {type(controller).__name__} controller, not a fuzzy one; give a 'kind: fuzzy' file or a .fis",
            file=str(path),
        )
    return controller


def describe_fuzzy(controller) -> str:
    """Terms and rules in words (what MATLAB's showrule and the MF editor show)."""
    from fuzzyservo.controllers.fuzzy.system import term_index

    system = controller.system
    lines = [
        f"{controller.name}: {system.type.capitalize()}, form {controller.form}, "
        f"{len(system.rules)} rules, {system.semantics} semantics; "
        f"and {system.and_method}, or {system.or_method}, implication {system.implication}, "
        f"aggregation {system.aggregation}, defuzzification {system.defuzzification}; "
        f"gains input {controller.input_gain:g}, rate {controller.rate_gain:g}, output {controller.output_gain:g}"
    ]
    for role, var in [*(("input", v) for v in system.inputs), ("output", system.output)]:
        lines.append(f"  {role} {var.name} [{var.low:g}, {var.high:g}]")
        for t in var.terms:
            lines.append(f"    {t.name:<4} {t.shape:<8} [{' '.join(f'{p:.4g}' for p in t.params)}]")
    names = [v.name for v in system.inputs]
    for n, rule in enumerate(system.rules, start=1):
        parts = []
        for var, name, idx in zip(system.inputs, names, rule.antecedent, strict=True):
            if idx == -1:
                continue
            term = var.terms[idx if idx >= 0 else -idx - 2].name
            parts.append(f"{name} is {'not ' if idx < -1 else ''}{term}")
        joined = f" {rule.connective} ".join(parts)
        weight = f" ({rule.weight:g})" if rule.weight != 1 else ""
        k, negated = term_index(rule.consequent)
        then = f"{'not ' if negated else ''}{system.output.terms[k].name}" if k >= 0 else "(none)"
        lines.append(f"  {n}. if {joined} then {system.output.name} is {then}{weight}")
    return "\n".join(lines)


def cmd_show(args: argparse.Namespace) -> int:
    from fuzzyservo import plots

    out = _out_dir(args.out)
    controller = _load_fuzzy(args.controller)
    print(describe_fuzzy(controller))
    if controller.system.type == "sugeno":
        raise ConfigError(
            "is a Sugeno system: its output terms are functions, not sets, so there are no "
            "membership plots to draw; use `fuzzyservo evaluate` for its values",
            file=args.controller,
        )
    figures = {
        "overview": plots.fuzzy_overview_figure(controller),
        "membership": plots.membership_figure(controller),
        "curve": plots.control_curve_figure(controller),
    }
    for kind, fig in figures.items():
        plots.save(fig, out / f"{controller.name}_{kind}.png")
    print(
        f"membership functions and control {'curve' if len(controller.system.inputs) == 1 else 'surface'} written to {out}/"
    )
    return 0


def cmd_export(args: argparse.Namespace) -> int:
    targets = [args.fis, args.fcl, args.c, args.st]
    if not any(targets):
        raise ConfigError("give at least one of --fis FILE, --fcl FILE, --c DIR, --st FILE")
    if (args.lut is not None and not (args.c or args.st)) or (args.float and not args.c):
        raise ConfigError("--lut shapes the code of --c DIR or --st FILE, --float that of --c")
    if args.lut is not None and args.lut < 2:
        raise ConfigError(f"--lut needs at least 2 points per input, got {args.lut}")
    if not (math.isfinite(args.sample_time) and args.sample_time > 0):
        raise ConfigError(f"--sample-time must be > 0 s, got {args.sample_time}")
    _out_file(args.fis, "--fis")
    _out_file(args.fcl, "--fcl")
    _out_file(args.st, "--st")
    _out_dir(args.c, "--c")
    controller = _load_fuzzy(args.controller)
    gains = (controller.input_gain, controller.rate_gain, controller.output_gain)
    if (args.fis or args.fcl) and (any(g != 1.0 for g in gains) or controller.form == "pi"):
        print(
            f"note: a .fis/.fcl holds the inference system only; form {controller.form!r} and "
            f"gains (input, rate, output) = {gains} stay in the YAML file",
            file=sys.stderr,
        )
    if args.fis:
        from fuzzyservo.io.fis import write_fis

        write_fis(controller.system, args.fis)
        print(f"{controller.name} written to {args.fis}")
    if args.fcl:
        from fuzzyservo.io.fcl import write_fcl

        write_fcl(controller.system, args.fcl)
        print(f"{controller.name} written to {args.fcl} (IEC 61131-7 FCL)")
    real = "float" if args.float else "double"

    def report_table(n: int) -> None:
        from fuzzyservo.codegen import lut_error

        err = lut_error(controller, n)
        print(
            f"lookup table {n} point(s) per input: largest error {err.found:.3g} "
            f"({err.found / err.span:.2e} of the output range {err.span:g}; bound "
            f"{err.bound:.3g}), found on a grid {err.refine}x finer, before the output gain"
        )

    if args.lut is not None and args.c:
        report_table(args.lut)
    if args.c:
        from fuzzyservo.codegen import write_c

        paths = write_c(controller, args.c, args.sample_time, real, args.lut)
        print(
            f"{controller.name}: C99 ({real}, sample time {args.sample_time:g} s"
            f"{', lookup table' if args.lut else ''}) written to "
            + ", ".join(str(p) for p in paths)
        )
    if args.st:
        from fuzzyservo.codegen import write_st

        path, n = write_st(controller, args.st, args.sample_time, args.lut)
        if not args.c or args.lut is None:
            report_table(n)
        print(f"{controller.name}: IEC 61131-3 Structured Text written to {path}")
    return 0


def cmd_evaluate(args: argparse.Namespace) -> int:
    from fuzzyservo.controllers.fuzzy.evaluate import evaluate_inputs
    from fuzzyservo.io.evaluation import load_system, read_input_table, write_output_table

    system = load_system(resolve(args.controller, "studies/controllers", "controller"))
    if args.semantics:
        import dataclasses

        system = dataclasses.replace(system, semantics=args.semantics)
    names = [v.name for v in system.inputs]
    inputs, ignored = read_input_table(args.inputs, names)
    if ignored:
        print(
            f"note: column(s) {ignored} are not inputs of {system.name!r}; ignored", file=sys.stderr
        )
    outputs, silent = evaluate_inputs(system, inputs)
    if silent:
        fallback = "the middle of its range" if system.semantics == "matlab" else "NaN"
        print(
            f"warning: no rule fired for {silent} output value(s); each is {fallback} "
            f"({system.semantics} semantics)",
            file=sys.stderr,
        )
    out_names = [v.name for v in system.outputs]
    if args.out:
        write_output_table(args.out, out_names, outputs)
        print(
            f"{len(inputs)} row(s) of {system.name!r} ({system.semantics} semantics) written to {args.out}"
        )
    else:
        print(",".join(out_names))
        for row in outputs:
            print(",".join(repr(float(v)) for v in row))
    return 0


def cmd_tune(args: argparse.Namespace) -> int:
    from fuzzyservo.io.studies import load_study
    from fuzzyservo.tuning.runner import run_study
    from fuzzyservo.tuning.spec import storage_problem

    if args.trials is not None and args.trials < 1:
        raise ConfigError(f"--trials must be >= 1, got {args.trials}")
    if args.workers is not None and args.workers < 1:
        raise ConfigError(f"--workers must be >= 1, got {args.workers}")
    if args.check_samples is not None and args.check_samples < 0:
        raise ConfigError(f"--check-samples must be >= 0, got {args.check_samples}")
    if args.storage and storage_problem(args.storage):
        raise ConfigError(f"--storage: {storage_problem(args.storage)}")
    _out_file(args.json, "--json")
    spec = load_study(resolve(args.study, "studies", "study"))
    if args.patience is not None or args.warm_start:
        import dataclasses

        if args.patience is not None and args.patience < 1:
            raise ConfigError(f"--patience must be >= 1, got {args.patience}")
        warm = [str(resolve(w, "studies/controllers", "controller")) for w in args.warm_start]
        spec = dataclasses.replace(
            spec,
            patience=args.patience if args.patience is not None else spec.patience,
            warm_start=(*spec.warm_start, *warm),
        )
    out = _out_dir(args.out) or Path("out") / spec.name
    _out_dir(str(out))
    total = args.trials or spec.trials
    workers = args.workers or spec.workers
    print(f"study {spec.name}: {spec.objective.describe()}; {total} trials, {workers} worker(s)")
    if spec.uncertainty is not None:
        print(f"uncertainty: {spec.uncertainty.describe()}")
    _note_compiling()
    try:
        outcome = run_study(spec, out, trials=total, storage=args.storage, workers=workers)
    except KeyboardInterrupt:
        print(
            "fuzzyservo: interrupted; completed trials are kept: run the same command to resume",
            file=sys.stderr,
        )
        return 130
    print(f"storage: {outcome.storage_url}")
    from fuzzyservo.tuning.report import write_outputs

    check = args.check_samples
    progress = None
    if spec.uncertainty is not None and check != 0:
        n = spec.uncertainty.samples if check is None else check
        print(f"checking the best against the baseline and the template on {n} fresh samples")
        same = Path(spec.controller_file).resolve() == Path(spec.baseline_file).resolve()
        progress = _progress((2 if same else 3) * n, "check")  # best, baseline, template
    paths = write_outputs(
        outcome, out, check_samples=check, progress=progress.update if progress else None
    )
    if progress is not None:
        progress.close()
    b, base = outcome.best, outcome.baseline
    print(metrics_table(["baseline", "best"], [base.metrics, b.metrics], {}))
    print(f"objective: best {_fmt_values(b.values)} against baseline {_fmt_values(base.values)}")
    if progress is not None:
        print(comparison_text(paths["summary"]))
    print(f"report: {paths['report']}")
    if args.json:
        import shutil

        shutil.copyfile(paths["summary"], args.json)
        print(f"JSON written to {args.json}")
    return 0


def comparison_text(summary_file: Path) -> str:
    """A robust study's comparison, read back from its summary: nominal, then Monte Carlo."""
    import json

    c = json.loads(Path(summary_file).read_text(encoding="utf-8"))["comparison"]
    rows = c["controllers"]
    lines = [f"nominal plant: {'controller':<22} {'objective':>9} {'settling s':>10} "
             f"{'sse mm':>8} {'overshoot %':>11} {'gain ' + format(c['gain_margin_checked'], 'g'):>7}"]  # fmt: skip
    for r in rows:
        n = r["nominal"]
        ok = {True: "holds", False: "FAILS", None: "-"}[n["gain_margin_holds"]]
        lines.append(
            f"{'':15}{r['controller']:<22} {_fmt(_nan(n['objective'])):>9} "
            f"{_fmt(_nan(n['settling_time_s'])):>10} {_fmt(_nan(n['sse_abs']) * 1e3):>8} "
            f"{_fmt(_nan(n['overshoot_pct'])):>11} {ok:>7}"
        )
    lines.append(f"Monte Carlo on {c['samples']} fresh samples (seed {c['seed']}):")
    for r in rows:  # JSON null (undefined: never settles) back to NaN for the table
        for key in ("settling_time_s", "sse_abs", "overshoot_pct", "saturation_time_s"):
            r[key] = {q: _nan(v) for q, v in r[key].items()}
    lines.append(robustness_text(rows))
    return "\n".join(lines)


def _nan(value: float | None) -> float:
    return math.nan if value is None else value


def robustness_text(rows: list[dict]) -> str:
    """The Monte Carlo table: failures and median / 90 % / worst of each metric."""
    head = f"{'controller':<22} {'failures':>9} {'gain ok':>8}"
    cols = [("settling_time_s", "settling s", 1.0), ("sse_abs", "sse mm", 1e3),
            ("overshoot_pct", "overshoot %", 1.0), ("saturation_time_s", "saturated s", 1.0)]  # fmt: skip
    for _, label, _ in cols:
        head += f"  {label + ' p50/p90/max':>26}"
    lines = [head]
    for r in rows:
        gain = (
            f"{r.get('gain_margin_holds', '-')}/{r['samples']}" if "gain_margin_holds" in r else "-"
        )
        line = f"{r['controller']:<22} {r['failures']:>5}/{r['samples']:<3} {gain:>8}"
        for key, _, k in cols:
            v = r[key]
            line += (
                "  " + f"{_fmt(v['p50'] * k)}/{_fmt(v['p90'] * k)}/{_fmt(v['worst'] * k)}".rjust(26)
            )
        lines.append(line)
    return "\n".join(lines)


def cmd_robustness(args: argparse.Namespace) -> int:
    """Monte Carlo of controllers on plants sampled from a study's ``uncertainty:``."""
    from fuzzyservo.analysis.robustness import monte_carlo
    from fuzzyservo.io.studies import load_study
    from fuzzyservo.tuning.robust import CHECK_SEED, sample_rigs

    _at_least_one(samples=args.samples)
    if args.gain_margin is not None and not args.gain_margin > 1:
        raise ConfigError(f"--gain-margin must be > 1, got {args.gain_margin}")
    _out_file(args.json, "--json")
    out = _out_dir(args.out)
    rig, controllers = _load(args.rig, args.controllers or [DEFAULT_CONTROLLER])
    spec = load_study(resolve(args.uncertainty, "studies", "study"))
    if spec.uncertainty is None:
        raise ConfigError("has no 'uncertainty:' section; name a robust study", file=spec.path)
    if Path(spec.rig_file).resolve() != Path(rig.path).resolve():
        raise ConfigError(
            f"samples {Path(spec.rig_file).stem}, not {rig.name}; name a study of this rig",
            file=spec.path,
        )
    import dataclasses

    seed = CHECK_SEED if args.seed is None else args.seed
    u = dataclasses.replace(spec.uncertainty, samples=args.samples, seed=seed, draws=())
    spec = dataclasses.replace(spec, uncertainty=u)
    scenarios = list(args.scenario or spec.scenarios)
    for s in scenarios:
        _scenario_name(rig, s)
    print(f"rig {rig.name}: {u.describe()}")
    print(f"scenarios {', '.join(scenarios)}; metrics: worst scenario of each sample")
    _note_compiling()
    rigs = sample_rigs(rig, spec)
    progress = _progress(len(rigs) * len(controllers), "robustness")
    mcs = monte_carlo(
        rig, controllers, rigs, [d.noise_seed for d in u.draws], scenarios,
        gain=args.gain_margin, progress=progress.update,
    )  # fmt: skip
    progress.close()
    from fuzzyservo.analysis.robustness import SUMMARY_METRICS, summary

    rows = summary(mcs, args.gain_margin)
    print(robustness_text(rows))
    for mc in mcs:
        for run in mc.failures[:3]:
            print(f"{mc.controller}: {u.draws[run.index].describe(u.parameters)}: {run.reason}")
    if out is not None:
        from fuzzyservo import plots
        from fuzzyservo.analysis.robustness import run_sample

        out.mkdir(parents=True, exist_ok=True)
        values = {m: {mc.controller: mc.values(m) for mc in mcs} for m in SUMMARY_METRICS}
        fig = plots.distribution_figure(values, SUMMARY_METRICS)
        plots.save(fig, out / f"{rig.name}_robustness.png")
        for mc, controller in zip(mcs, controllers, strict=True):
            worst = (mc.failures or [mc.worst("settling_time_s")])[0]
            if worst is None:
                continue
            d = u.draws[worst.index]
            run = run_sample(worst.index, rigs[worst.index], controller, scenarios, d.noise_seed,
                             keep_results=True)  # fmt: skip
            for name, result in run.results.items():
                fig = plots.response_figure([result])
                fig.suptitle(f"{mc.controller}: worst {d.describe(u.parameters)}", fontsize=8)
                plots.save(fig, out / f"{rig.name}_{mc.controller}_worst_{name}.png")
        print(f"plots written to {out}/")
    if args.json:
        write_json(args.json, {"rig": rig.name, "uncertainty": u.describe(), "controllers": rows})
        print(f"JSON written to {args.json}")
    return EXIT_FAILED_RUN if any(mc.failures for mc in mcs) and args.strict else 0


def cmd_designer(args: argparse.Namespace) -> int:
    from fuzzyservo.designer import serve

    rig = resolve(args.rig, "rigs", "rig")
    controller = resolve(args.controller, "studies/controllers", "controller")
    serve(rig, controller, port=args.port, host=args.host, out_dir=args.out, show=args.show)
    return 0


def _fmt_values(values) -> str:
    return ", ".join(_fmt(v) for v in values)


def _network_file_of(rig_name: str | None, into_rig: bool) -> Path | None:
    """The weights file a rig's network_valve names (relative to the rig file); None
    without ``--rig``."""
    from fuzzyservo.io._yaml import read_yaml

    if rig_name is None:
        if into_rig:
            raise ConfigError("--into-rig needs --rig RIG, the rig whose network file to replace")
        return None
    path = resolve(rig_name, "rigs", "rig")
    parts = read_yaml(path).get("plant", {}).get("components") or {}
    for part in parts.values():
        entry = (part.get("parameters") or {}).get("weights") if isinstance(part, dict) else None
        if isinstance(entry, dict) and "file" in entry:
            return path.parent / entry["file"]
    raise ConfigError(
        "has no network_valve with a weights file; give --out FILE",
        file=str(path),
        key="plant.components",
    )


def cmd_fit_valve(args: argparse.Namespace) -> int:
    """Train the seed-003 valve network on a valve-data CSV and write it as JSON."""
    from fuzzyservo.components.nn_fit import fit_valve_network
    from fuzzyservo.errors import DataError
    from fuzzyservo.io.valve_data import read_valve_csv, write_valve_network

    _at_least_one(restarts=args.restarts)
    _out_file(args.out, "--out")
    # the rig's own file (a shipped one too) is replaced only when --into-rig asks for it
    rig_file = _network_file_of(args.rig, args.into_rig)
    name = rig_file.name if rig_file else "valve_network.json"
    out = Path(args.out) if args.out else rig_file if args.into_rig else Path("out") / name
    data = read_valve_csv(args.data)
    bar = _progress(args.restarts, "restarts")
    try:
        fit = fit_valve_network(
            data, seed=args.seed, restarts=args.restarts, progress=lambda k: bar.update(1)
        )
    except ValueError as exc:
        raise DataError(f"{args.data}: {exc}") from None
    finally:
        bar.close()
    write_valve_network(
        out,
        fit.weights,
        fit.train_rms,
        fit.validation_rms,
        {
            "data": str(args.data),
            "method": "Levenberg-Marquardt (scipy least_squares, method=lm), best of restarts",
            "seed": fit.seed,
            "restarts": fit.restarts,
            "samples_train": fit.n_train,
            "samples_validation": fit.n_validation,
        },
    )
    for label, values in (("training", fit.train_rms), ("validation", fit.validation_rms)):
        q_a, q_b = (v * 60e3 for v in values)
        print(f"{label:<10} RMS  Q_A {q_a:.4g} l/min  Q_B {q_b:.4g} l/min")
    print(f"wrote {out}")
    if rig_file is not None and out.resolve() != rig_file.resolve():
        print(
            f"the rig reads {rig_file}: use --into-rig to replace it, or point its weights at {out}"
        )
    return 0


def cmd_calibrate(args: argparse.Namespace) -> int:
    from fuzzyservo.calibration.joint import joint_replay, per_record_fields
    from fuzzyservo.calibration.replay import make_replay
    from fuzzyservo.calibration.report import write_outputs
    from fuzzyservo.calibration.search import calibrate
    from fuzzyservo.components.effects import LIBRARY
    from fuzzyservo.io.controllers import load_controller
    from fuzzyservo.io.measured import read_rig_data
    from fuzzyservo.io.rigs import load_rig

    out = _out_dir(args.out)
    _out_file(args.json, "--json")
    if args.max_effects < 0:
        raise ConfigError(f"--max-effects must be >= 0, got {args.max_effects}")
    _at_least_one(workers=args.workers)
    rig = load_rig(resolve(args.rig, "rigs", "rig"))
    controller = None
    if args.controller:
        controller = load_controller(resolve(args.controller, "studies/controllers", "controller"))
    records = [read_rig_data(d, rig.measured, resample=args.resample) for d in args.data]
    per_record = per_record_fields(rig, args.per_record.split(",") if args.per_record else [])
    effects = None
    if args.effects:
        effects = [e.strip() for e in args.effects.split(",") if e.strip()]
        for e in effects:
            if e not in LIBRARY:
                raise ConfigError(
                    f"--effects: unknown effect {e!r}; choose from {', '.join(LIBRARY)}"
                )
    replays = [make_replay(rig, d, controller) for d in records]
    replay = replays[0] if len(replays) == 1 and not per_record else None
    replay = replay or joint_replay(replays, rig, per_record)
    candidates = [
        e for e in (effects or LIBRARY) if e in rig.plant.effects and e not in rig.effects
    ]
    print(
        f"calibrate {rig.name} on {', '.join(d.source for d in records)}: {replay.mode}; "
        f"{sum(len(d) for d in records)} samples, "
        f"channels {', '.join(replay.channels)}; {len(candidates)} candidate effects"
    )
    bar = _progress(len(candidates) * max(args.max_effects, 1), "candidates")
    try:
        outcome = calibrate(
            replay,
            rig,
            effects=effects,
            max_effects=args.max_effects,
            progress=lambda name: (bar.set_postfix_str(name), bar.update(1)),
            workers=args.workers,
        )
    finally:
        bar.close()
    stem = Path(args.data[0]).stem + (f"+{len(args.data) - 1}" if len(args.data) > 1 else "")
    out = out or _out_dir(str(Path("out") / f"calibrate_{rig.name}_{stem}"))
    label = ", ".join(Path(d).name for d in args.data)
    paths, summary = write_outputs(outcome, replay, label, out)
    summary = json_ready(summary)  # as in summary.json: non-finite numbers are null
    for warning in summary["warnings"]:
        print(f"warning: {warning}")
    print(f"effects added: {summary['decision']}")
    for c in outcome.added:
        print(f"  {c.name}: " + ", ".join(f"{k} = {v:.4g}" for k, v in c.params.items()))
    print("held-out fit %  (channel: before -> after)")
    for channel in replay.channels:
        b = summary["fit_before_pct"][channel]
        a = summary["fit_after_pct"][channel]
        print(f"  {channel:6s} {_fmt(b):>8s} -> {_fmt(a):>8s}")
    if outcome.rounds:
        ranking = ", ".join(f"{c['name']} {_fmt(c['score'])}" for c in summary["candidates"][:5])
        print(f"ranking (score, lower is better): {ranking}")
    print(f"calibrated in {outcome.seconds:.1f} s; report: {paths['report']}")
    if "rig" in paths:
        print(f"calibrated rig: {paths['rig']}")
    if args.json:
        import shutil

        shutil.copyfile(paths["summary"], args.json)
        print(f"JSON written to {args.json}")
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    from fuzzyservo import bench

    _at_least_one(
        runs=args.runs,
        reference_runs=args.reference_runs,
        study_trials=args.study_trials,
        workers=args.workers,
    )
    _out_file(args.json, "--json")
    known = [bench.FUZZY_EVAL, *(c.name for c in bench.CASES), bench.STUDY, bench.CALIBRATE]
    known.append(bench.MARGINS)
    known.append(bench.ROBUST_STUDY)
    wanted = args.case or known
    unknown = [c for c in wanted if c not in known]
    if unknown:
        raise ConfigError(f"unknown bench case {unknown[0]!r}; known: {', '.join(known)}")
    results = []
    progress = _progress(len(wanted), "bench")
    for name in wanted:
        progress.set_description(name)
        if name == bench.FUZZY_EVAL:
            results.append(bench.run_fuzzy_eval(runs=args.runs))
        elif name == bench.STUDY:
            results.append(bench.run_study_case(trials=args.study_trials, workers=args.workers))
        elif name == bench.CALIBRATE:
            results.append(bench.run_calibrate_case())
        elif name == bench.ROBUST_STUDY:
            results.append(
                bench.run_robust_study_case(trials=args.study_trials, workers=args.workers)
            )
        elif name == bench.MARGINS:
            results.append(bench.run_margins_case())
        else:
            case = next(c for c in bench.CASES if c.name == name)
            results.append(bench.run_case(case, runs=args.runs, reference_runs=args.reference_runs))
        progress.update(1)
    progress.close()
    print(f"{'case':<20} {'median':>10} {'reference':>10} {'ratio':>7}  error")
    for r in results:
        err = ", ".join(f"{k} {v:.3g}" for k, v in r.error.items())
        if r.name == bench.STUDY:
            x = r.extra
            print(
                f"{r.name:<20} {_duration(x['wall_s']):>10} {'':>10} {'':>7}  {x['trials']} trials on "
                f"{x['workers']} workers, {x['trials_per_s']:.1f} trials/s; in the trials: simulation "
                f"{x['simulation_s']:.1f} s, sampler/storage/building {x['sampler_and_storage_s']:.1f} s; {err}"
            )
            continue
        if r.name == bench.ROBUST_STUDY:
            x = r.extra
            print(
                f"{r.name:<20} {_duration(x['wall_s']):>10} {'':>10} {'':>7}  {x['trials']} trials on "
                f"{x['workers']} workers ({x['trials_pruned']} pruned), {x['trials_per_s']:.1f} trials/s, {x['simulations']} "
                f"simulations, {x['simulations_per_s']:.0f} simulations/s; {err}"
            )
            continue
        if r.name == bench.MARGINS:
            x = r.extra
            print(
                f"{r.name:<20} {_duration(x['wall_s']):>10} {'':>10} {'':>7}  "
                f"{x['simulations']} simulations of 22 s, {x['ms_per_simulation']:.0f} ms each; {err}"
            )
            continue
        if r.name == bench.CALIBRATE:
            x = r.extra
            print(
                f"{r.name:<20} {_duration(x['wall_s']):>10} {'':>10} {'':>7}  wall_s {x['wall_s']:.1f} "
                f"(budget {x['budget_s']:.0f} s); {x['replays']} replays of 30 s, "
                f"{x['replay_ms']:.0f} ms each; added {', '.join(x['added']) or 'none'}; {err}"
            )
            continue
        print(
            f"{r.name:<20} {_duration(r.median_s):>10} {_duration(r.reference_s):>10} {r.ratio:>6.0f}×  {err}"
        )
    print(
        "reference: scipy solve_ivp (LSODA, rtol 1e-6) per control interval, or skfuzzy compute();"
    )
    print(
        "error: largest deviation from solve_ivp at rtol 1e-9, or from compute() (fraction of output span)"
    )
    if args.json:
        write_json(args.json, {"cases": [r.to_dict() for r in results]})
        print(f"JSON written to {args.json}")
    return 0


def _duration(seconds: float) -> str:
    if seconds < 1e-3:
        return f"{seconds * 1e6:.2f}µs"
    if seconds < 1.0:
        return f"{seconds * 1e3:.2f}ms"
    return f"{seconds:.3f}s"


class _Lines:
    """Progress as one plain line per step on stderr, for logs and CI (no terminal)."""

    def __init__(self, total: int, desc: str):
        import time

        self.total, self.desc, self.postfix, self.n = total, desc, "", 0
        self._clock, self._t0 = time.perf_counter, time.perf_counter()

    def set_description(self, desc: str) -> None:
        self.desc = desc

    def set_postfix_str(self, text: str) -> None:
        self.postfix = text

    def update(self, k: int = 1) -> None:
        self.n += k
        done = f" {self.postfix}" if self.postfix else ""
        print(
            f"{self.desc}: {self.n}/{self.total}{done} ({self._clock() - self._t0:.0f} s)",
            file=sys.stderr,
            flush=True,
        )

    def close(self) -> None:
        pass


def _progress(total: int, desc: str):
    """A tqdm bar on a terminal, plain progress lines otherwise."""
    if not sys.stderr.isatty():
        return _Lines(total, desc)
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit="step", file=sys.stderr)


# --------------------------------------------------------------------------- parser
class _Parser(argparse.ArgumentParser):
    """argparse with its errors on one line (what, and where to read the usage)."""

    def error(self, message: str) -> NoReturn:
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


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="fuzzyservo",
        description="Design, simulate and tune controllers for electro-hydraulic servo systems.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)

    def common(p: argparse.ArgumentParser) -> None:
        p.add_argument("--scenario", help="scenario of the rig file (default: its first)")
        p.add_argument(
            "--duration", type=_seconds, help="simulated time [s] (default: the scenario's)"
        )
        p.add_argument(
            "--out", default="out", help="folder for plots and CSV signals (default: out)"
        )
        p.add_argument("--json", metavar="FILE", help="also write the results as JSON")

    p = sub.add_parser("simulate", help="simulate one controller on a rig scenario")
    p.add_argument("rig", help="rig file or name under rigs/")
    p.add_argument("controller", help="controller file or name under studies/controllers/")
    common(p)
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser("compare", help="compare controllers on a rig scenario: table, plots, JSON")
    p.add_argument(
        "rig", nargs="?", default=DEFAULT_RIG, help=f"rig file or name (default: {DEFAULT_RIG})"
    )
    p.add_argument(
        "controllers", nargs="*", help=f"controller files or names (default: {DEFAULT_CONTROLLER})"
    )
    common(p)
    p.set_defaults(func=cmd_compare)

    p = sub.add_parser(
        "tune", help="run (or resume) a tuning study and report against the baseline"
    )
    p.add_argument(
        "study",
        nargs="?",
        default=DEFAULT_STUDY,
        help=f"study file or name under studies/ (default: {DEFAULT_STUDY})",
    )
    p.add_argument(
        "--trials", type=int, help="complete trials the study should hold (default: the study's)"
    )
    p.add_argument(
        "--storage",
        help="Optuna storage URL, e.g. postgresql://user@host/db (default: SQLite in --out)",
    )
    p.add_argument(
        "--workers", type=int, help="local worker processes (default: the study's, else 1)"
    )
    p.add_argument("--out", help="output folder (default: out/<study name>)")
    p.add_argument("--json", metavar="FILE", help="also write summary.json here")
    p.add_argument(
        "--patience",
        type=int,
        help="stop when the best has not improved for this many trials (default: the study's)",
    )
    p.add_argument(
        "--warm-start",
        action="append",
        default=[],
        metavar="CONTROLLER",
        help="try this controller's numbers first (a previous best, a named controller; repeat)",
    )
    p.add_argument(
        "--check-samples",
        type=int,
        metavar="N",
        help="robust studies: compare the best with the baseline and the template on N fresh "
        "sampled plants in the report (default: the study's sample count; 0: skip)",
    )
    p.set_defaults(func=cmd_tune)

    p = sub.add_parser(
        "robustness",
        help="Monte Carlo of controllers on sampled plants: distributions, failures, worst sample",
    )
    p.add_argument("rig", help="rig file or name under rigs/")
    p.add_argument("controllers", nargs="+", help="controller files or names")
    p.add_argument("--samples", type=int, default=200, help="sampled plants (default: 200)")
    p.add_argument(
        "--uncertainty",
        default=DEFAULT_STUDY,
        help=f"study whose 'uncertainty:' section is sampled (default: {DEFAULT_STUDY})",
    )
    p.add_argument(
        "--seed",
        type=int,
        default=None,
        help="sampling seed (default: the one a study report's check uses, so both draw the "
        "same plants; not the study's)",
    )
    p.add_argument(
        "--gain-margin",
        type=float,
        default=2.0,
        help="check on every sample that the loop holds this gain margin (default: 2)",
    )
    p.add_argument("--scenario", action="append", help="scenario (repeat; default: the study's)")
    p.add_argument("--out", default="out", help="folder for the plots (default: out)")
    p.add_argument("--json", metavar="FILE", help="also write the table as JSON")
    p.add_argument("--strict", action="store_true", help="exit 1 when any sample fails")
    p.set_defaults(func=cmd_robustness)

    p = sub.add_parser(
        "show", help="a fuzzy controller: terms, rules, membership functions and control curve"
    )
    p.add_argument(
        "controller", help="fuzzy controller file (YAML or .fis) or name under studies/controllers/"
    )
    p.add_argument("--out", default="out", help="folder for the PNG figures (default: out)")
    p.set_defaults(func=cmd_show)

    p = sub.add_parser(
        "export",
        help="write a fuzzy controller as MATLAB .fis, IEC 61131-7 FCL, C99 or Structured Text",
    )
    p.add_argument(
        "controller", help="fuzzy controller file (YAML or .fis) or name under studies/controllers/"
    )
    p.add_argument("--fis", metavar="FILE", help="the .fis file to write")
    p.add_argument("--fcl", metavar="FILE", help="the IEC 61131-7 FCL file to write")
    p.add_argument("--c", metavar="DIR", help="write <name>.c and <name>.h (C99) into DIR")
    p.add_argument("--st", metavar="FILE", help="the IEC 61131-3 Structured Text file to write")
    p.add_argument(
        "--lut",
        type=int,
        metavar="N",
        help="code with a lookup table of N points per input instead of the evaluator; "
        "prints its largest error",
    )
    p.add_argument("--float", action="store_true", help="single precision (default: double)")
    p.add_argument(
        "--sample-time",
        type=float,
        default=0.01,
        metavar="S",
        help="controller sample time [s] for the error rate and form pi (default: 0.01)",
    )
    p.set_defaults(func=cmd_export)

    p = sub.add_parser(
        "evaluate", help="evaluate a fuzzy system on a table of inputs (what evalfis does)"
    )
    p.add_argument("controller", help=".fis, .fcl or fuzzy controller file, or a name")
    p.add_argument("inputs", help="CSV with one column per input variable, named like it")
    p.add_argument(
        "--semantics",
        choices=("skfuzzy", "matlab"),
        help="skfuzzy (sampled universes) or matlab (evalfis: exact membership, 101 output "
        "points); default: the file's (skfuzzy unless it says otherwise)",
    )
    p.add_argument("--out", metavar="OUT.csv", help="write the outputs here (default: print)")
    p.set_defaults(func=cmd_evaluate)

    p = sub.add_parser(
        "designer", help="web app: shape a fuzzy controller and watch the loop respond"
    )
    p.add_argument(
        "rig", nargs="?", default=DEFAULT_RIG, help=f"rig file or name (default: {DEFAULT_RIG})"
    )
    p.add_argument(
        "controller",
        nargs="?",
        default=DEFAULT_DESIGN,
        help=f"fuzzy controller file (YAML or .fis) or name (default: {DEFAULT_DESIGN})",
    )
    p.add_argument("--port", type=int, default=5006, help="port (default: 5006)")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default: 127.0.0.1)")
    p.add_argument(
        "--out",
        default="out/designer",
        help="the only folder the app writes to (default: out/designer)",
    )
    p.add_argument("--show", action="store_true", help="open the page in the web browser")
    p.set_defaults(func=cmd_designer)

    p = sub.add_parser("margins", help="gain and delay margin of the nonlinear loop")
    p.add_argument("rig", help="rig file or name under rigs/")
    p.add_argument("controller", help="controller file or name under studies/controllers/")
    p.add_argument("--scenario", help="scenario of the rig (default: its first)")
    p.add_argument("--json", metavar="FILE", help="also write the margins as JSON")
    p.set_defaults(func=cmd_margins)

    p = sub.add_parser("frequency", help="closed-loop frequency response by stepped sines")
    p.add_argument("rig", help="rig file or name under rigs/")
    p.add_argument("controller", help="controller file or name under studies/controllers/")
    p.add_argument("--scenario", help="scenario giving operating point and load (default: first)")
    p.add_argument(
        "--amplitude",
        type=float,
        help="sine amplitude, feedback unit (default: 10 %% of the reference range)",
    )
    p.add_argument("--out", default="out", help="folder for the Bode plot (default: out)")
    p.add_argument("--json", metavar="FILE", help="also write the response as JSON")
    p.set_defaults(func=cmd_frequency)

    p = sub.add_parser("bench", help="speed of the compiled loop against the scipy reference path")
    p.add_argument("--json", metavar="FILE", help="write the figures as JSON")
    p.add_argument("--case", action="append", help="run only this case (repeatable)")
    p.add_argument("--runs", type=int, default=7, help="timed runs per case (median reported)")
    p.add_argument("--reference-runs", type=int, default=3, help="timed runs of the reference path")
    p.add_argument(
        "--study-trials", type=int, default=300, help="trials of the study case (default: 300)"
    )
    p.add_argument(
        "--workers", type=int, default=2, help="worker processes of the study case (default: 2)"
    )
    p.set_defaults(func=cmd_bench)

    p = sub.add_parser(
        "calibrate",
        help="replay measured data on a rig, trace the residual to missing effects, add them",
    )
    p.add_argument("rig", help="rig file or name in rigs/")
    p.add_argument(
        "data",
        nargs="+",
        help="measured data: CSV with <signal>_<unit> columns, or .mat; several files are "
        "calibrated together (shared effects and unknowns)",
    )
    p.add_argument(
        "--per-record",
        help="comma-separated rig-file keys of unknowns (fit: [lower, upper]) fitted once per "
        "data file, e.g. bias_current (default: every unknown is shared)",
    )
    p.add_argument(
        "--controller",
        help="replay closed loop through this controller from the data's ref column "
        "(default: open loop from the recorded i or u)",
    )
    p.add_argument("--out", help="output folder (default out/calibrate_<rig>_<data>)")
    p.add_argument("--json", help="also write the summary JSON here")
    p.add_argument(
        "--effects", help="comma-separated candidate effects (default: the whole library)"
    )
    p.add_argument("--max-effects", type=int, default=2, help="effects to add at most (default 2)")
    p.add_argument(
        "--workers",
        type=int,
        default=os.cpu_count() or 1,
        help="processes that fit a round's candidates in parallel (default: one per core)",
    )
    p.add_argument(
        "--resample", action="store_true", help="resample uneven or repeated time stamps"
    )
    p.set_defaults(func=cmd_calibrate)

    p = sub.add_parser("fit-valve", help="train the seed-003 valve network on a valve-data CSV")
    p.add_argument(
        "data", help="CSV with columns p_s_bar, u_c_V, p_a_bar, p_b_bar, q_a_l_min, q_b_l_min"
    )
    p.add_argument(
        "--out",
        metavar="FILE",
        help="network JSON to write (default: out/<the file name the rig gives>, "
        "else out/valve_network.json)",
    )
    p.add_argument(
        "--rig",
        help="rig whose network_valve weights file to write (with --into-rig; default: none)",
    )
    p.add_argument(
        "--seed", type=int, default=0, help="seed of the split and restarts (default: 0)"
    )
    p.add_argument("--restarts", type=int, default=6, help="random restarts (default: 6)")
    p.add_argument(
        "--into-rig",
        action="store_true",
        help="replace the network file the rig names (default: write out/<that file name>)",
    )
    p.set_defaults(func=cmd_fit_valve)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return EXIT_USAGE
    try:
        return args.func(args)
    except FuzzyservoError as exc:
        print(f"fuzzyservo: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("fuzzyservo: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # output piped into head & co.
        sys.stderr.close()
        return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
