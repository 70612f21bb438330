"""Robustness of controllers: a Monte Carlo on plants drawn from a robust study's
``uncertainty:`` (what ``fuzzyservo robustness`` runs).

:func:`plan` draws the plants, :meth:`RobustnessPlan.run` simulates every controller
on each (:func:`~fuzzyservo.tuning.uncertainty.robustness.monte_carlo`); :func:`robustness`
does both.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fuzzyservo.display import MetricUnits, metric_units
from fuzzyservo.errors import ConfigError
from fuzzyservo.results import Result
from fuzzyservo.tuning.uncertainty.robustness import (
    SUMMARY_METRICS,
    MonteCarlo,
    monte_carlo,
    run_sample,
    summary,
    summary_text,
)

if TYPE_CHECKING:
    import numpy as np

    from fuzzyservo.controllers.base import Controller
    from fuzzyservo.rig import Rig
    from fuzzyservo.simulation import SimResult
    from fuzzyservo.tuning.spec import Study
    from fuzzyservo.tuning.uncertainty.sets import Uncertainty


@dataclass(frozen=True)
class RobustnessResult(Result):
    """Every controller on every drawn plant: the distributions, failures and gain checks."""

    rig: str
    uncertainty: Uncertainty
    scenarios: tuple[str, ...]
    gain_margin: float | None
    runs: tuple[MonteCarlo, ...]
    controllers: tuple[Controller, ...] = field(repr=False)
    rigs: tuple[Rig, ...] = field(repr=False)
    units: MetricUnits = field(default_factory=MetricUnits)  # how the metrics are shown

    @property
    def failed(self) -> bool:
        """Did any controller fail on any sample?"""
        return any(mc.failures for mc in self.runs)

    def rows(self) -> list[dict[str, object]]:
        """Per controller: failures and the median, 90th percentile and worst of each metric."""
        return summary(self.runs, self.gain_margin)

    def text(self) -> str:
        u = self.uncertainty
        lines = [summary_text(self.rows(), self.units)]
        for mc in self.runs:
            for run in mc.failures[:3]:
                lines.append(f"{mc.controller}: {u.draws[run.index].describe(u.parameters)}: "
                             f"{run.reason}")  # fmt: skip
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        return {"rig": self.rig, "uncertainty": self.uncertainty.describe(),
                "units": self.units.si_units(SUMMARY_METRICS), "controllers": self.rows()}  # fmt: skip

    def distributions(self) -> dict[str, dict[str, np.ndarray]]:
        """Each summary metric's values by controller, in its display unit (for a
        distribution figure labelled with ``units.unit``)."""
        return {m: {mc.controller: mc.values(m) * self.units.factor(m) for mc in self.runs}
                for m in SUMMARY_METRICS}  # fmt: skip

    def worst_runs(self) -> dict[str, tuple[str, dict[str, SimResult]]]:
        """Per controller, its first failure (else the sample it settles slowest on),
        described, and that sample simulated again with every scenario's result."""
        u, out = self.uncertainty, {}
        for mc, controller in zip(self.runs, self.controllers, strict=True):
            worst = (mc.failures or [mc.worst("settling_time_s")])[0]
            if worst is None:
                continue
            d = u.draws[worst.index]
            run = run_sample(worst.index, self.rigs[worst.index], controller, self.scenarios,
                             d.noise_seed, keep_results=True)  # fmt: skip
            out[mc.controller] = (d.describe(u.parameters), run.results)
        return out


