"""What ``fuzzyservo calibrate`` prints, and ``CalibrationResult.text()`` returns: a
verdict an engineer reads in ten seconds (issue 40, item 4).

Its last lines are the verdict: each effect added with its size in the rig's units and
its 95 % interval, the held-out fit before -> after, the decision's error rate worded
as the decision's, one plain sentence for each effect likely but not established (its
size and the experiment that would settle it, in a test engineer's words), and each
effect named with ``--effects`` that was not tried, with why. Candidates are ranked by
what their fit improves, not by how well a signature correlates.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from support import DATA, controller_named, rig_named

from fuzzyservo.calibration.identifiability import Separation, excitations
from fuzzyservo.calibration.replay import make_replay
from fuzzyservo.calibration.run import prepare, skipped_effects
from fuzzyservo.calibration.verdict import experiment_words, ranking_line, verdict_lines
from fuzzyservo.cli import main
from fuzzyservo.components.effects import LIBRARY
from fuzzyservo.display import quantity_text, unit_text
from fuzzyservo.io.measured import read_rig_data
from fuzzyservo.io.rigs import load_rig
from fuzzyservo.metrics import format_value

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "run_dinca_friction.csv"  # 300 N of Coulomb friction
# what the verdict used to print and a test engineer does not read: experiment names,
# "limit on this record", "× the recorded separation", parameters as "key = value"
JARGON = ("positions_", "load_pull", "load_push", "sine_sweep", "recorded separation",
          "limit on this record", "×", "would need", "= ", "false-positive")  # fmt: skip


def _verdict(printed: str) -> list[str]:
    """The verdict's lines: everything after the ``verdict:`` line, which must end the
    output."""
    lines = printed.rstrip("\n").splitlines()
    tail = lines[lines.index("verdict:") + 1 :]
    assert tail and all(line.startswith("  ") for line in tail), printed
    return [line[2:] for line in tail]


def _check_not_established(summary: dict, verdict: list[str], printed: str) -> None:
    """One plain sentence for each effect likely but not established: its size in its
    unit and the experiment that would settle it, without jargon."""
    weak = [line for line in verdict if line.startswith("not established: ")]
    assert {j["name"] for j in summary["not_established"]} == {
        re.match(r"not established: (\w+)", line).group(1) for line in weak
    }
    for j, line in zip(summary["not_established"], weak, strict=True):
        key = j["size"]["param"]
        text, unit = quantity_text([j["params"][key]], j["units"][key])
        assert line.startswith(f"not established: {j['name']} may be present, {key} about "
                               f"{text[0]} {unit}; "), line  # fmt: skip
        assert unit and line.endswith(" would settle it"), line
        assert not any(token in line for token in JARGON), line
    experiments = [j["experiment"]["plain"] for j in summary["not_established"]]
    assert all(plain in printed for plain in experiments)


def test_an_effect_not_established_reads_as_one_sentence(tmp_path, capsys) -> None:
    """The example record replayed through P K=10: round 2 leans to a Stribeck law on
    top of the friction added (z > 0) without establishing it; the verdict says so in
    one sentence with the experiment that would settle it."""
    summary_file = tmp_path / "summary.json"
    effects = "coulomb_friction,stribeck_friction,internal_leakage,valve_deadband"
    code = main(["calibrate", "dinca_cylinder", str(EXAMPLE), "--controller", "p_k10",
                 "--effects", effects, "--workers", "1", "--out", str(tmp_path / "out"),
                 "--json", str(summary_file)])  # fmt: skip
    assert code == 0
    printed = capsys.readouterr().out
    summary = json.loads(summary_file.read_text(encoding="utf-8"))
    verdict = _verdict(printed)
    assert summary["not_established"], verdict
    _check_not_established(summary, verdict, printed)


def test_the_verdict_is_last_and_reads_in_ten_seconds(tmp_path, capsys) -> None:
    """The example record replayed in open loop (its pressures show the friction to
    0.1 N) with three candidates and one effect the rig declares."""
    summary_file = tmp_path / "summary.json"
    effects = "coulomb_friction,valve_deadband,internal_leakage,valve_lag"
    code = main(["calibrate", "dinca_cylinder", str(EXAMPLE), "--effects", effects,
                 "--workers", "1", "--out", str(tmp_path / "out"),
                 "--json", str(summary_file)])  # fmt: skip
    assert code == 0
    printed = capsys.readouterr().out
    summary = json.loads(summary_file.read_text(encoding="utf-8"))
    verdict = _verdict(printed)

    # the effect added: its size in N and its 95 % interval, as summary.json has them
    added = re.fullmatch(
        r"added: coulomb_friction: force ([\d.]+) N \(95 % interval ([\d.]+) to ([\d.]+) N\)",
        verdict[0],
    )
    assert added, verdict[0]
    # replayed from its current, friction's cost is smooth: no warning about the loop
    assert not [w for w in summary["warnings"] if "through the controller" in w]
    force = summary["uncertainty"]["coulomb_friction.force"]
    value, low, high = map(float, added.groups())
    assert value == pytest.approx(force["value"], rel=1e-4)
    assert [low, high] == pytest.approx(force["interval"], rel=1e-4)
    assert low < value < high

    # the held-out fit before -> after of every channel
    fit = next(line for line in verdict if line.startswith("held-out fit %"))
    for channel, after in summary["fit_after_pct"].items():
        before = summary["fit_before_pct"][channel]
        assert f"{channel} {format_value(before)} -> {format_value(after)}" in fit, fit

    # the error rate is the decision's: how often it would add an effect that is not there
    (rate,) = [line for line in verdict if line.startswith("error rate: ")]
    assert rate.startswith(
        "error rate: on records like this one without a missing effect, this decision "
        "would add one in "
    ), rate
    draws = summary["rounds"][0]["null"]["draws"]
    assert f"of the {draws} tried)" in rate

    # round 2 refits the friction along with each candidate: nothing else leans
    _check_not_established(summary, verdict, printed)

    # the effect the rig declares is skipped with why, before the run and in the verdict
    why = summary["skipped_effects"]["valve_lag"]
    assert why.startswith("the rig declares it already (time_constant 3.20 ms)")
    assert verdict[-1] == f"skipped: valve_lag: {why}"
    head = printed.split("\nreport: ")[0]
    assert "3 candidate effects (coulomb_friction, valve_deadband, internal_leakage)" in head
    assert f"\nskipped: valve_lag: {why}\n" in head + "\n"

    # the candidates ranked by their fit (held-out cost, lowest first)
    ranking = next(line for line in printed.splitlines() if line.startswith("candidates, "))
    shown = re.findall(r"(\w+) ([\d.e+]+)(?:,|$)", ranking.split("a perfect one 1): ")[1])
    costs = {c["name"]: c["score"] for c in summary["rounds"][0]["candidates"]}
    assert [name for name, _ in shown] == sorted(costs, key=costs.get)
    # and so is the report's signature table, whatever the signatures' R²
    report = (tmp_path / "out" / "report.md").read_text(encoding="utf-8")
    table = report.split("| effect | round 1 held-out cost | improvement | R² |")[1]
    rows = re.findall(r"^\| (\w+) \| ([\d.e+-]+) \|", table, re.M)
    assert [name for name, _ in rows] == sorted(costs, key=costs.get)[: len(rows)]
    assert rows[0][0] == "coulomb_friction"


def test_the_readme_command_says_the_rig_declares_valve_lag(tmp_path, capsys) -> None:
    """The README's own command names valve_lag, which rigs/dinca_cylinder.yaml
    declares: it is listed as skipped, with why, never dropped without a word."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    command = re.search(r"^fuzzyservo (calibrate dinca_cylinder \S+ .*)$", readme, re.M)
    args = command.group(1).split()
    assert "valve_lag" in args[args.index("--effects") + 1]
    assert "valve_lag" in rig_named("dinca_cylinder").effects
    args[2] = str(ROOT / args[2])
    assert main([*args, "--out", str(tmp_path / "out")]) == 0
    printed = capsys.readouterr().out
    assert printed.startswith("calibrate dinca_cylinder on ")
    assert "; 1 candidate effect (coulomb_friction)\nskipped: valve_lag: the rig declares it" in (
        printed
    )
    assert _verdict(printed)[-1].startswith("skipped: valve_lag: the rig declares it already")
    summary = json.loads((tmp_path / "out" / "summary.json").read_text(encoding="utf-8"))
    assert list(summary["skipped_effects"]) == ["valve_lag"]


