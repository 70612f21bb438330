"""Tuning and checking under uncertainty, in one package.

- :mod:`.sets`: a study's ``uncertainty:`` (distributions of plant values, the sampled
  plants, how values over the samples aggregate);
- :mod:`.noise`: a robust objective's standard error and fresh samples for the best trials;
- :mod:`.robust`: the robust objective (a trial on every sampled plant, one evaluation)
  and the comparison of controllers on fresh plants;
- :mod:`.robustness`: runs on sampled plants, margin checks and their summaries;
- :mod:`.montecarlo`: ``fuzzyservo robustness`` (:func:`~.montecarlo.robustness`).
"""

from fuzzyservo.tuning.uncertainty.sets import (
    IO_DELAY,
    KINDS,
    SAMPLE_AGGREGATES,
    Distribution,
    Sample,
    Uncertainty,
    aggregate,
    sample_rig,
)

__all__ = [
    "IO_DELAY", "KINDS", "SAMPLE_AGGREGATES", "Distribution", "Sample", "Uncertainty",
    "aggregate", "sample_rig",
]  # fmt: skip
