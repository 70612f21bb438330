"""A calibration from start to end: the data replayed on the rig (one record or several
together), the candidate effects, the search, and what it concluded as a result object.

:func:`prepare` assembles it (the one place that does), :meth:`Calibration.run` fits;
:func:`fuzzyservo.calibration.calibrate` does both.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from fuzzyservo.calibration.candidates import candidate_effects
from fuzzyservo.calibration.null import DRAWS
from fuzzyservo.calibration.replay import Replay
from fuzzyservo.calibration.search import SearchOutcome
from fuzzyservo.components.effects import LIBRARY
from fuzzyservo.display import quantity_text
from fuzzyservo.errors import ConfigError, DataError, did_you_mean
from fuzzyservo.results import Result, json_ready

if TYPE_CHECKING:
    from fuzzyservo.controllers.base import Controller
    from fuzzyservo.measured import Measured
    from fuzzyservo.rig import Rig


@dataclass(frozen=True)
class CalibrationResult(Result):
    """What a calibration concluded (:class:`~fuzzyservo.calibration.search.SearchOutcome`,
    whose attributes read through: ``result.added``, ``result.calibrated`` ...), the
    replay it is shown on (the whole record's) and everything computed from them, once,
    by :func:`conclude`: ``summary`` is ``summary.json`` (without the written rig's path)
    and what ``--json`` writes, ``correlations`` the residual figures' numbers. Nothing
    reading it simulates: :func:`fuzzyservo.io.calibration_report.write_calibration`
    only draws and writes."""

    outcome: SearchOutcome
    replay: Replay = field(repr=False)
    # effects asked for that were not tried, with why (:func:`skipped_effects`)
    skipped: dict[str, str] = field(default_factory=dict)
    summary: Mapping[str, Any] = field(default_factory=dict, repr=False)
    # the held-out residual's correlations before and after (``before``/``after``: the
    # input name, the white band, each channel's Correlations; summary.residual_correlations)
    correlations: Mapping[str, tuple[str, float, dict[str, Any]]] = field(
        default_factory=dict, repr=False
    )

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__") or name in (
            "outcome",
            "replay",
            "skipped",
            "summary",
            "correlations",
        ):
            raise AttributeError(name)
        return getattr(self.outcome, name)

    def to_dict(self) -> dict[str, Any]:
        return dict(self.summary)

    def text(self) -> str:
        """Warnings, the first round's ranking, then the verdict (report.verdict_lines):
        what an engineer reads first is last on the console."""
        from fuzzyservo.calibration.verdict import ranking_line

        summary = json_ready(self.to_dict())  # as in summary.json: non-finite numbers are null
        lines = [f"warning: {w}" for w in summary["warnings"]]
        ranking = ranking_line(summary)
        if ranking:
            lines.append(ranking)
        lines.append("verdict:")
        lines += [f"  {line}" for line in summary["verdict"]]
        return "\n".join(lines)


def conclude(
    outcome: SearchOutcome, replay: Replay, skipped: Mapping[str, str] | None = None
) -> CalibrationResult:
    """The :class:`CalibrationResult` of ``outcome`` shown on ``replay`` (the whole
    record's), its summary, residual analysis and correlations computed here: the
    residual analysis and the signatures' R² simulate."""
    from fuzzyservo.calibration.summary import (
        RESIDUAL_MODELS,
        calibration_summary,
        diagnostics,
        residual_correlations,
    )

    skipped = dict(skipped or {})
    summary = {**calibration_summary(outcome, replay, skipped), **diagnostics(outcome, replay)}
    correlations = {label: residual_correlations(replay, outcome.models[key])
                    for label, key in RESIDUAL_MODELS}  # fmt: skip
    return CalibrationResult(outcome, replay, skipped, summary, correlations)


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

    @property
    def skipped(self) -> dict[str, str]:
        """The effects asked for that are not tried, with why (:func:`skipped_effects`)."""
        return skipped_effects(self.rig, self.effects or ())

    def steps(self, max_effects: int) -> int:
        """Candidate fits at most: what a progress bar counts."""
        return len(self.candidates) * max(max_effects, 1)

    def describe(self) -> str:
        n = len(self.candidates)
        named = f" ({', '.join(self.candidates)})" if self.effects is not None and n else ""
        return (
            f"calibrate {self.rig.name} on {', '.join(d.source for d in self.records)}: "
            f"{self.replay.mode}; {sum(len(d) for d in self.records)} samples, "
            f"channels {', '.join(self.replay.channels)}; {n} candidate "
            f"effect{'' if n == 1 else 's'}{named}"
            + (f"\nfitted on {self.replay.segment_words}" if self.replay.segment_words else "")
            + "".join(f"\nskipped: {name}: {why}" for name, why in self.skipped.items())
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
        from fuzzyservo.calibration.search import search_effects

        effects = None if self.effects is None else list(self.effects)
        outcome = search_effects(self.replay, self.rig, effects=effects, max_effects=max_effects,
                         progress=progress, workers=workers, cluster=cluster,
                         bootstrap_draws=DRAWS if bootstrap_draws is None else bootstrap_draws)  # fmt: skip
        return conclude(outcome, self.replay.whole(), self.skipped)


def skipped_effects(rig: Rig, effects: Sequence[str]) -> dict[str, str]:
    """Of the ``effects`` asked for, those a calibration of ``rig`` does not try (the
    complement of search.candidate_effects), with why: the rig declares it already
    (a calibration adds only what the rig lacks), or its plant cannot take it."""
    out = {}
    for name in effects:
        if name in rig.effects:
            out[name] = _declared_words(rig, name)
        elif why := rig.plant.refusal(name):
            out[name] = why
    return out


def _declared_words(rig: Rig, name: str) -> str:
    """Why a declared effect is not a candidate, and how to have it fitted."""
    params = LIBRARY[name].params
    fitted = [p.key for p in params if p.field in rig.unknowns]
    if fitted:
        return (
            f"the rig declares it already, with {', '.join(fitted)} marked fit: and fitted "
            "with the rig's other unknowns"
        )
    values = []
    for p in params:
        if p.optional and not getattr(rig.params, p.field):
            continue  # an optional part left off (a first-order spool's second time constant)
        (text,), unit = quantity_text(
            [float(getattr(rig.params, p.field))], rig.plant.effect_unit(p.unit)
        )
        values.append(f"{p.key} {text} {unit}".rstrip())
    return (
        f"the rig declares it already ({', '.join(values)}); a calibration adds only "
        "effects the rig lacks: to refit it, mark its value fit: [lower, upper] in the rig file"
    )


def prepare(
    rig: Rig,
    data: Measured | Sequence[Measured],
    controller: Controller | None = None,
    *,
    effects: Sequence[str] | None = None,
    per_record: Sequence[str] = (),
    segments: bool = False,
) -> Calibration:
    """Replay the measured ``data`` (a :class:`Measured`, or a list of them to calibrate
    together; :func:`fuzzyservo.io.measured.read_rig_data` reads a data file as the rig
    file's ``measured:`` says) on ``rig`` (closed loop through ``controller`` when given)
    and check the effect names. ``per_record``: rig-file keys of unknowns fitted per record.
    ``segments``: fit and test on segments restarted from the recorded state
    (calibration/segments.py); the overlays and fit % still replay the whole record."""
    from fuzzyservo.calibration.joint import joint_replay, per_record_fields
    from fuzzyservo.calibration.replay import make_replay
    from fuzzyservo.calibration.segments import probe_rigs, segmented

    several = isinstance(data, Sequence)
    records = tuple(data) if several else (data,)
    fields = per_record_fields(rig, per_record)
    for e in effects or ():
        if e not in LIBRARY:
            raise ConfigError(
                f"unknown effect {e!r}; {did_you_mean(e, LIBRARY)}choose from {', '.join(LIBRARY)}",
                argument="effects",
            )
    effects = None if effects is None else tuple(dict.fromkeys(effects))  # each once
    replays = [make_replay(rig, d, controller) for d in records]
    if segments:
        probes = probe_rigs(rig, candidate_effects(rig, effects))
        replays = [segmented(r, rig, probes) for r in replays]
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