def test_an_effect_asked_for_and_not_tried_is_skipped_with_why() -> None:
    """Declared (fitted as an unknown when marked fit:, else how to refit it), or one
    the plant cannot take: the named effects are the candidates and the skipped ones."""
    asked = ["supply_droop", "internal_leakage", "coulomb_friction", "valve_lag"]
    motor = load_rig(DATA / "rigs" / "ehs160_motor.yaml")  # ideal supply, leakage declared
    skipped = skipped_effects(motor, asked)
    assert set(skipped) == {"supply_droop", "internal_leakage"}
    assert "supply (ideal_supply) holds its pressure whatever the flow" in skipped["supply_droop"]
    assert (
        "m³/(s·Pa)); a calibration adds only effects the rig lacks: to refit it, mark"
        in (skipped["internal_leakage"])
    )
    festo = load_rig(DATA / "rigs" / "festo_hanging_load.yaml")  # its leakage marked fit:
    assert skipped_effects(festo, ["internal_leakage"]) == {
        "internal_leakage": "the rig declares it already, with coefficient marked fit: and "
        "fitted with the rig's other unknowns"
    }
    rig = rig_named("dinca_cylinder")
    data = read_rig_data(EXAMPLE, rig.measured)
    setup = prepare(rig, data, effects=[*asked, "coulomb_friction"])  # named twice: once
    assert setup.candidates == ["supply_droop", "internal_leakage", "coulomb_friction"]
    assert sorted([*setup.candidates, *setup.skipped]) == sorted(asked)
    assert setup.skipped == {"valve_lag": skipped_effects(rig, ["valve_lag"])["valve_lag"]}
    assert "skipped: valve_lag: the rig declares it already" in setup.describe()


