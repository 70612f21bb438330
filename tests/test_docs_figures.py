"""The figures the README and the docs state are measured values, checked here.

A page states a figure only when a script generates it (docs/reproduction.md, the
component reference, the metrics table) or a test checks it against the computation it
comes from, within a stated tolerance. This module is that test for the figures that are
neither generated nor pinned by another test: each check reads the number as the page
writes it (a table cell, a console excerpt) and recomputes it, so editing either side
alone fails. Timings are never stated outside docs/performance.md and never asserted.

The cheap checks (a few simulations, margins by bisection) run in the quick suite; the
calibration example and the main job are marked slow.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from support import DATA

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
NUMBER = re.compile(r"[-+−]?\d+(?:\.\d+)?(?:e[-+]?\d+)?")

pytestmark = pytest.mark.skipif(
    not (DOCS / "tuning.md").is_file(), reason="docs/ is not shipped with an installed package"
)


def page(name: str) -> str:
    return (ROOT / name).read_text(encoding="utf-8")


def number(text: str) -> float:
    """The first number written in ``text`` (a table cell, a line)."""
    found = NUMBER.search(text)
    assert found, f"no number in {text!r}"
    return float(found.group().replace("−", "-"))


def table(name: str, header_starts: str) -> tuple[list[str], dict[str, list[str]]]:
    """The header cells and the rows (by their first cell) of the table on page ``name``
    whose header row starts with ``header_starts``."""
    lines = page(name).splitlines()
    start = next((i for i, line in enumerate(lines) if line.startswith(f"| {header_starts}")), None)
    assert start is not None, f"{name}: no table starting with {header_starts!r}"

    def cells(line: str) -> list[str]:
        return [c.strip() for c in line.strip().strip("|").split("|")]

    rows: dict[str, list[str]] = {}
    for line in lines[start + 2 :]:
        if not line.startswith("|"):
            break
        row = cells(line)
        rows[row[0]] = row[1:]
    return cells(lines[start])[1:], rows


def row(rows: dict[str, list[str]], starts: str) -> list[str]:
    matches = [cells for label, cells in rows.items() if label.startswith(starts)]
    assert len(matches) == 1, f"no single row starting with {starts!r} in {list(rows)}"
    return matches[0]


def controller_columns(header: list[str]) -> list[str]:
    """The controller each column names first in backticks: "FLC2 (`flc2_reshaped`)"."""
    return [re.search(r"`([\w.]+)`", h).group(1) for h in header]


def agree(where: str, stated: float, measured: float, rel: float, floor: float) -> None:
    """The page's ``stated`` value is ``measured`` within ``rel`` of it or ``floor``."""
    assert abs(stated - measured) <= max(rel * abs(measured), floor), (
        f"{where}: the page states {stated:g}, measured {measured:.6g} "
        f"(tolerance {rel:.0%} or {floor:g}); update the page"
    )


# ------------------------------------------------------------------ docs/tuning.md
def test_tuning_results_table_is_what_dinca_flc_scores():
    from fuzzyservo import load_controller
    from fuzzyservo.io.studies import load_study
    from fuzzyservo.tuning.objective import build_evaluator

    header, rows = table("docs/tuning.md", "scored by `dinca_flc`")
    names = controller_columns(header)
    evaluator = build_evaluator(load_study(DATA / "studies" / "dinca_flc.yaml"))
    scored = {
        name: evaluator.baseline_evaluation
        if name == evaluator.baseline.name
        else evaluator.evaluate(load_controller(name))
        for name in names
    }
    # row label -> (what it is in the evaluation, factor from SI to the page's unit)
    figures = {
        "objective": (lambda e: e.values[0], 1.0),
        "settling time": (lambda e: e.metrics["settling_time_s"], 1.0),
        "steady-state error [mm]": (lambda e: e.metrics["sse_abs"], 1e3),
        "converter saturated": (lambda e: e.metrics["saturation_time_s"], 1.0),
        "overshoot": (lambda e: e.metrics["overshoot_pct"], 1.0),
        "command variation": (lambda e: e.metrics["command_tv"], 1.0),
    }
    for label, (what, factor) in figures.items():
        for name, cell in zip(names, row(rows, label), strict=True):
            agree(f"tuning.md {label} / {name}", number(cell), factor * what(scored[name]),
                  rel=0.03, floor=0.01)  # fmt: skip


