"""Several records of one rig calibrated together (issue 12, item 6).

Records taken at other positions, under other loads or with other currents see the
same rig from other sides: an effect one record cannot pin (or cannot tell from
another) the next may. :class:`JointReplay` replays every record on one rig and puts
their channels end to end, training parts first, held-out parts after::

    [train 1 | train 2 | … | train K | held-out 1 | held-out 2 | … | held-out K]

so the search, the held-out test and the intervals (candidates.py, decision.py,
uncertainty.py) see one training part and one held-out part, as for a single record.
The rig's parameters, its declared unknowns and every effect are shared by all
records; a declared unknown named in ``per_record`` (e.g. a valve null that drifts
between sessions, a payload that differs) is fitted once per record, within its
declared bounds, as ``<field>@<k>`` (k from 0).

A channel's noise level is the root mean square of the records' estimates: the
records come from one rig and its sensors.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from fuzzyservo.calibration.replay import Replay, Scored
from fuzzyservo.controllers.base import Controller
from fuzzyservo.errors import ConfigError, DataError
from fuzzyservo.rig import Rig

SEP = "@"  # "<field>@<record index>": a parameter fitted once per record


def record_field(name: str, k: int) -> str:
    """The name under which record ``k``'s value of ``name`` is fitted."""
    return f"{name}{SEP}{k}"


def split_field(name: str) -> tuple[str, int] | None:
    """``(field, k)`` of a per-record name, None for a shared one."""
    base, sep, k = name.rpartition(SEP)
    return (base, int(k)) if sep and k.isdigit() else None


@dataclass(frozen=True, eq=False)
class JointReplay(Scored):
    """Records of one rig replayed together; see the module docstring.

    ``per_record``: field -> bounds of the unknowns fitted once per record;
    ``values``: field -> current value in each record (the declared value until fitted).
    """

    records: tuple[Replay, ...]
    per_record: dict[str, tuple[float, float]] = field(default_factory=dict)
    values: dict[str, tuple[float, ...]] = field(default_factory=dict)

    @property
    def channels(self) -> dict[str, str]:
        return self.records[0].channels

    @property
    def controller(self) -> Controller:
        return self.records[0].controller

    @property
    def drive(self) -> str:
        return self.records[0].drive

    @property
    def data(self):
        """The first record's data (units and sample period are checked to agree)."""
        return self.records[0].data

    @property
    def mode(self) -> str:
        return f"{len(self.records)} records, {self.records[0].mode}"

    @cached_property
    def split(self) -> int:
        return sum(r.split for r in self.records)

    @cached_property
    def t(self) -> np.ndarray:
        """Sample index times of the joined channels (for sizes, not for plotting)."""
        return np.arange(sum(r.t.size for r in self.records)) * self.data.sample_period_s

    def join(self, parts: Sequence[np.ndarray]) -> np.ndarray:
        """Per-record arrays (one per record, on each record's grid) in the joined order."""
        train = [p[: r.split] for p, r in zip(parts, self.records, strict=True)]
        held = [p[r.split :] for p, r in zip(parts, self.records, strict=True)]
        return np.concatenate(train + held)

    def unjoin(self, joined: np.ndarray) -> list[np.ndarray]:
        """The inverse of :meth:`join`: each record's array on its own grid."""
        out, a, b = [], 0, self.split
        for r in self.records:
            n_train, n_held = r.split, r.t.size - r.split
            out.append(np.concatenate([joined[a : a + n_train], joined[b : b + n_held]]))
            a, b = a + n_train, b + n_held
        return out

    @property
    def split_s(self) -> float:
        return float(self.t[self.split])

    @property
    def logged_gains(self) -> dict[str, tuple[float, float, float]]:
        """Gains fitted on a logged command are a single record's (replay.py)."""
        return {}

    logged_fit = float("nan")

    def recorded(self, name: str) -> np.ndarray:
        """A recorded signal of every record (zeros where a record lacks it), joined."""
        return self.join(
            [
                r.recorded(name) if name in r.data.signals else np.zeros(r.t.size)
                for r in self.records
            ]
        )

    @cached_property
    def _measured(self) -> dict[str, np.ndarray]:
        return {c: self.join([r.measured(c) for r in self.records]) for c in self.channels}

    def measured(self, channel: str) -> np.ndarray:
        return self._measured[channel]

    @cached_property
    def sigma(self) -> dict[str, float]:
        return {
            c: float(np.sqrt(np.mean([r.sigma[c] ** 2 for r in self.records])))
            for c in self.channels
        }

    def record_rigs(self, rig: Rig, values: Mapping[str, Sequence[float]] | None = None):
        """``rig`` as each record sees it: its per-record values applied."""
        values = self.values if values is None else values
        return [
            rig.with_params(**{f: v[k] for f, v in values.items()}) if values else rig
            for k in range(len(self.records))
        ]

    def run(
        self,
        rig: Rig,
        controller: Controller | None = None,
        values: Mapping[str, Sequence[float]] | None = None,
        *,
        training: bool = False,
    ) -> tuple[dict[str, np.ndarray], str]:
        """Every record replayed on ``rig`` (with each record's ``values``), joined;
        ``training``: as far as each record's training part (replay.py)."""
        runs = [
            r.run(rig_k, controller, training=training)
            for r, rig_k in zip(self.records, self.record_rigs(rig, values), strict=True)
        ]
        status = next((s for _, s in runs if s != "ok"), runs[0][1])
        return {c: self.join([m[c] for m, _ in runs]) for c in self.channels}, status

    def with_controller(self, controller: Controller) -> JointReplay:
        records = tuple(r.with_controller(controller) for r in self.records)
        return dataclasses.replace(self, records=records)

    def whole(self) -> JointReplay:
        """Every record run through, never restarted (replay.py)."""
        records = tuple(r.whole() for r in self.records)
        if all(a is b for a, b in zip(records, self.records, strict=True)):
            return self
        return dataclasses.replace(self, records=records)

    @property
    def segment_words(self) -> str:
        """The first record's segments in words (segments.py; "" when not segmented)."""
        return self.records[0].segment_words

    def with_values(self, fitted: Mapping[str, float]) -> JointReplay:
        """The per-record values among ``fitted`` (``<field>@<k>`` -> value) taken on."""
        values = {f: list(v) for f, v in self.values.items()}
        for name, value in fitted.items():
            parsed = split_field(name)
            if parsed and parsed[0] in values:
                values[parsed[0]][parsed[1]] = float(value)
        return dataclasses.replace(self, values={f: tuple(v) for f, v in values.items()})


