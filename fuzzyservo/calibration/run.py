"""A calibration from start to end: the data replayed on the rig (one record or several
together), the candidate effects, the search, and what it concluded as a result object.

:func:`prepare` assembles it (the one place that does), :meth:`Calibration.run` fits;
:func:`fuzzyservo.calibration.calibrate` does both.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from fuzzyservo.calibration.null import DRAWS
from fuzzyservo.calibration.replay import Replay
from fuzzyservo.calibration.search import Outcome, candidate_effects
from fuzzyservo.components.effects import LIBRARY
from fuzzyservo.errors import ConfigError, DataError, did_you_mean
from fuzzyservo.metrics import format_value
from fuzzyservo.results import Result, json_ready

if TYPE_CHECKING:
    from fuzzyservo.controllers.base import Controller
    from fuzzyservo.io.measured import Measured
    from fuzzyservo.rig import Rig


@dataclass(frozen=True)
class CalibrationResult(Result):
    """What a calibration concluded (:class:`~fuzzyservo.calibration.search.Outcome`,
    whose attributes read through: ``result.added``, ``result.calibrated`` ...) and the
    replay it was fitted on. ``to_dict()`` is ``summary.json`` (without the written
    rig's path); :func:`fuzzyservo.io.calibration_report.write_calibration` writes the report."""

    outcome: Outcome
    replay: Replay = field(repr=False)

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__") or name in ("outcome", "replay"):
            raise AttributeError(name)
        return getattr(self.outcome, name)

    def to_dict(self) -> dict[str, Any]:
        from fuzzyservo.calibration.report import summary_data

        return summary_data(self.outcome, self.replay)

    def text(self) -> str:
        summary = json_ready(self.to_dict())  # as in summary.json: non-finite numbers are null
        lines = [f"warning: {w}" for w in summary["warnings"]]
        lines.append(f"effects added: {summary['decision']}")
        for c in self.outcome.added:
            lines.append(f"  {c.name}: " + ", ".join(f"{k} = {v:.4g}" for k, v in c.params.items()))
        lines.append("held-out fit %  (channel: before -> after)")
        for channel in self.replay.channels:
            b, a = summary["fit_before_pct"][channel], summary["fit_after_pct"][channel]
            lines.append(f"  {channel:6s} {format_value(b):>8s} -> {format_value(a):>8s}")
        if self.outcome.rounds:
            best = summary["candidates"][:5]
            ranking = ", ".join(f"{c['name']} {format_value(c['score'])}" for c in best)
            lines.append(f"ranking (score, lower is better): {ranking}")
        lines += [f"verdict: {line}" for line in summary["verdict"]]
        return "\n".join(lines)


@dataclass(frozen=True)
class Calibration:
    """A calibration ready to run: ``rig``, the ``replay`` of its data and the candidate
    effects (``effects`` as asked for, None: the whole library)."""

    rig: Rig
    replay: Replay
    records: tuple[Measured, ...]
    effects: tuple[str, ...] | None

    @property
    def candidates(self) -> list[str]:
        """The effects the rig's plant can take and does not declare yet."""
        return candidate_effects(self.rig, self.effects)

    def steps(self, max_effects: int) -> int:
        """Candidate fits at most: what a progress bar counts."""
        return len(self.candidates) * max(max_effects, 1)

    def describe(self) -> str:
        return (
            f"calibrate {self.rig.name} on {', '.join(d.source for d in self.records)}: "
            f"{self.replay.mode}; {sum(len(d) for d in self.records)} samples, "
            f"channels {', '.join(self.replay.channels)}; {len(self.candidates)} candidate effects"
        )

    def run(
        self,
        *,
        max_effects: int = 2,
        workers: int = 1,
        cluster: str | None = None,
        progress: Callable[[str], object] | None = None,
        bootstrap_draws: int | None = None,
    ) -> CalibrationResult:
        """Fit the unknowns, then add up to ``max_effects`` effects; ``progress(name)``
        as each candidate ends; ``workers`` local processes or the Dask ``cluster``
        (``tcp://HOST:PORT``) fit a round's candidates (the same result).
        ``bootstrap_draws``: surrogate records of each round's null (null.py; no
        simulation; None: DRAWS; 0: decision.py's Bonferroni threshold alone)."""
        from fuzzyservo.calibration.search import calibrate as search

        effects = None if self.effects is None else list(self.effects)
        outcome = search(self.replay, self.rig, effects=effects, max_effects=max_effects,
                         progress=progress, workers=workers, cluster=cluster,
                         bootstrap_draws=DRAWS if bootstrap_draws is None else bootstrap_draws)  # fmt: skip
        return CalibrationResult(outcome, self.replay)


def prepare(
    rig: Rig,
    data: Measured | Sequence[Measured],
    controller: Controller | None = None,
    *,
    effects: Sequence[str] | None = None,
    per_record: Sequence[str] = (),
) -> Calibration:
    """Replay the measured ``data`` (a :class:`Measured`, or a list of them to calibrate
    together; :func:`fuzzyservo.io.measured.read_rig_data` reads a data file as the rig
    file's ``measured:`` says) on ``rig`` (closed loop through ``controller`` when given)
    and check the effect names. ``per_record``: rig-file keys of unknowns fitted per record."""
    from fuzzyservo.calibration.joint import joint_replay, per_record_fields
    from fuzzyservo.calibration.replay import make_replay

    several = isinstance(data, Sequence)
    records = tuple(data) if several else (data,)
    fields = per_record_fields(rig, per_record)
    for e in effects or ():
        if e not in LIBRARY:
            raise ConfigError(
                f"--effects: unknown effect {e!r}; {did_you_mean(e, LIBRARY)}"
                f"choose from {', '.join(LIBRARY)}"
            )
    replays = [make_replay(rig, d, controller) for d in records]
    replay = joint_replay(replays, rig, fields) if several or fields else replays[0]
    still = replay.still_channels()
    if len(still) == len(replay.channels):
        raise DataError(
            f"{replay.sources()}: the held-out part ({replay.held_out_words()}) does not move "
            f"in any channel: {replay.still_words(still)}; a fit % there is undefined and the "
            "held-out test has nothing to judge; give a record whose held-out part moves (a "
            "step or pulse there), or cut the record so that it ends after one"
        )
    return Calibration(rig, replay, records, None if effects is None else tuple(effects))