def test_ehs160_table_is_what_the_motor_does_on_steps():
    from fuzzyservo import load_controller, load_rig, result_metrics, simulate

    header, rows = table("docs/tuning.md", "`ehs160_motor`, `steps`")
    rig = load_rig("ehs160_motor")
    metrics = {
        name: result_metrics(simulate(rig, load_controller(name), "steps")).aggregate
        for name in controller_columns(header)
    }
    for label, key in (("settling", "settling_time_s"), ("overshoot", "overshoot_pct"),
                       ("steady-state error", "sse_abs")):  # fmt: skip
        for name, cell in zip(metrics, row(rows, label), strict=True):
            agree(f"tuning.md {label} / {name}", number(cell), metrics[name][key],
                  rel=0.03, floor=0.01)  # fmt: skip


# ------------------------------------------------------------------ docs/margins.md
def test_margins_table_is_what_margins_finds():
    from fuzzyservo import load_controller, load_rig
    from fuzzyservo.analysis.margins import margins, stable_at

    _header, rows = table("docs/margins.md", "seed-002 rig, `pulses`")
    rig = load_rig("dinca_cylinder")
    p = margins(rig, load_controller("p_k10"), "pulses")
    cells = row(rows, "P K=10")
    agree("margins.md P gain margin", number(cells[0]), p.gain.value, rel=0.02, floor=0)
    agree("margins.md P onset gain", number(cells[1].split("=")[1]), 10 * p.gain.value,
          rel=0.02, floor=0)  # fmt: skip
    agree("margins.md P oscillation", number(cells[2]), p.gain.frequency_hz, rel=0.05, floor=0)
    agree("margins.md P delay margin [ms]", number(cells[3]), 1e3 * p.delay.value,
          rel=0.03, floor=0)  # fmt: skip
    flc = margins(rig, load_controller("flc_dinca_tuned"), "pulses")
    cells = row(rows, "tuned FLC")
    agree("margins.md FLC gain margin", number(cells[0]), flc.gain.value, rel=0.02, floor=0)
    agree("margins.md FLC oscillation", number(cells[2]), flc.gain.frequency_hz, rel=0.05,
          floor=0)  # fmt: skip
    # "≥ 80 ms": stable with that much extra delay; `margins` itself lands beyond it
    at_least = number(cells[3].split("≥")[1]) / 1e3
    assert stable_at(rig, load_controller("flc_dinca_tuned"), "pulses", extra_delay_s=at_least)
    assert flc.delay.value > at_least


# ------------------------------------------------------------------ docs/seeds.md
def test_seed001_rise_times_are_the_rigs():
    from fuzzyservo import load_controller, load_rig, result_metrics, simulate

    _, rows = table("docs/seeds.md", "supply")
    for column, (rig_name, controller) in enumerate(
        (("ahc_cylinder", "p_ahc_cylinder"), ("ahc_motor", "p_ahc_motor"))
    ):
        rig, ctrl = load_rig(rig_name), load_controller(controller)
        for label, cells in rows.items():
            mpa = int(number(label))
            rise = result_metrics(simulate(rig, ctrl, f"steps_{mpa}mpa")).aggregate["rise_time_s"]
            agree(f"seeds.md {rig_name} at {mpa} MPa", number(cells[column]), rise,
                  rel=0.02, floor=0.002)  # fmt: skip


def test_seed003_network_errors_are_the_shipped_networks():
    training = json.loads((DATA / "rigs" / "hydroprax_nn_valve.json").read_text())["training"]
    text = " ".join(page("docs/seeds.md").split())
    found = re.search(
        r"RMS Q_A ([\d.]+) / Q_B ([\d.]+) l/min in training and ([\d.]+) / ([\d.]+) l/min in"
        r" validation",
        text,
    )
    assert found, "seeds.md no longer states the network's RMS errors as this test reads them"
    shipped = [training[part][q] for part in ("train_rms_l_min", "validation_rms_l_min")
               for q in ("q_a", "q_b")]  # fmt: skip
    for stated, value in zip(map(float, found.groups()), shipped, strict=True):
        agree("seeds.md network RMS", stated, value, rel=0.005, floor=0)