@dataclass(frozen=True)
class RobustnessPlan:
    """The drawn plants and what to run on them."""

    rig: Rig
    controllers: tuple[Controller, ...]
    uncertainty: Uncertainty
    scenarios: tuple[str, ...]
    rigs: tuple[Rig, ...] = field(repr=False)

    @property
    def steps(self) -> int:
        """Simulated samples in all (what a progress bar counts)."""
        return len(self.rigs) * len(self.controllers)

    def describe(self) -> str:
        return (
            f"rig {self.rig.name}: {self.uncertainty.describe()}\n"
            f"scenarios {', '.join(self.scenarios)}; metrics: worst scenario of each sample"
        )

    def run(
        self,
        gain_margin: float | None = 2.0,
        progress: Callable[[int], object] | None = None,
        *,
        workers: int = 1,
        cluster: str | None = None,
    ) -> RobustnessResult:
        """Every controller on every plant, with the gain check ``gain_margin`` (None:
        none); ``progress(k)`` as ``k`` samples finish. ``workers`` local processes or the
        Dask ``cluster`` (``tcp://HOST:PORT``) share the samples, :data:`CHUNK` at a time:
        the same numbers as in this process (each sample's runs are its own)."""
        seeds = [d.noise_seed for d in self.uncertainty.draws]
        if workers <= 1 and not cluster:
            runs = monte_carlo(self.rig, self.controllers, self.rigs, seeds, self.scenarios,
                               gain=gain_margin, progress=progress)  # fmt: skip
        else:
            from fuzzyservo.executor import make_executor

            executor = make_executor(workers, cluster)
            try:
                task = _Chunk(self.rig, self.controllers, self.rigs, tuple(seeds),
                              self.scenarios, gain_margin)  # fmt: skip
                parts = executor.map(task, range(0, len(self.rigs), CHUNK))
            finally:
                executor.close()
            runs = [MonteCarlo(c.name, [r for part in parts for r in part[k].runs])
                    for k, c in enumerate(self.controllers)]  # fmt: skip
            if progress is not None:
                progress(self.steps)
        return RobustnessResult(self.rig.name, self.uncertainty, self.scenarios, gain_margin,
                                tuple(runs), self.controllers, self.rigs,
                                metric_units(self.rig))  # fmt: skip


#: samples per task when the Monte Carlo is shared out (monte_carlo's own chunk)
CHUNK = 16


@dataclass(frozen=True)
class _Chunk:
    """The Monte Carlo of samples ``start`` to ``start + CHUNK`` (an executor's task),
    numbered as in the whole."""

    rig: Rig
    controllers: tuple[Controller, ...]
    rigs: tuple[Rig, ...]
    seeds: tuple[int, ...]
    scenarios: tuple[str, ...]
    gain: float | None

    def __call__(self, start: int) -> list[MonteCarlo]:
        stop = min(start + CHUNK, len(self.rigs))
        runs = monte_carlo(self.rig, self.controllers, self.rigs[start:stop],
                           self.seeds[start:stop], self.scenarios, gain=self.gain,
                           chunk=CHUNK)  # fmt: skip
        return [MonteCarlo(mc.controller, [dataclasses.replace(r, index=r.index + start)
                                           for r in mc.runs]) for mc in runs]  # fmt: skip


def _where(rig: Rig) -> str:
    """A rig's identity for "is this study about this rig": its file, else its name."""
    return str(Path(rig.path).resolve()) if rig.path else rig.name


def plan(
    rig: Rig,
    controllers: Sequence[Controller],
    study: Study,
    *,
    samples: int = 200,
    seed: int | None = None,
    scenarios: Sequence[str] | None = None,
) -> RobustnessPlan:
    """Draw ``samples`` plants of ``rig`` from the ``uncertainty:`` of ``study`` (a robust
    study of this rig), seeded ``seed`` (default: the seed a study report's check uses,
    so both draw the same plants); ``scenarios`` default: the study's."""
    from fuzzyservo.tuning.uncertainty.robust import CHECK_SEED, sample_rigs

    if study.uncertainty is None:
        raise ConfigError("has no 'uncertainty:' section; name a robust study", file=study.path)
    if _where(study.rig) != _where(rig):
        raise ConfigError(
            f"samples {study.rig.name}, not {rig.name}; name a study of this rig",
            file=study.path,
        )
    seed = CHECK_SEED if seed is None else seed
    u = dataclasses.replace(study.uncertainty, samples=samples, seed=seed, draws=())
    study = dataclasses.replace(study, uncertainty=u)
    names = tuple(scenarios or study.scenarios)
    for s in names:
        rig.scenario(s)
    rigs = tuple(sample_rigs(rig, study))
    return RobustnessPlan(rig, tuple(controllers), u, names, rigs)


def robustness(
    rig: Rig,
    controllers: Sequence[Controller],
    study: Study,
    *,
    gain_margin: float | None = 2.0,
    progress: Callable[[int], object] | None = None,
    **draw: Any,
) -> RobustnessResult:
    """Monte Carlo of ``controllers`` on plants drawn from ``study``'s uncertainty
    (:func:`plan`, with its ``samples``, ``seed`` and ``scenarios`` from ``draw``), each
    checked for ``gain_margin``."""
    return plan(rig, controllers, study, **draw).run(gain_margin, progress)
