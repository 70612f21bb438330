"""One unit per quantity on screen, SI in JSON: the units schema (metrics.METRIC_UNITS)
covers every metric the metrics package produces, and every console table shows a
metric in the rig's display unit (issue 30, item 2)."""

from __future__ import annotations

import dataclasses
import math
import re
from types import SimpleNamespace

import numpy as np
import pytest
from support import controller_named, rig_named

from fuzzyservo.analysis.compare import compare
from fuzzyservo.display import MetricUnits, metric_units, metrics_table, undefined_note
from fuzzyservo.metrics import (
    METRIC_NAMES,
    METRIC_UNITS,
    Metrics,
    StepMetrics,
    heave_metrics,
    metric_unit,
)
from fuzzyservo.tuning.spec import MARGIN_METRICS
from fuzzyservo.tuning.uncertainty.robustness import SUMMARY_METRICS, comparison_text
from fuzzyservo.units import parse_unit


def _produced_names() -> set[str]:
    """Every metric name the metrics package can put in a result or a JSON file."""
    t = np.linspace(0.0, 10.0, 1001)
    heave = SimpleNamespace(
        t=t, warmup_s=0.0, signals={"z_wave": np.sin(t), "z_load": 0.1 * np.sin(t)}
    )
    step_fields = {f.name for f in dataclasses.fields(StepMetrics)}
    run_fields = {f.name for f in dataclasses.fields(Metrics) if f.type == "float"}
    return {*METRIC_NAMES, *step_fields, *run_fields, *heave_metrics(heave), *MARGIN_METRICS}


def test_every_metric_the_package_produces_has_a_unit_in_the_schema():
    missing = _produced_names() - set(METRIC_UNITS)
    assert not missing, f"metrics without a unit in METRIC_UNITS: {sorted(missing)}"


@pytest.mark.parametrize("output", ["m", "rad", "rad/s"])
def test_each_schema_unit_has_the_dimension_of_its_formula(output):
    """sse_abs is an output, iae an output·s, ise an output²·s, itae an output·s²; time
    metrics are s, ratios %, the command V (its variation V/s)."""
    y, s = parse_unit(output), parse_unit("s")
    expected = {"sse_abs": y, "r0": y, "r1": y, "y_init": y, "y_final": y, "motion": y,
                "resolution": y, "iae": y * s,
                "ise": y * y * s, "itae": y * s * s, "peak_command": parse_unit("V"),
                "command_tv": parse_unit("V") / s}  # fmt: skip
    for name in METRIC_UNITS:
        unit = parse_unit(metric_unit(name, output))
        if name in expected:
            assert unit.dims == expected[name].dims, name
        elif name.endswith("_s"):
            assert unit == s, name
        else:  # _pct and the gain margin: pure numbers
            assert unit.dims == parse_unit("1").dims, name


def test_a_compound_output_is_bracketed_before_it_is_squared():
    assert MetricUnits("rad/s", "rad/s").label("ise") == "ise [(rad/s)²·s]"
    assert MetricUnits("m", "mm").label("ise") == "ise [mm²·s]"
    assert MetricUnits("m", "mm").si("itae") == "m·s²"


def test_display_values_scale_with_the_unit_and_json_units_stay_si():
    units = MetricUnits("m", "mm")
    assert units.value("sse_abs", 0.0012) == pytest.approx(1.2)
    assert units.value("ise", 2e-6) == pytest.approx(2.0)  # m²·s -> mm²·s: 1e6
    assert units.value("settling_time_s", 0.5) == 0.5
    assert math.isnan(units.value("sse_abs", None))
    assert units.text("sse_abs", 0.0012) == "1.2 mm"
    assert units.text("gain_margin", 4.386) == "4.386"
    assert units.si_units()["sse_abs"] == "m" and set(units.si_units()) == set(METRIC_UNITS)


def _labels(text: str) -> dict[str, set[str]]:
    """Every ``metric [unit]`` label and short Monte Carlo head (``sse cm``) in ``text``."""
    found: dict[str, set[str]] = {}
    for name, unit in re.findall(r"\b(\w+) \[([^\]]+)\]", text):
        found.setdefault(name, set()).add(unit)
    for short, name in (("sse", "sse_abs"), ("settling", "settling_time_s")):
        for unit in re.findall(rf"\b{short} (\S+) ", text):
            found.setdefault(name, set()).add(unit)
    return found


def test_compare_and_the_tuning_tables_show_one_display_unit_per_quantity():
    """dinca_cylinder shows its position in cm (its ``display_unit``): compare, the tune
    table and the Monte Carlo table all show sse_abs in cm, with the same numbers."""
    rig = rig_named("dinca_cylinder")
    result = compare(rig, [controller_named("p_k10"), controller_named("flc2_reshaped")], "steps")
    units = metric_units(rig)
    assert units == metric_units(result["p_k10"]) == MetricUnits("m", "cm")
    rows = [result.metrics[n].aggregate for n in result]
    nominal = {m: rows[0][m] for m in SUMMARY_METRICS}
    summary = {
        "gain_margin_checked": 2.0,
        "samples": 1,
        "seed": 0,
        "controllers": [
            {"controller": "p_k10", "samples": 1, "failures": 0,
             "nominal": {"objective": 1.0, "gain_margin_holds": True, **nominal},
             **{m: {"p50": v, "p90": v, "worst": v} for m, v in nominal.items()}}
        ],
    }  # fmt: skip
    text = "\n".join(
        [result.text(), metrics_table(["a", "b"], rows, units), comparison_text(summary, units)]
    )
    labels = _labels(text)
    assert labels["sse_abs"] == {"cm"} and labels["settling_time_s"] == {"s"}
    assert labels["ise"] == {"cm²·s"} and labels["iae"] == {"cm·s"}
    cm = f"{rows[0]['sse_abs'] * 100:.4g}"
    assert text.count(cm) >= 3  # compare, the tune table and the Monte Carlo row
    data = result.to_dict()
    assert data["units"]["sse_abs"] == "m" and data["units"]["ise"] == "m²·s"


def test_undefined_metrics_are_explained_where_they_are_printed():
    rows = [{"rise_time_s": math.nan, "iae": 0.1}, {"rise_time_s": 0.2, "iae": 0.1}]
    note = undefined_note(("rise_time_s", "iae"), rows)
    assert note.startswith("n/a (rise_time_s): undefined") and "brake" in note
    assert undefined_note(("iae",), rows) == ""


def test_tune_explains_the_brake_scenarios_n_a_and_counts_its_trials(tmp_path):
    """A study scored on the ehs160 brake (a constant reference: no step metrics) prints
    why its metrics are n/a and why the objective is the penalty, in the console text and
    in report.md; the trials read asked / complete / pruned / failed."""
    from support import DATA

    from fuzzyservo.io.studies import load_study
    from fuzzyservo.tuning.runner import run_study
    from fuzzyservo.workflows import write_study_report

    spec = dataclasses.replace(
        load_study(DATA / "studies" / "ehs160_flc.yaml"), scenarios=("steps", "brake")
    )
    outcome = run_study(spec, tmp_path, trials=2, workers=1, progress=False)
    result, paths = write_study_report(outcome, tmp_path)
    text = result.text()
    report = paths["report"].read_text(encoding="utf-8")
    for shown in (text, report):
        assert "n/a (rise_time_s, settling_time_s" in shown and "brake" in shown
        assert "2 asked: 2 complete, 0 pruned, 0 failed" in shown
    assert "baseline: status undefined (" in text
    assert "sse_abs [rad/s]" in text and "| `ise` [(rad/s)²·s] |" in report
