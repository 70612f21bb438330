"""Figures of a tuning study: trial history, parameter importances, Pareto front.

They take plain records (the trial history as ``{number, values, status, feasible}``
mappings, as :class:`~fuzzyservo.tuning.outcome.StudyOutcome` holds it), so they need no
Optuna. A trial whose simulation failed carries the study's penalty instead of a
measured value; it is drawn as a mark at the top of the panel, never at its value,
which would flatten every real one.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

# A panel switches to a log axis when its values span more than this ratio (2 decades).
_LOG_SPAN = 100.0
_FEASIBLE = "tab:blue"
_INFEASIBLE = "tab:orange"
_PENALISED = "tab:red"
_BEST = "black"
_FRONT = "tab:red"
_BASELINE = "gold"


def history_figure(
    history: Sequence[Mapping], names: Sequence[str], *, title: str | None = None
) -> Figure:
    """Objective value(s) of every complete trial against its number, with the best so far.

    One panel per objective (``names``, one per entry of each trial's ``values``).
    Feasible trials are filled dots, trials that break a constraint hollow orange
    circles, trials whose simulation failed (``status`` other than ``"ok"``: their value
    is the penalty) red crosses along the top edge. The best-so-far line follows the
    feasible trials (the ``ok`` ones when none is feasible). A panel is logarithmic when
    its measured values are positive and span more than two decades.
    """
    names = list(names)
    if not names:
        raise ValueError("history_figure needs at least one objective name, got none")
    for h in history:
        if len(h["values"]) != len(names):
            raise ValueError(
                f"trial {h['number']} has {len(h['values'])} values but {len(names)} objective "
                f"names were given ({names}); give one name per value"
            )
    fig = Figure(figsize=(10.0, 0.8 + 2.8 * len(names)), layout="constrained")
    axes = fig.subplots(len(names), 1, sharex=True, squeeze=False)[:, 0]
    number = np.array([h["number"] for h in history], dtype=float)
    ok = np.array([h.get("status") == "ok" for h in history], dtype=bool)
    feasible = np.array([bool(h.get("feasible")) for h in history], dtype=bool) & ok
    for k, (ax, name) in enumerate(zip(axes, names, strict=True)):
        values = np.array([float(h["values"][k]) for h in history], dtype=float)
        _history_panel(ax, number, values, ok, feasible)
        ax.set_ylabel(name)
        ax.grid(True, color="0.85", lw=0.6)
    axes[-1].set_xlabel("trial number")
    # beside the panels: the penalised marks run along the top edge
    axes[0].legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    fig.suptitle(title or f"trial history ({len(history)} complete trials)")
    return fig


def _history_panel(
    ax: Axes, number: np.ndarray, values: np.ndarray, ok: np.ndarray, feasible: np.ndarray
) -> None:
    measured = ok & np.isfinite(values)
    good, bad = measured & feasible, measured & ~feasible
    ax.plot(
        number[good], values[good], "o", ms=4, color=_FEASIBLE, label=f"feasible ({good.sum()})"
    )
    if bad.any():
        ax.plot(number[bad], values[bad], "o", ms=5, mfc="none", color=_INFEASIBLE,
                label=f"constraint broken ({bad.sum()})")  # fmt: skip
    pool = good if good.any() else measured
    if pool.any():
        order = np.argsort(number[pool], kind="stable")
        best = np.minimum.accumulate(values[pool][order])
        ax.step(number[pool][order], best, where="post", color=_BEST, lw=1.4, label="best so far")
    failed = ~ok
    if failed.any():
        # the penalty is not a measurement: mark the trial, not the value
        ax.plot(number[failed], np.full(failed.sum(), 0.97), "x", ms=6, color=_PENALISED,
                transform=ax.get_xaxis_transform(), clip_on=False,
                label=f"simulation failed, penalised ({failed.sum()})")  # fmt: skip
    if _wants_log(values[measured]):
        ax.set_yscale("log")


def importance_figure(importances: Mapping[str, float], *, title: str | None = None) -> Figure:
    """Horizontal bars of each parameter's importance (normalised to sum to 1), largest on top."""
    if not importances:
        raise ValueError("importance_figure needs at least one parameter importance, got none")
    items = sorted(importances.items(), key=lambda kv: kv[1])
    names = [k for k, _ in items]
    values = np.array([float(v) for _, v in items])
    fig = Figure(figsize=(7.0, 1.0 + 0.42 * len(items)), layout="constrained")
    ax = fig.subplots()
    y = np.arange(len(items))
    ax.barh(y, values, color=_FEASIBLE, height=0.6)
    for yk, v in zip(y, values, strict=True):
        ax.annotate(f"{v:.2f}", (v, yk), xytext=(3, 0), textcoords="offset points",
                    va="center", fontsize=8)  # fmt: skip
    ax.set_yticks(y, names)
    ax.set_xlabel("importance (normalised: they sum to 1)")
    ax.set_xlim(0.0, max(1e-9, float(values.max())) * 1.15)
    ax.grid(True, axis="x", color="0.85", lw=0.6)
    ax.set_axisbelow(True)
    ax.set_title(title or "parameter importances")
    return fig


def pareto_figure(
    values: Sequence[Sequence[float]],
    front: Sequence[Sequence[float]],
    names: Sequence[str],
    *,
    baseline: Sequence[float] | None = None,
    best: Sequence[float] | None = None,
    title: str | None = None,
) -> Figure:
    """Every pair of objectives as a scatter: all trials grey, the front red, baseline a star.

    ``values`` are the objective vectors of the measured trials (leave penalised ones
    out), ``front`` those of the Pareto front, ``best`` the front member the study
    reports (circled). One panel per pair of ``names`` (three for three objectives); an
    axis is logarithmic when its values are positive and span more than two decades.
    With two objectives the front is joined in order of the first.
    """
    names = list(names)
    m = len(names)
    if m < 2:
        raise ValueError(f"pareto_figure needs two or more objectives, got names={names}")
    pts = _matrix(values, m, "values")
    fr = _matrix(front, m, "front")
    base = None if baseline is None else _matrix([baseline], m, "baseline")[0]
    chosen = None if best is None else _matrix([best], m, "best")[0]
    pairs = list(itertools.combinations(range(m), 2))
    ncols = min(3, len(pairs))
    nrows = math.ceil(len(pairs) / ncols)
    fig = Figure(figsize=(4.4 * ncols, 0.6 + 4.0 * nrows), layout="constrained")
    axes = fig.subplots(nrows, ncols, squeeze=False).ravel()
    for ax in axes[len(pairs) :]:
        fig.delaxes(ax)
    for ax, (i, j) in zip(axes, pairs, strict=False):
        ax.plot(pts[:, i], pts[:, j], "o", ms=3, color="0.65", label=f"trials ({len(pts)})")
        if m == 2 and len(fr):
            order = np.argsort(fr[:, i], kind="stable")
            ax.plot(fr[order, i], fr[order, j], "-", color=_FRONT, lw=1.0, alpha=0.6)
        ax.plot(fr[:, i], fr[:, j], "o", ms=5, color=_FRONT, label=f"Pareto front ({len(fr)})")
        if base is not None:
            ax.plot(base[i], base[j], "*", ms=15, mfc=_BASELINE, mec="black", label="baseline")
        if chosen is not None:
            ax.plot(chosen[i], chosen[j], "o", ms=14, mfc="none", mec=_BEST, mew=1.6,
                    label="reported best")  # fmt: skip
        for axis, k, setter in ((pts[:, i], i, ax.set_xscale), (pts[:, j], j, ax.set_yscale)):
            extra = [base[k]] if base is not None else []
            if _wants_log(np.concatenate([axis, fr[:, k], extra])):
                setter("log")
        ax.set_xlabel(names[i])
        ax.set_ylabel(names[j])
        ax.grid(True, color="0.85", lw=0.6)
    axes[0].legend(loc="best", fontsize=8)
    fig.suptitle(title or "objectives of every trial, Pareto front highlighted")
    return fig


def _matrix(rows: Sequence[Sequence[float]], m: int, what: str) -> np.ndarray:
    rows = [list(r) for r in rows]
    wrong = [len(r) for r in rows if len(r) != m]
    if wrong:
        raise ValueError(
            f"{what}: each entry needs {m} values (one per objective name), got one with "
            f"{wrong[0]}; pass the objective vectors in the order of names"
        )
    return np.array(rows, dtype=float).reshape(-1, m)


def _wants_log(values: np.ndarray) -> bool:
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size < 2 or np.any(v <= 0):
        return False
    return float(v.max() / v.min()) > _LOG_SPAN