def per_record_fields(rig: Rig, keys: Sequence[str]) -> list[str]:
    """The fields of the rig-file ``keys`` (e.g. ``bias_current``) that the rig declares
    unknown (``fit: [lower, upper]``), to be fitted per record."""
    fields = type(rig.params).__dataclass_fields__
    by_key = {f.metadata.get("key"): name for name, f in fields.items()}
    out = []
    for key in (k.strip() for k in keys):
        if not key:
            continue
        name = by_key.get(key)
        if name is None or name not in rig.unknowns:
            declared = ", ".join(fields[f].metadata["key"] for f in rig.unknowns) or "none"
            raise ConfigError(
                f"{key!r} is not an unknown of rig {rig.name} (declared "
                f"unknowns: {declared}); give it fit: [lower, upper] in the rig file",
                argument="per_record",
            )
        out.append(name)
    return out


def joint_replay(
    records: Sequence[Replay], rig: Rig, per_record: Sequence[str] = ()
) -> JointReplay:
    """Records of ``rig`` (replays made by ``make_replay``) to calibrate together;
    ``per_record``: declared unknowns (fields of ``rig.unknowns``) fitted per record."""
    if not records:
        raise ValueError("joint_replay needs at least one record")
    first = records[0]
    for r in records[1:]:
        if r.channels != first.channels or r.drive != first.drive:
            raise DataError(
                f"{r.data.source}: records calibrated together need the same channels and "
                f"input ({first.data.source} has {', '.join(first.channels)} driven by "
                f"{first.drive}; this one {', '.join(r.channels)} driven by {r.drive}); "
                "give every file the same columns"
            )
        if any(r.data.units[c] != first.data.units[c] for c in r.channels):
            raise DataError(
                f"{r.data.source}: a channel's unit differs from {first.data.source}'s; "
                "give every file the same column units"
            )
    bounds = {}
    for name in per_record:
        if name not in rig.unknowns:
            raise ValueError(f"{name} is fitted per record but is not an unknown of the rig")
        bounds[name] = rig.unknowns[name]
    values = {f: (float(getattr(rig.params, f)),) * len(records) for f in bounds}
    return JointReplay(records=tuple(records), per_record=bounds, values=values)
