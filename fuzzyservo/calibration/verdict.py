"""The verdict in words: the lines the console and the report print, read from a
calibration's summary (:func:`~fuzzyservo.calibration.summary.calibration_summary`)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from fuzzyservo.calibration.decision import ALPHA
from fuzzyservo.calibration.identifiability import SWEEP_HZ, Separation
from fuzzyservo.calibration.replay import Replay
from fuzzyservo.components.effects import LIBRARY
from fuzzyservo.display import quantity_text
from fuzzyservo.metrics import format_value
from fuzzyservo.rig import Rig

if TYPE_CHECKING:
    pass


def experiment_words(experiment: Separation, replay: Replay, rig: Rig) -> str:
    """The experiment (identifiability.excitations) as a test engineer would ask for
    it, in the rig's units: "a run of the same reference under a constant 990 N load
    pulling in the + direction" (a positive load resists motion in the + direction)."""
    record = getattr(replay, "records", (replay,))[0]  # the one the experiment varies
    fb = rig.feedback
    position_unit = rig.plant.signal_units.get(fb.signal, "")
    recorded = np.asarray(record.scenario.reference.sample(record.t), dtype=float)
    varied = np.asarray(experiment.scenario.reference.sample(record.t), dtype=float)
    name = experiment.name
    if name == "recorded":
        return "repeating the same run (more records of it, calibrated together)"
    if name.startswith("positions_"):
        (shift,), unit = quantity_text(
            [float(np.mean(varied - recorded)) / fb.slope], position_unit
        )
        sign = "+" if not shift.startswith("-") else ""
        return f"a run of the same reference shifted by {sign}{shift} {unit}".rstrip()
    if name.startswith("load_"):
        load = float(np.mean(experiment.scenario.load.sample(record.t)))
        (size,), unit = quantity_text([abs(load)], rig.plant.load[1])
        way = "resisting motion in" if load > 0 else "pulling in"
        return (
            f"a run of the same reference under a constant {size} {unit} load {way} the + direction"
        )
    if name == "sine_sweep":
        (amplitude,), unit = quantity_text(
            [float(np.ptp(varied)) / 2.0 / abs(fb.slope)], position_unit
        )
        return (
            f"a sine sweep from {SWEEP_HZ[0]:g} to {SWEEP_HZ[1]:g} Hz of ±{amplitude} {unit} about "
            "the recorded mid position"
        )
    return experiment.description


def verdict_lines(summary: dict[str, Any]) -> list[str]:
    """The verdict an engineer reads in ten seconds (the console's last lines): each
    effect added with its size in the rig's units and its 95 % interval, the held-out
    fit before -> after, the decision's error rate, then one line for each other effect
    judged (out-ranked, negligible, failed fit, failed, likely but not established:
    its size and the experiment that would settle it) and for each effect skipped."""
    added = summary["effects_added"]
    uncertainty = summary.get("uncertainty") or {}
    lines = []
    for e in added:
        lines.append(f"added: {e['name']}: {_added_size(e, uncertainty)}")
        if e["lookalike"]:
            lines.append(f"{e['name']} may also be {e['lookalike']}")
    if not added:
        tried = summary.get("rounds", True)
        lines.append("added: no effect" + ("" if tried else " (no candidate effect to try)"))
    before, after = summary.get("fit_before_pct"), summary.get("fit_after_pct")
    if before and after:
        lines.append(
            "held-out fit % (100 = perfect), before -> after: "
            + ", ".join(f"{c} {format_value(before[c])} -> {format_value(after[c])}" for c in after)
        )
    rate = error_rate_words(summary)
    if rate:
        lines.append(rate)
    judged = summary.get("judged", [])
    for j in judged:
        if j["verdict"] == "out-ranked":
            lines.append(
                f"out-ranked: {j['name']}, {judged_size(j)}: passes the test too, but "
                f"{j.get('first_in_round', 'another')} ranks first"
                + (f" ({j['reason']})" if j.get("reason") else "")
            )
    for j in summary["negligible"]:
        lines.append(f"negligible: {j['name']}, {judged_size(j)}: {j.get('reason') or _small(j)}")
    failed_fits = {j["name"]: j.get("reason", "") for j in judged if j["verdict"] == "failed fit"}
    last = summary["rounds"][-1]["candidates"] if summary.get("rounds") else []
    failed_fits.update(
        {c["name"]: "" for c in last if _failed_fit(c) and c["name"] not in failed_fits}
    )
    for name, reason in failed_fits.items():
        lines.append(
            f"failed fit: {name}: "
            + (
                reason
                or "its fit ended above the starting model's cost on the fitting part, which "
                "it contains: the search failed, and this record neither shows nor rules it out"
            )
        )
    for j in judged:
        if j["verdict"] == "failed":
            lines.append(
                f"failed: {j['name']}: "
                + (j.get("reason") or "its replay diverged at the fitted values: not judged")
            )
    for j in summary["not_established"]:
        e = j.get("experiment")
        if e:
            settle = f"{e.get('plain') or e['description']} would settle it"
        elif _beyond_range(j):
            settle = "this record cannot show it within the range the fit may take"
        else:
            settle = "too weak on this record to tell"
        lines.append(f"not established: {j['name']} may be present, {judged_size(j)}; {settle}")
    for name, why in summary.get("skipped_effects", {}).items():
        lines.append(f"skipped: {name}: {why}")
    return lines