def test_an_experiment_reads_in_a_test_engineers_words() -> None:
    """The excitations that would settle an effect, in the rig's units: a shift of the
    recorded reference in mm, a load in N with its direction, a sweep's band and
    amplitude; never their code names."""
    rig = rig_named("dinca_cylinder")
    record = make_replay(rig, read_rig_data(EXAMPLE, rig.measured), controller_named("p_k10"))
    words = {
        s.name: experiment_words(Separation(s.name, s.description, 1.0, {}, s), record, rig)
        for s in excitations(record, rig)
    }
    assert words["recorded"] == "repeating the same run (more records of it, calibrated together)"
    up = re.fullmatch(
        r"a run of the same reference shifted by \+([\d.]+) mm", words["positions_up"]
    )
    down = re.fullmatch(
        r"a run of the same reference shifted by -([\d.]+) mm", words["positions_down"]
    )
    assert up and down and up.group(1) == down.group(1), words
    # 20 % of the stall force: 70 bar on the 7.07 cm² piston
    load = 0.2 * 70e5 * 7.0686e-4
    (shown,), _ = quantity_text([load], "N")
    assert words["load_push"] == (
        f"a run of the same reference under a constant {shown} N load resisting motion in "
        "the + direction"
    )
    assert words["load_pull"] == (
        f"a run of the same reference under a constant {shown} N load pulling in the + direction"
    )
    assert re.fullmatch(
        r"a sine sweep from 0\.1 to 5 Hz of ±[\d.]+ mm about the recorded mid position",
        words["sine_sweep"],
    )
    assert float(up.group(1)) == pytest.approx(
        float(re.search(r"±([\d.]+) mm", words["sine_sweep"]).group(1)), rel=0.02
    )  # the shift and the sweep's amplitude: half the recorded span


def _judged(name: str, verdict: str, **extra) -> dict:
    param = LIBRARY[name].fitted[0]
    return {"name": name, "verdict": verdict, "params": {param.key: 2e-3}, "z": 3.0,
            "units": {param.key: "s"}, "share_of_residual": 0.1, "share_needed": 0.25,
            "first_in_round": "coulomb_friction", **extra}  # fmt: skip