def test_seed_observation_counts_are_the_reproduction_tables():
    """seeds.md's counts against docs/reproduction.md (generated, kept current by a test)."""
    status = [
        line.split("|")[8].strip()
        for line in page("docs/reproduction.md").splitlines()
        if re.match(r"^\| 00\d \|", line)
    ]
    text = " ".join(page("docs/seeds.md").split())
    found = re.search(r"(\d+) observations, (\d+) reproduced and (\d+) that differ", text)
    assert found, "seeds.md no longer states the counts as this test reads them"
    observations = [s for s in status if s in ("reproduced", "differs")]
    assert [int(g) for g in found.groups()] == [
        len(observations),
        status.count("reproduced"),
        status.count("differs"),
    ]


# ------------------------------------------------------------------ docs/calibration.md
# the lines the console prints that are this machine's (paths written, times)
MACHINE = ("report: ", "calibrated rig: ", "JSON written to ", "the command took ")


@pytest.mark.slow
def test_calibration_example_prints_what_the_page_shows(tmp_path, capsys, monkeypatch):
    """The page's console excerpt ("Reading the console", its ``$ fuzzyservo`` line run
    as written) line by line: every word as printed (the numbers aside), the forces and
    their 95 % intervals within 5 %, the fits and the error rate within 5 points (the
    record is generated with sensor noise, so the last digits may move between
    machines); and the figures the page quotes from its first command."""
    from fuzzyservo.cli import main

    text = page("docs/calibration.md")
    monkeypatch.chdir(tmp_path)  # --out and --json are relative: under tmp_path
    (tmp_path / "examples").mkdir()
    (tmp_path / "examples" / "run_dinca_friction.csv").write_bytes(
        (ROOT / "examples" / "run_dinca_friction.csv").read_bytes()
    )
    section = text.split("## Reading the console")[1].split("\n## ")[0]
    command, *shown = re.search(r"```text\n(.*?)```", section, re.S).group(1).splitlines()
    args = command.removeprefix("$ fuzzyservo ").split()
    assert main(args) == 0
    printed = [
        line for line in capsys.readouterr().out.splitlines() if not line.startswith(MACHINE)
    ]

    def words(line: str) -> str:
        return NUMBER.sub("#", line)

    assert [words(x) for x in shown] == [words(x) for x in printed], "\n".join(printed)
    summary = json.loads((tmp_path / args[args.index("--out") + 1] / "summary.json").read_text())
    for line in (x.strip() for x in shown):
        if line.startswith("added: "):
            name, key = re.match(r"added: (\w+): (\w+) ", line).groups()
            found = re.search(r"(\S+) N \(95 % interval (\S+) to (\S+) N\)", line)
            value, low, high = map(number, found.groups())
            u = summary["uncertainty"][f"{name}.{key}"]
            agree(f"calibration.md {name}", value, u["value"], rel=0.05, floor=0)
            agree(f"calibration.md {name} low", low, u["interval"][0], rel=0.05, floor=0)
            agree(f"calibration.md {name} high", high, u["interval"][1], rel=0.05, floor=0)
        elif line.startswith("held-out fit % "):
            for channel in summary["fit_after_pct"]:
                before, after = re.search(rf"\b{channel} (\S+) -> ([^,\s]+)", line).groups()
                agree(f"calibration.md fit {channel} before", float(before),
                      summary["fit_before_pct"][channel], rel=0, floor=5)  # fmt: skip
                agree(f"calibration.md fit {channel} after", float(after),
                      summary["fit_after_pct"][channel], rel=0, floor=5)  # fmt: skip
        elif line.startswith("error rate: "):
            rate = number(re.search(r"in (?:about|under) (\S+) %", line).group(1))
            agree("calibration.md error rate", rate, 100 * summary["false_positive_rate"],
                  rel=0, floor=5)  # fmt: skip

    # the page's first command: the calibrated rig's interval, z and the threshold quoted
    first = re.search(r"^fuzzyservo (calibrate dinca_cylinder examples/\S+ .*)$", text, re.M)
    assert main(first.group(1).split()) == 0
    summary = json.loads((tmp_path / "out" / "cal.json").read_text())
    low, high = map(float, re.search(r"interval: \[([\d.]+), ([\d.]+)\]", text).groups())
    interval = summary["uncertainty"]["coulomb_friction.force"]["interval"]
    agree("calibration.md interval low", low, interval[0], rel=0.05, floor=0)
    agree("calibration.md interval high", high, interval[1], rel=0.05, floor=0)
    z = number(re.search(r"z = (\S+) for the friction", text).group(1))
    agree("calibration.md z", z, summary["effects_added"][0]["z"], rel=0.3, floor=0)
    threshold = number(re.search(r"against a threshold near\s+(\S+)", text).group(1))
    agree("calibration.md threshold", threshold, summary["rounds"][0]["threshold_z"],
          rel=0.3, floor=0)  # fmt: skip