def ranking_line(summary: dict[str, Any], shown: int = 5) -> str:
    """The first round's best candidates by fitted improvement (held-out cost, lowest
    first), with the cost of the model they start from ("" when no round ran)."""
    if not summary.get("rounds"):
        return ""
    first = summary["rounds"][0]
    ranked = sorted(first["candidates"], key=_score_key)
    shown_text = ", ".join(
        f"{c['name']} "
        + (
            "failed fit"
            if _failed_fit(c)
            else "failed"
            if not is_finite(c["score"])
            else format_value(c["score"])
        )
        for c in ranked[:shown]
    )
    return (
        "candidates, best fit first (held-out cost in noise units, lower is better: the "
        f"starting model {format_value(first['start_cost'])}, a perfect one 1): {shown_text}"
    )


def error_rate_words(summary: dict[str, Any]) -> str:
    """The decision's error rate on this record, worded as the decision's (how often it
    would add an effect to a record like this one that lacks it), not the finding's."""
    if not summary.get("rounds", True):
        return ""
    rate = summary.get("false_positive_rate")
    null = (summary.get("rounds") or [{}])[0].get("null") or {}
    draws = null.get("draws") or 0
    if rate is None or not draws:
        return (
            "error rate: no records like this one were drawn to measure it; where the "
            "model reproduces the data up to noise, this decision adds an effect the "
            f"record lacks in at most {100 * ALPHA:.0f} % of cases"
        )
    if rate == 0.0:
        how_often = f"under {100 / draws:.2g} % of cases (none of the {draws} tried)"
    else:
        how_often = (
            f"about {100 * rate:.2g} % of cases ({round(rate * draws)} of the {draws} tried)"
        )
    return (
        "error rate: on records like this one without a missing effect, this decision "
        f"would add one in {how_often}"
    )


def _failed_fit(c: dict[str, Any]) -> bool:
    """A summary candidate whose fit ended above the starting model (its status reads
    ``failed fit: <cause>``, candidates.fit)."""
    return str(c.get("status", "")).startswith("failed fit")


def _score_key(c: dict[str, Any]) -> tuple[float, str]:
    """Lowest held-out cost first; exact ties (fits that found nothing) by name."""
    return (c["score"] if is_finite(c["score"]) else math.inf, c["name"])


def is_finite(value: float | None) -> bool:
    return value is not None and math.isfinite(value)


