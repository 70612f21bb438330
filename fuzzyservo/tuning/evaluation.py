"""A controller scored on a study's scenarios: the value a trial records and the report shows."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol

from fuzzyservo.simulation import SimResult

if TYPE_CHECKING:
    from fuzzyservo.rig import Rig
    from fuzzyservo.tuning.spec import Study


@dataclass(frozen=True)
class Evaluation:
    """A controller scored on the study's scenarios."""

    values: tuple[float, ...]
    metrics: dict[str, float]
    scenario_metrics: dict[str, dict[str, float]]
    violations: tuple[float, ...]
    status: str
    message: str = ""
    sim_time_s: float = 0.0
    results: dict[str, SimResult] = field(default_factory=dict, repr=False)
    simulations: int = 0  # runs it took (robust studies count them; 0: not counted)
    #: a robust study's objective on each sample (the value is their aggregate); () otherwise
    sample_values: tuple[float, ...] = ()
    #: sampled plants a robust trial never ran: decided (pruned, failed) before them
    samples_skipped: int = 0

    @property
    def feasible(self) -> bool:
        return self.status == "ok" and all(v <= 0 for v in self.violations)


class Scorer(Protocol):
    """What scores a study's controllers (:class:`~fuzzyservo.tuning.objective.Evaluator`):
    the study, its nominal rig and sampled rigs, and its objective of a set of metrics."""

    spec: Study
    rig: Rig
    sample_rigs: list[Rig]

    def objective_values(self, metrics: dict[str, float]) -> tuple[float, ...]: ...
