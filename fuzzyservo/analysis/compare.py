"""Several controllers on one rig and scenario: the runs side by side, their metrics, a table."""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Any

from fuzzyservo.controllers.base import Controller
from fuzzyservo.display import metric_units, metrics_table, not_moved_note, undefined_note
from fuzzyservo.errors import ConfigError
from fuzzyservo.metrics import (
    METRIC_NAMES,
    Metrics,
    applicable_metrics,
    heave_metrics,
    result_metrics,
)
from fuzzyservo.results import Result
from fuzzyservo.rig import Rig, Scenario
from fuzzyservo.simulation import SimResult, simulate


@dataclass(frozen=True, eq=False)
class ComparisonResult(Result, Mapping[str, SimResult]):
    """The runs by controller name, in the given order (a read-only mapping), with
    their metrics; ``text()`` is the table ``fuzzyservo compare`` prints."""

    rig: str
    scenario: str
    description: str
    results: dict[str, SimResult]

    def __getitem__(self, name: str) -> SimResult:
        return self.results[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self.results)

    def __len__(self) -> int:
        return len(self.results)

    @cached_property
    def metrics(self) -> dict[str, Metrics]:
        return {name: result_metrics(r) for name, r in self.results.items()}

    @cached_property
    def heave(self) -> dict[str, dict[str, float]]:
        """Heave-compensation metrics of each run (empty for a run that does not compensate)."""
        return {name: heave_metrics(r) for name, r in self.results.items()}

    @property
    def problems(self) -> list[str]:
        """One line for each run that did not end ``ok`` (an end stop says when the
        piston hit it: ``hit the end stop at t = ... s``)."""
        return [f"{n}: status {r.status}: {r.message}" for n, r in self.items() if r.status != "ok"]

    @cached_property
    def not_moved(self) -> dict[str, str]:
        """Why each run that did not move has no rise, settling or overshoot (runs that
        moved are left out): ``did not move (4.2 fm peak to peak, below the 15.8 µm
        resolution: ...)``."""
        units = metric_units(next(iter(self.values())))
        notes = {n: not_moved_note(self.metrics[n], units) for n in self}
        return {n: note for n, note in notes.items() if note}

    @property
    def failed(self) -> bool:
        """Did any run fail (diverge, or break a physical limit)?"""
        return any(not r.ok for r in self.values())

    def text(self) -> str:
        runs = list(self.values())
        units = metric_units(runs[0])
        lines = [f"rig {self.rig} · scenario {self.scenario} · {self.description}".rstrip(" ·")]
        shown = applicable_metrics(runs[0])
        rows = [self.metrics[n].aggregate for n in self]
        lines.append(metrics_table(list(self), rows, units, shown))
        if len(shown) < len(METRIC_NAMES):
            left_out = ", ".join(m for m in METRIC_NAMES if m not in shown)
            lines.append(f"not shown: {left_out} (step metrics; this scenario's reference is "
                         "tracked, not stepped)")  # fmt: skip
        lines += [f"{n}: {note}" for n, note in self.not_moved.items()]
        if note := undefined_note(shown, rows):
            lines.append(note)
        if any(self.heave.values()):
            pct = (f"{n}: {units.text('compensation_pct', h.get('compensation_pct'))}"
                   for n, h in self.heave.items())  # fmt: skip
            lines.append("compensation_pct  " + "  ".join(pct))
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        runs = [
            {"controller": n, "status": r.status, "message": r.message,
             "end_stop_s": r.end_stop_s, "not_moved": self.not_moved.get(n),
             **self.metrics[n].to_dict(), **self.heave[n]}
            for n, r in self.items()
        ]  # fmt: skip
        units = metric_units(next(iter(self.values()))).si_units()
        return {"rig": self.rig, "scenario": self.scenario, "units": units, "runs": runs}


def compare(
    rig: Rig,
    controllers: Sequence[Controller],
    scenario: str | Scenario | None = None,
    *,
    duration_s: float | None = None,
) -> ComparisonResult:
    """Simulate each controller on ``rig`` (``scenario`` default: the rig's first).

    Raises :class:`~fuzzyservo.errors.ConfigError` when two controllers share a name
    (their results would collide) or the rig has no such scenario.
    """
    names = [c.name for c in controllers]
    if len(set(names)) != len(names):
        raise ConfigError(
            f"two controllers share a name ({names}); give each file a distinct 'name'"
        )
    sc = scenario if isinstance(scenario, Scenario) else rig.scenario(scenario)
    results = {c.name: simulate(rig, c, sc, duration_s=duration_s) for c in controllers}
    return ComparisonResult(rig.name, sc.name, sc.description, results)