# ------------------------------------------------------------------ README.md
@pytest.mark.slow
def test_readme_main_job_figures_are_the_main_jobs(tmp_path, capsys):
    """The main job run as the README's first line runs it: the objectives its excerpt
    shows (to the 4 digits printed) and what the text under it says of them."""
    from fuzzyservo.cli import main

    assert main(["tune", "--out", str(tmp_path / "out")]) == 0
    printed = capsys.readouterr().out.splitlines()
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    readme = page("README.md")
    excerpt = re.search(r"## What the main job prints.*?```text\n(.*?)```", readme, re.S).group(1)
    # every line of the excerpt is printed as it stands, but the progress bar (on stderr),
    # the storage path and the times, which are this machine's
    timed = ("dinca_robust: ", "storage: ", "report: ", "the command took ")
    for line in excerpt.splitlines():
        if not line.startswith(timed):
            assert line in printed, line
    worse = [ln.split()[0] for ln in printed if ln.endswith(" worse") and "[" in ln]
    assert worse == ["rise_time_s", "ise"], worse
    best, baseline = summary["best"]["objective"], summary["baseline"]["objective"]
    assert f"{best:.4g}" in excerpt and f"{baseline:.4g}" in excerpt, (best, baseline)
    prose = " ".join(readme[readme.index("The metrics are the worst") :].split()[:60])
    b, base = summary["best"]["metrics"], summary["baseline"]["metrics"]
    assert "settles four times faster" in prose
    assert 3.5 <= base["settling_time_s"] / b["settling_time_s"] < 4.5
    assert "a ninth of its steady-state error" in prose
    assert 8 <= base["sse_abs"] / b["sse_abs"] < 10
    assert "never saturates" in prose and b["saturation_time_s"] == 0
    rows = {c["controller"]: c for c in summary["comparison"]["controllers"]}
    assert "gain margin of 2 on every sample where P K=10 fails on all" in prose
    assert rows["dinca_robust_best"]["gain_margin_holds"] == rows["dinca_robust_best"]["samples"]
    assert rows["p_k10"]["gain_margin_holds"] == 0
    assert "Two rows are worse, rise time and ISE" in " ".join(readme.split())


# ------------------------------------------------------------------ docs/samplers.md
@pytest.mark.slow
def test_samplers_table_row_is_what_the_benchmark_gives():
    """One row of the sampler comparison (the default sampler of `ehs160_flc`), re-run with
    benchmarks/compare_samplers.py as the page says: the same numbers to the digits shown."""
    import importlib.util
    import statistics

    script = ROOT / "benchmarks" / "compare_samplers.py"
    if not script.is_file():
        pytest.skip("benchmarks/ is not shipped with an installed package")
    spec = importlib.util.spec_from_file_location("compare_samplers", script)
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    stated = next(
        [c.strip() for c in line.strip().strip("|").split("|")][1:]
        for line in page("docs/samplers.md").splitlines()
        if line.startswith("| ehs160_flc | cmaes |")
    )
    bests = [bench.run("ehs160_flc", "cmaes", seed, None, 2)["best"] for seed in range(5)]
    assert int(stated[1]) == len(bests)
    for cell, value in zip(stated[2:5], (statistics.median(bests), min(bests), max(bests)),
                           strict=True):  # fmt: skip
        assert cell.strip("*") == f"{value:.4g}", (stated, bests)
