"""A robust study's value is a statistic over a few sampled plants: its standard error,
and the choice of the winner on samples the search never saw.

* :func:`standard_error`: of the mean, σ/√n; of the worst or the CVaR (no closed form
  over a handful of samples), the spread of the statistic over bootstrap resamples of the
  samples (Efron and Tibshirani, *An Introduction to the Bootstrap*, 1993, ch. 6), with a
  fixed seed so a report reads the same twice.
* :func:`fresh_uncertainty`: the study's uncertainty drawn again with another seed, derived
  from the study's own. The best trials of a search over noisy values are biased low (the
  winner's curse; optuna#4124): the top :data:`TOP` are scored again on these fresh plants
  and the lowest fresh value wins.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from fuzzyservo.tuning.uncertainty.sets import Uncertainty, aggregate

#: the best trials scored again on fresh samples before the winner is declared
TOP = 5
#: added to the study's uncertainty seed for the fresh samples (a prime: no other draw of
#: the study uses it; the report's Monte Carlo check has its own seed)
FRESH_SEED_OFFSET = 104_729
BOOTSTRAP_RESAMPLES = 2000


def standard_error(values: Sequence[float], how: str, alpha: float = 0.25) -> float:
    """The standard error of ``aggregate(values, how, alpha)`` (see the module docstring);
    NaN for fewer than two values or any value not finite."""
    v = np.asarray(values, dtype=float)
    if v.size < 2 or not np.isfinite(v).all():
        return math.nan
    if how == "mean":
        return float(v.std(ddof=1) / math.sqrt(v.size))
    rng = np.random.default_rng(0)
    picks = rng.integers(0, v.size, size=(BOOTSTRAP_RESAMPLES, v.size))
    stats = [aggregate(v[p], how, alpha) for p in picks]
    return float(np.std(stats, ddof=1))


def fresh_uncertainty(u: Uncertainty) -> Uncertainty:
    """``u`` with new draws (seed ``u.seed + FRESH_SEED_OFFSET``), as many as ``u``'s."""
    return dataclasses.replace(u, seed=u.seed + FRESH_SEED_OFFSET, draws=())
