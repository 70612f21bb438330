"""A controller on many sampled plants: metrics, failures, and margin checks per sample.

Used by robust studies (each trial on the study's samples) and by
``fuzzyservo robustness`` (Monte Carlo of several controllers). A sample *fails* when a
scenario diverges, fails a step or hits an end stop, or when a margin check does not hold.

Margin checks take one simulation each: the loop has a gain margin of at least ``g``
when it does not oscillate with the controller output multiplied by ``g``
(:func:`~fuzzyservo.analysis.margins.scaled`, the detector of
:func:`~fuzzyservo.analysis.margins.oscillation`); the delay margin likewise with the
extra delay added. That is the bisection of :mod:`fuzzyservo.analysis.margins` reduced to
its last question, at a tenth of its cost.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from fuzzyservo.analysis.margins import stable_at
from fuzzyservo.controllers.base import Controller
from fuzzyservo.display import MetricUnits
from fuzzyservo.metrics import METRIC_NAMES, result_metrics
from fuzzyservo.metrics import format_value as fmt
from fuzzyservo.rig import Rig
from fuzzyservo.simulation import SimResult, simulate


@dataclass(frozen=True)
class SampleRun:
    """One controller on one sampled plant: ``metrics`` aggregated over the scenarios."""

    index: int
    status: str
    message: str
    metrics: dict[str, float]
    scenario_metrics: dict[str, dict[str, float]]
    gain_holds: bool | None = None
    delay_holds: bool | None = None
    results: dict[str, SimResult] = field(default_factory=dict, repr=False)

    @property
    def failed(self) -> bool:
        return self.status != "ok" or self.gain_holds is False or self.delay_holds is False

    @property
    def reason(self) -> str:
        if self.status != "ok":
            return self.message
        why = []
        if self.gain_holds is False:
            why.append("oscillates at the required gain margin")
        if self.delay_holds is False:
            why.append("oscillates at the required delay margin")
        return "; ".join(why)


def run_sample(
    index: int,
    rig: Rig,
    controller: Controller,
    scenarios: Sequence[str],
    noise_seed: int,
    *,
    aggregate: str = "worst",
    gain: float | None = None,
    delay_s: float | None = None,
    margin_scenario: str | None = None,
    keep_results: bool = False,
    stop: Callable[[dict[str, float]], bool] | None = None,
    ran: dict[str, SimResult] | None = None,
) -> SampleRun:
    """Simulate every scenario on ``rig`` (noise seeded ``noise_seed``), then the margin
    checks asked for (``gain``, ``delay_s``) on ``margin_scenario``, unless a run failed.

    ``stop(metrics)``, when given, is asked after each scenario but the last with the
    metrics aggregated over the scenarios run so far; True ends the sample there with
    status ``pruned`` (a robust trial that is already lost: tuning/uncertainty/robust.py).
    ``ran``: the scenarios' results already simulated (in lock-step with other samples,
    :func:`lockstep_runs`), taken instead of simulating them again."""
    per: dict[str, dict[str, float]] = {}
    results: dict[str, SimResult] = {}
    status, message = "ok", ""
    for n, scenario in enumerate(scenarios, 1):
        r = (ran or {}).get(scenario)
        if r is None:
            r = simulate(rig, controller, scenario, noise_seed=noise_seed)
        if keep_results:
            results[scenario] = r
        per[scenario] = result_metrics(r).aggregate
        if r.status != "ok":
            status, message = r.status, f"{scenario}: {r.message}"
            break
        if stop is not None and n < len(scenarios) and stop(_over_scenarios(per, aggregate)):
            status, message = "pruned", f"after {', '.join(per)}"
            break
    metrics = _over_scenarios(per, aggregate) if status in ("ok", "pruned") else {}
    gain_ok = delay_ok = None
    if status == "ok":
        gain_ok, delay_ok = margin_checks(
            rig, controller, margin_scenario or scenarios[0], noise_seed, gain, delay_s
        )
    return SampleRun(index, status, message, metrics, per, gain_ok, delay_ok, results)


def lockstep_runs(
    rigs: Sequence[Rig],
    controller: Controller,
    scenarios: Sequence[str],
    noise_seeds: Sequence[int],
) -> list[dict[str, SimResult]]:
    """Every scenario on each rig of ``rigs`` (each with its noise seed), the rigs of one
    scenario in one compiled call (:func:`~fuzzyservo.simulation.closed_loop.
    simulate_batch`, parallel over the cores): per rig, its results by scenario, each the
    one :func:`simulate` gives (for :func:`run_sample`'s ``ran``)."""
    from fuzzyservo.simulation.closed_loop import simulate_batch

    out: list[dict[str, SimResult]] = [{} for _ in rigs]
    for scenario in scenarios:
        for ran, r in zip(out, simulate_batch(rigs, controller, scenario, noise_seeds),
                          strict=True):  # fmt: skip
            ran[scenario] = r
    return out


def margin_checks(
    rig: Rig,
    controller: Controller,
    scenario: str,
    noise_seed: int,
    gain: float | None,
    delay_s: float | None,
) -> tuple[bool | None, bool | None]:
    """The margin checks asked for, one run each on ``scenario``: does the loop stay free
    of oscillation with the output times ``gain``, and with ``delay_s`` more delay?
    ``None`` for a check not asked for."""
    gain_ok = delay_ok = None
    if gain is not None:
        gain_ok = stable_at(rig, controller, scenario, multiplier=gain, noise_seed=noise_seed)
    if delay_s is not None:
        delay_ok = stable_at(rig, controller, scenario, extra_delay_s=delay_s,
                             noise_seed=noise_seed)  # fmt: skip
    return gain_ok, delay_ok


def run_samples(
    indices: Sequence[int],
    rigs: Sequence[Rig],
    controller: Controller,
    scenarios: Sequence[str],
    noise_seeds: Sequence[int],
    *,
    aggregate: str = "worst",
) -> list[SampleRun]:
    """:func:`run_sample` on each rig in turn (no margin checks), up to and including the
    first whose run fails: the runs of a robust trial that nothing else stops early. The
    rigs go through each scenario in lock-step, in one compiled call
    (:func:`~fuzzyservo.simulation.closed_loop.simulate_batch`, parallel over the cores);
    a rig after one that failed is run at most once more, and dropped."""
    from fuzzyservo.simulation.closed_loop import simulate_batch

    per: list[dict[str, dict[str, float]]] = [{} for _ in rigs]
    failed: dict[int, tuple[str, str]] = {}
    alive = len(rigs)  # only rigs before the first failure count
    for scenario in scenarios:
        todo = [i for i in range(alive) if i not in failed]
        if not todo:
            break
        results = simulate_batch([rigs[i] for i in todo], controller, scenario,
                                 [noise_seeds[i] for i in todo])  # fmt: skip
        for i, r in zip(todo, results, strict=True):
            per[i][scenario] = result_metrics(r).aggregate
            if r.status != "ok":
                failed[i] = (r.status, f"{scenario}: {r.message}")
        if failed:
            alive = min(failed) + 1
    runs = []
    for i in range(alive):
        status, message = failed.get(i, ("ok", ""))
        metrics = _over_scenarios(per[i], aggregate) if status == "ok" else {}
        runs.append(SampleRun(indices[i], status, message, metrics, per[i]))
    return runs


def margin_checks_batch(
    rigs: Sequence[Rig],
    controller: Controller,
    scenario: str,
    noise_seeds: Sequence[int],
    gain: float | None,
    delay_s: float | None,
) -> list[tuple[bool | None, bool | None]]:
    """:func:`margin_checks` on every rig of ``rigs`` (each with its noise seed), each
    check in one compiled call over the rigs (:func:`~fuzzyservo.simulation.closed_loop.
    simulate_batch`, parallel over the cores): the same verdicts, one pair per rig."""
    from fuzzyservo.analysis.margins import delayed, oscillation, scaled
    from fuzzyservo.simulation.closed_loop import simulate_batch

    def verdicts(pairs: list[tuple[Rig, Controller]]) -> list[bool]:
        results = simulate_batch([r for r, _ in pairs], pairs[0][1], scenario, noise_seeds)
        return [not oscillation(r).sustained for r in results]

    n = len(rigs)
    gain_ok: list[bool | None] = [None] * n
    delay_ok: list[bool | None] = [None] * n
    if n and gain is not None:  # as stable_at(multiplier=gain)
        gain_ok = verdicts(
            [scaled(r, controller, gain) if gain != 1.0 else (r, controller) for r in rigs]
        )
    if n and delay_s is not None:  # as stable_at(extra_delay_s=delay_s)
        gain_free = [(delayed(r, delay_s) if delay_s > 0.0 else r, controller) for r in rigs]
        delay_ok = verdicts(gain_free)
    return list(zip(gain_ok, delay_ok, strict=True))


def _over_scenarios(per: dict[str, dict[str, float]], how: str) -> dict[str, float]:
    out = {}
    for m in METRIC_NAMES:
        vals = [s[m] for s in per.values()]
        if any(not math.isfinite(v) for v in vals):
            out[m] = math.nan
        else:
            out[m] = max(vals) if how == "worst" else sum(vals) / len(vals)
    return out


@dataclass(frozen=True)
class MonteCarlo:
    """One controller on every sample: the runs, and their metric distributions."""

    controller: str
    runs: list[SampleRun]

    @property
    def failures(self) -> list[SampleRun]:
        return [r for r in self.runs if r.failed]

    def values(self, metric: str) -> np.ndarray:
        """``metric`` of the samples that ran through (NaN where it is undefined)."""
        return np.array([r.metrics.get(metric, math.nan) for r in self.runs if r.status == "ok"])

    def percentiles(self, metric: str, qs: Sequence[float] = (50, 90, 100)) -> list[float]:
        v = self.values(metric)
        if v.size == 0:
            return [math.nan for _ in qs]
        if not np.isfinite(v).all():  # an undefined metric (never settles) counts as worst
            v = np.where(np.isfinite(v), v, math.inf)
        return [float(np.percentile(v, q, method="higher")) for q in qs]

    def worst(self, metric: str) -> SampleRun | None:
        ok = [r for r in self.runs if r.status == "ok"]
        if not ok:
            return None

        def key(r: SampleRun) -> float:
            v = r.metrics.get(metric, math.nan)
            return v if math.isfinite(v) else math.inf

        return max(ok, key=key)


def monte_carlo(
    rig: Rig,
    controllers: Sequence[Controller],
    rigs: Sequence[Rig],
    noise_seeds: Sequence[int],
    scenarios: Sequence[str],
    *,
    gain: float | None = 2.0,
    margin_scenarios: Sequence[str] | None = None,
    progress=None,
    chunk: int = 16,
) -> list[MonteCarlo]:
    """Every controller on every sampled plant ``rigs`` (noise seeds alike: common random
    numbers). The gain check (``gain``) runs on each of ``margin_scenarios`` (default: all
    ``scenarios``) and holds only when it holds on all. ``progress(k)`` is called as runs
    finish, ``k`` samples at a time.

    The samples go ``chunk`` at a time through one compiled call per scenario and per gain
    check (:func:`~fuzzyservo.simulation.closed_loop.simulate_batch`, parallel over the
    cores); each sample's runs are the ones :func:`run_sample` and
    :func:`~fuzzyservo.analysis.margins.stable_at` make: a sample whose run fails skips
    its later scenarios and the gain check, and the gain check stops at the first scenario
    where the loop oscillates."""
    from fuzzyservo.analysis.margins import oscillation, scaled
    from fuzzyservo.simulation.closed_loop import simulate_batch

    where = list(margin_scenarios or scenarios)
    out = []
    for controller in controllers:
        runs: list[SampleRun] = []
        for start in range(0, len(rigs), chunk):
            idx = range(start, min(start + chunk, len(rigs)))
            per: dict[int, dict[str, dict[str, float]]] = {i: {} for i in idx}
            failed: dict[int, str] = {}
            status: dict[int, str] = {}
            for scenario in scenarios:
                todo = [i for i in idx if i not in failed]
                results = simulate_batch([rigs[i] for i in todo], controller, scenario,
                                         [noise_seeds[i] for i in todo])  # fmt: skip
                for i, r in zip(todo, results, strict=True):
                    per[i][scenario] = result_metrics(r).aggregate
                    if r.status != "ok":
                        status[i], failed[i] = r.status, f"{scenario}: {r.message}"
            held: dict[int, bool | None] = {i: None for i in idx}
            if gain is not None:
                for i in idx:
                    if i not in failed:
                        held[i] = True
                for scenario in where:
                    todo = [i for i in idx if held[i]]
                    pairs = [scaled(rigs[i], controller, gain) for i in todo]
                    if not pairs:
                        break
                    results = simulate_batch([r for r, _ in pairs], pairs[0][1], scenario,
                                             [noise_seeds[i] for i in todo])  # fmt: skip
                    for i, r in zip(todo, results, strict=True):
                        held[i] = not oscillation(r).sustained
            for i in idx:
                ok = i not in failed
                metrics = _over_scenarios(per[i], "worst") if ok else {}
                runs.append(SampleRun(i, status.get(i, "ok"), failed.get(i, ""), metrics,
                                      per[i], held[i]))  # fmt: skip
            if progress is not None:
                progress(len(idx))
        out.append(MonteCarlo(controller.name, runs))
    return out


#: the metrics a Monte Carlo summary shows (units: the schema, metrics.METRIC_UNITS)
SUMMARY_METRICS: tuple[str, ...] = (
    "settling_time_s",
    "sse_abs",
    "overshoot_pct",
    "saturation_time_s",
)
# their short column heads
_SHORT = {"settling_time_s": "settling", "sse_abs": "sse", "overshoot_pct": "overshoot",
          "saturation_time_s": "saturated"}  # fmt: skip


def summary(mcs: Sequence[MonteCarlo], gain: float | None) -> list[dict[str, object]]:
    """Per controller: samples, failures (with the gain check), and the median, 90th
    percentile and worst of each :data:`SUMMARY_METRICS` (an undefined value counts as worst)."""
    rows = []
    for mc in mcs:
        row: dict[str, object] = {
            "controller": mc.controller,
            "samples": len(mc.runs),
            "failures": len(mc.failures),
            "runs_failed": sum(r.status != "ok" for r in mc.runs),
        }
        if gain is not None:
            row["gain_margin_holds"] = sum(r.gain_holds is True for r in mc.runs)
            row["gain_margin_checked"] = gain
        for m in SUMMARY_METRICS:
            p50, p90, worst = mc.percentiles(m)
            row[m] = {"p50": p50, "p90": p90, "worst": worst}
        rows.append(row)
    return rows


def summary_text(rows: Sequence[dict], units: MetricUnits) -> str:
    """The Monte Carlo table of :func:`summary` rows (SI values): failures and median /
    90 % / worst of each metric, in its display unit (``units``)."""
    head = f"{'controller':<22} {'failures':>9} {'gain ok':>8}"
    for m in SUMMARY_METRICS:
        head += f"  {_SHORT[m] + ' ' + units.unit(m) + ' p50/p90/max':>26}"
    lines = [head]
    for r in rows:
        gain = (
            f"{r.get('gain_margin_holds', '-')}/{r['samples']}" if "gain_margin_holds" in r else "-"
        )
        line = f"{r['controller']:<22} {r['failures']:>5}/{r['samples']:<3} {gain:>8}"
        for m in SUMMARY_METRICS:
            line += "  " + "/".join(
                fmt(units.value(m, r[m][q])) for q in ("p50", "p90", "worst")
            ).rjust(26)
        lines.append(line)
    lines.append(
        "failures: samples whose run did not end ok (diverged, end stop, cavitation) or whose "
        "loop oscillates at the checked margin; gain ok: samples that hold the gain margin; "
        "p50/p90/max over the samples that ran through"
    )
    return "\n".join(lines)


def comparison_text(comparison: dict, units: MetricUnits) -> str:
    """A robust study's comparison (the ``comparison`` of its ``summary.json``, SI): the
    nominal plant, then the Monte Carlo table, in display units (``units``)."""
    c = comparison
    nominal = SUMMARY_METRICS[:3]
    lines = [f"nominal plant: {'controller':<22} {'objective':>9} "
             + " ".join(f"{_SHORT[m] + ' ' + units.unit(m):>12}" for m in nominal)
             + f" {'gain ' + format(c['gain_margin_checked'], 'g'):>7}"]  # fmt: skip
    for r in c["controllers"]:
        n = r["nominal"]
        ok = {True: "holds", False: "FAILS", None: "-"}[n["gain_margin_holds"]]
        lines.append(
            f"{'':15}{r['controller']:<22} {fmt(n['objective']):>9} "
            + " ".join(f"{fmt(units.value(m, n[m])):>12}" for m in nominal)
            + f" {ok:>7}"
        )
    lines.append(f"Monte Carlo on {c['samples']} fresh samples (seed {c['seed']}):")
    lines.append(summary_text(c["controllers"], units))
    return "\n".join(lines)