def test_every_verdict_kind_reads_in_plain_words() -> None:
    """Added, out-ranked, negligible (its ``reason`` when the rule gives one), failed fit
    (judged, or a candidate of the last round whose fit could not beat the start),
    failed, not established; the error rate when no surrogate was drawn."""
    summary = {
        "effects_added": [
            {"name": "coulomb_friction", "params": {"force": 120.0, "smoothing_velocity": 4e-4},
             "units": {"force": "N", "smoothing_velocity": "m/s"}, "z": 9.0, "lookalike": ""}
        ],
        "uncertainty": {"coulomb_friction.force": {"value": 120.0, "interval": [118.0, 122.0],
                                                   "bounds": [0.0, 500.0], "at_bound": False}},
        "fit_before_pct": {"y": 90.0}, "fit_after_pct": {"y": 99.5},
        "false_positive_rate": None,
        "rounds": [{"null": {"draws": 0}, "candidates": [
            {"name": "valve_lag", "score": 800.0, "status": "failed fit"}]}],
        "judged": [
            _judged("transport_delay", "out-ranked"),
            _judged("valve_lag", "failed fit", reason="its fit ended at 812, above the start's 790"),
            _judged("valve_deadband", "failed"),
        ],
        "negligible": [_judged("transport_delay", "negligible", reason="2 ms is 1 % of its range")],
        "not_established": [],
        "skipped_effects": {},
    }  # fmt: skip
    lines = verdict_lines(summary)
    assert lines[0] == "added: coulomb_friction: force 120.0 N (95 % interval 118.0 to 122.0 N)"
    assert lines[1] == "held-out fit % (100 = perfect), before -> after: y 90 -> 99.5"
    assert lines[2].startswith("error rate: no records like this one were drawn")
    assert "at most 5 % of cases" in lines[2]
    assert (
        "out-ranked: transport_delay, delay about 2.00 ms: passes the test too, but "
        "coulomb_friction ranks first" in lines
    )
    assert "negligible: transport_delay, delay about 2.00 ms: 2 ms is 1 % of its range" in lines
    assert "failed fit: valve_lag: its fit ended at 812, above the start's 790" in lines
    assert sum(line.startswith("failed fit: valve_lag") for line in lines) == 1
    assert "failed: valve_deadband: its replay diverged at the fitted values: not judged" in lines
    assert not any(line.startswith("not established") for line in lines)
    summary["judged"] = []  # a failed fit the judging did not reach: the candidate's status
    (line,) = [line for line in verdict_lines(summary) if line.startswith("failed fit")]
    assert "the search failed" in line and "neither shows nor rules it out" in line


def test_values_print_in_the_unit_an_engineer_reads() -> None:
    assert quantity_text([0.0032], "s") == (["3.20"], "ms")
    assert quantity_text([2.97e-8], "A") == (["29.7"], "nA")
    assert quantity_text([-1.2e-3, 1e-4], "A") == (["-1.20", "0.10"], "mA")
    assert quantity_text([290.31, 290.18, 290.45], "N", 5) == (["290.31", "290.18", "290.45"], "N")
    assert quantity_text([1.4e9], "Pa") == (["14000"], "bar")
    assert quantity_text([2e-3], "m/s") == (["2.00"], "mm/s")
    assert quantity_text([5.01e-19], "m^3/(s*Pa)") == (["5.01e-19"], "m³/(s·Pa)")
    assert unit_text("Pa*s/m^3") == "Pa·s/m³" and unit_text("1") == ""


def test_the_ranking_names_a_failed_fit_as_such() -> None:
    """A candidate whose fit ended above the starting model (status ``failed fit: ...``,
    candidates.fit) is ranked as a failed fit, not by the cost its failed fit reached."""
    summary = {"rounds": [{"start_cost": 9.5, "candidates": [
        {"name": "coulomb_friction", "score": 1.2, "status": "ok"},
        {"name": "valve_lag", "score": 12.0,
         "status": "failed fit: its training cost 12 ends above the starting model's 9.5"},
    ]}]}  # fmt: skip
    line = ranking_line(summary)
    assert line.endswith("coulomb_friction 1.2, valve_lag failed fit"), line


def test_a_stribeck_law_reads_with_its_breakaway_and_a_value_on_its_bound_as_no_size():
    """The verdict's words for an added Stribeck law (the Festo record's, values as it
    fitted them): its stiction is stored as the part above the Coulomb level, so the
    breakaway force is printed as their sum; the stiction on its bound is no size."""
    from fuzzyservo.calibration.verdict import _added_size

    effect = {
        "name": "stribeck_friction",
        "params": {"coulomb_force": 8.8, "stiction_force": 120.6, "stribeck_velocity": 1.73e-3,
                   "presliding_distance": 0.0, "smoothing_velocity": 4e-4},
        "units": {"coulomb_force": "N", "stiction_force": "N", "stribeck_velocity": "m/s",
                  "presliding_distance": "m", "smoothing_velocity": "m/s"},
    }  # fmt: skip
    uncertainty = {
        "stribeck_friction.coulomb_force": {"interval": [0.0, 32.0], "at_bound": False},
        "stribeck_friction.stiction_force": {"interval": [0.0, 120.6], "at_bound": True,
                                             "trades_with": "coulomb_force",
                                             "correlation": -0.93},
        "stribeck_friction.stribeck_velocity": {"interval": [5.9e-4, 5.08e-3],
                                                "at_bound": False},
    }  # fmt: skip
    words = _added_size(effect, uncertainty)
    assert words.startswith(
        "present, size unresolved (stiction_force pressed against its "
        "bound 121 N, traded against coulomb_force (correlation -0.93)"
    )
    assert "stiction_force 121 N (95 %" not in words
    assert words.endswith("breakaway (coulomb_force + stiction_force) 129 N")