def _added_size(e: dict[str, Any], uncertainty: dict[str, Any]) -> str:
    """Each fitted parameter of an added effect in its unit with its 95 % interval. A
    value on its bound is no size: the effect is "present, size unresolved", with the
    bound the data pressed against and the value the record trades it against."""
    parts, unresolved = [], []
    for param in LIBRARY[e["name"]].fitted:
        value = e["params"].get(param.key, 0.0)
        if param.optional and not value:
            continue  # an optional part left off (friction that does not stick)
        unit = e.get("units", {}).get(param.key, "")
        u = uncertainty.get(f"{e['name']}.{param.key}")
        if u is not None and u["at_bound"]:
            trade = (
                f", traded against {u['trades_with']} (correlation {u['correlation']:.2f})"
                if u.get("trades_with")
                else ""
            )
            unresolved.append(
                f"{param.key} pressed against its bound {_quantity(value, unit)}{trade}"
            )
            continue
        if u is None or not all(is_finite(v) for v in u["interval"]):
            parts.append(f"{param.key} {_quantity(value, unit)}")
            continue
        lo, hi = u["interval"]
        (text, a, b), shown = quantity_text([value, lo, hi], unit, _digits(value, lo, hi))
        shown = f" {shown}" if shown else ""
        parts.append(f"{param.key} {text}{shown} (95 % interval {a} to {b}{shown})")
    for name, keys in LIBRARY[e["name"]].totals:  # a Stribeck law's breakaway force
        units = {e.get("units", {}).get(k, "") for k in keys}
        if len(units) == 1 and all(k in e["params"] for k in keys):
            total = sum(e["params"][k] for k in keys)
            parts.append(f"{name} ({' + '.join(keys)}) {_quantity(total, units.pop())}")
    if unresolved:
        parts.insert(0, f"present, size unresolved ({'; '.join(unresolved)}: widen the bound "
                        "with fit: [lower, upper] if physics allows)")  # fmt: skip
    return "; ".join(parts)


def _quantity(value: float, unit: str) -> str:
    """``value`` in the display form of ``unit`` (``121 N``; a bare number without one)."""
    (text,), shown = quantity_text([value], unit)
    return f"{text} {shown}".rstrip()


def _digits(value: float, lo: float, hi: float) -> int:
    """Significant digits that show an interval's half-width to two."""
    half = (hi - lo) / 2.0
    if not (half > 0.0 and value != 0.0):
        return 3
    return min(max(math.floor(math.log10(abs(value))) - math.floor(math.log10(half)) + 2, 3), 6)


def judged_size(j: dict[str, Any]) -> str:
    """A judged candidate's approximate size in its unit: its size parameter (report
    ``size``) or every fitted parameter."""
    units = j.get("units", {})
    if "size" in j:
        keys = [j["size"]["param"]]
    else:
        fitted = {p.key for p in LIBRARY[j["name"]].fitted} if j["name"] in LIBRARY else set()
        keys = [k for k in j["params"] if k in fitted] or list(j["params"])
    parts = []
    for key in keys:
        (text,), unit = quantity_text([j["params"][key]], units.get(key, ""))
        parts.append(f"{key} about {text} {unit}".rstrip())
    return ", ".join(parts)


def _small(j: dict[str, Any]) -> str:
    """Why a candidate that passes the test is negligible (a summary without ``reason``):
    within the starting model's prediction band, or below what matters on this record."""
    share = 100 * j["share_of_residual"]
    if j["share_needed"] > 0.0 and j["share_of_residual"] < j["share_needed"]:
        return (
            f"it moves the outputs by {share:.1f} % of the residual level, less than the "
            "starting model's fitted effects move them within their 95 % intervals "
            f"({100 * j['share_needed']:.1f} %)"
        )
    return "too small to matter" + (f" ({limit_words(j)})" if "size" in j else "")


def _beyond_range(j: dict[str, Any]) -> bool:
    """The detection limit lies beyond the range the fit may take."""
    if "size" not in j:
        return False
    size = j["size"]
    if not is_finite(size["limit"]):
        return True
    lo, hi = size["range"]
    return abs(size["limit"]) > (hi if size["limit"] >= 0 else -lo)


def limit_words(j: dict[str, Any]) -> str:
    """The detection limit in words and in the parameter's unit: the size (its
    magnitude for a signed one found below 0) from which this record shows it, and
    whether the fit's range reaches it at all."""
    size = j["size"]
    limit, name = size["limit"], size["param"]
    if not is_finite(limit):
        return "this record cannot show it at any size"
    unit = j.get("units", {}).get(name, "")
    (text,), shown = quantity_text([abs(limit)], unit)
    words = f"this record shows it from {'|' + name + '|' if limit < 0 else name} {text} {shown}"
    if _beyond_range(j):
        lo, hi = size["range"]
        (reach,), shown = quantity_text([hi if limit >= 0 else -lo], unit)
        words += f", beyond the {reach} {shown} the fit may take"
    return words.replace("  ", " ").rstrip()
