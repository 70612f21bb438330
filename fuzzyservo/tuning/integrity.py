"""A study stays one study: its definition's fingerprint, unique proposals, workers that die with their parent.

* **Fingerprint**: what decides a trial's value (the rig, the scenarios, the controller
  template, the search space, the objective with its constraints and aggregation, the
  uncertainty; rig and controllers by the numbers their typed objects hold) is stored in the Optuna study's user attributes when it is created. Opening
  the study with an edited definition stops with one line naming what changed, instead of
  mixing old and new trials (a reported best outside the new search range).
* **Unique proposals**: each trial's sampler is seeded from the study seed and the
  trial's number, which the storage hands out once. Processes sharing a storage (the
  default SQLite file too) never replay the same random stream, and a fresh single-process
  run is reproducible.
* **Workers die with their parent**: :func:`fuzzyservo.executor.die_with_parent` (a
  worker process asks the kernel for SIGTERM when its parent dies and also watches its
  parent's pid).

Stdlib only at import; optuna is imported inside the functions that need it.
"""

from __future__ import annotations

import hashlib
import json
from typing import TYPE_CHECKING, Any

from fuzzyservo.errors import ConfigError
from fuzzyservo.executor import die_with_parent

if TYPE_CHECKING:
    from fuzzyservo.controllers.base import Controller
    from fuzzyservo.rig import Rig
    from fuzzyservo.tuning.spec import Study

FINGERPRINT_ATTR = "fingerprint"
DEFINITION_ATTR = "definition"
PARTS = ("rig", "scenarios", "template", "search space", "objective", "uncertainty", "sampler")


# --------------------------------------------------------------------------- fingerprint
#: how the definition's parts are written: 2 from the study's typed objects (rig,
#: template and baseline by their numbers); studies stored before carry no scheme and
#: had the rig, template and baseline hashed from their files' content
SCHEME = 2
SCHEME_ATTR = "fingerprint_scheme"
#: the parts whose writing scheme 2 kept: what an older study is still checked on
_KEPT = ("scenarios", "search space", "uncertainty")


def _rig_data(rig: Rig) -> str:
    """The numbers that make a rig: parameters, sensor, actuator, timing, scenarios."""
    scenarios = [repr(rig.scenarios[name]) for name in sorted(rig.scenarios)]
    return repr((rig.params, rig.feedback, rig.actuator, rig.sample_time_s, rig.io_delay_s,
                 rig.output, sorted(rig.initial.items()), rig.effects, scenarios))  # fmt: skip


def _controller_data(controller: Controller) -> str:
    """The numbers that make a controller (a fuzzy one's design when it has one)."""
    design = getattr(controller, "design", None)
    return repr(design if design is not None else controller)


def definition(spec: Study) -> dict[str, Any]:
    """The study's definition, part by part, as plain JSON-able data."""
    objective = {
        "weights": dict(spec.objective.weights),
        "pareto": list(spec.objective.pareto),
        "normalize": spec.objective.normalize,
        "aggregate": spec.aggregate,
        "constraints": [str(c) for c in spec.constraints],
        "penalty": spec.penalty,
    }
    if spec.objective.normalize == "baseline":
        objective["baseline"] = _digest(_controller_data(spec.baseline))
    uncertainty = spec.uncertainty
    return {
        "rig": _digest(_rig_data(spec.rig)),
        "scenarios": list(spec.scenarios),
        "template": _digest(_controller_data(spec.template)),
        "search space": {
            p.path: [p.low, p.high, "log" if p.log else "linear", "int" if p.integer else "float"]
            for p in spec.parameters
        },
        "objective": objective,
        "uncertainty": uncertainty.describe_data() if uncertainty is not None else None,
        # what proposes the trials: a study resumed under another sampler or seed is not
        # the study its first trials belong to (and no longer reproducible)
        "sampler": {"name": spec.sampler, "seed": spec.seed},
    }


def _digest(data: Any) -> str:
    text = json.dumps(data, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def fingerprint(spec: Study) -> dict[str, str]:
    """A short hash per part of the definition (:data:`PARTS`)."""
    return {part: _digest(value) for part, value in definition(spec).items()}


def _changes(old: dict[str, Any], new: dict[str, Any], stored: dict[str, str]) -> list[str]:
    """What differs, part by part, with the changed keys of the search space and objective."""
    out = []
    current = {part: _digest(value) for part, value in new.items()}
    for part in PARTS:
        if stored.get(part) == current.get(part):
            continue
        before, after = old.get(part), new.get(part)
        if isinstance(before, dict) and isinstance(after, dict):
            keys = sorted(set(before) | set(after))
            diffs = []
            for k in keys:
                if before.get(k) == after.get(k):
                    continue
                if k not in before:
                    diffs.append(f"{k} added")
                elif k not in after:
                    diffs.append(f"{k} removed")
                else:
                    diffs.append(f"{k} {_short(before[k])} -> {_short(after[k])}")
            out.append(f"{part} ({'; '.join(diffs)})" if diffs else part)
        elif part == "scenarios" and before is not None:
            out.append(f"scenarios ({_short(before)} -> {_short(after)})")
        else:
            out.append(part)
    return out


def _short(value: Any) -> str:
    if isinstance(value, list) and len(value) == 4 and value[2] in ("log", "linear"):
        return f"[{value[0]:g}, {value[1]:g}]" + (" log" if value[2] == "log" else "")
    text = json.dumps(value, default=str)
    return text if len(text) <= 40 else text[:37] + "..."


def check_definition(study: Any, spec: Study, url: str) -> None:
    """Store the definition's fingerprint in a study that has none; raise :class:`ConfigError`
    (one line: what changed, how to start anew) when the stored one differs. A study
    stored before :data:`SCHEME` is checked on the parts written alike (:data:`_KEPT`)
    and then carries the new fingerprint."""
    current = fingerprint(spec)
    stored = study.user_attrs.get(FINGERPRINT_ATTR)
    if stored is not None and study.user_attrs.get(SCHEME_ATTR) != SCHEME:
        if all(stored.get(part) == current[part] for part in _KEPT):
            stored = None  # nothing comparable changed: adopt the new fingerprint
        else:
            stored = {**current, **{part: stored.get(part) for part in _KEPT}}
    missing = [part for part in PARTS if stored is not None and part not in stored]
    if missing:  # stored before the part was fingerprinted: it takes the definition's
        stored = {**stored, **{part: current[part] for part in missing}}
        new = definition(spec)
        old = dict(study.user_attrs.get(DEFINITION_ATTR, {}))
        study.set_user_attr(FINGERPRINT_ATTR, stored)
        study.set_user_attr(DEFINITION_ATTR, {**old, **{part: new[part] for part in missing}})
    if stored is None:
        study.set_user_attr(FINGERPRINT_ATTR, current)
        study.set_user_attr(DEFINITION_ATTR, definition(spec))
        study.set_user_attr(SCHEME_ATTR, SCHEME)
        return
    if stored == current:
        return
    changed = _changes(study.user_attrs.get(DEFINITION_ATTR, {}), definition(spec), stored)
    where = url
    fix = "give another --out folder (a new study), or delete the old study's folder"
    if url.startswith("sqlite:///"):
        where = url[len("sqlite:///") :]
        fix = f"give another --out folder (a new study), or delete {where}"
    elif spec.storage or not url.startswith("sqlite"):
        fix = "give the study another `name:` (a new study in the same storage)"
    raise ConfigError(
        f"study {spec.name!r} in {where} holds trials of another definition: changed "
        f"{', '.join(changed) or 'definition'}; {fix}",
        file=spec.path or None,
    )


# --------------------------------------------------------------------------- unique proposals
def trial_seed(seed: int, number: int) -> int:
    """The sampler seed of trial ``number`` in a study seeded ``seed``."""
    return (seed + 7919 * number) % (2**32)


def reseed(sampler: Any, seed: int, _depth: int = 0) -> None:
    """Seed every random state of an Optuna sampler (and of the samplers it holds)."""
    from optuna.samplers import BaseSampler
    from optuna.samplers._lazy_random_state import LazyRandomState

    for value in vars(sampler).values():
        if isinstance(value, LazyRandomState):
            value.rng.seed(seed)
        elif isinstance(value, BaseSampler) and _depth < 3:
            reseed(value, (seed + 1) % (2**32), _depth + 1)


def per_trial_seeded(sampler: Any, seed: int | None) -> Any:
    """``sampler`` reseeded before every trial from ``seed`` and the trial's number (no
    reseeding when ``seed`` is None: then each process draws its own entropy)."""
    if seed is None:
        return sampler
    from optuna.samplers import BaseSampler

    class TrialSeeded(BaseSampler):
        """Delegates to the wrapped sampler; seeds it per trial (see the module docstring)."""

        def __init__(self) -> None:
            self.inner = sampler

        def infer_relative_search_space(self, study, trial):
            return self.inner.infer_relative_search_space(study, trial)

        def sample_relative(self, study, trial, search_space):
            return self.inner.sample_relative(study, trial, search_space)

        def sample_independent(self, study, trial, param_name, param_distribution):
            return self.inner.sample_independent(study, trial, param_name, param_distribution)

        def before_trial(self, study, trial) -> None:
            reseed(self.inner, trial_seed(seed, trial.number))
            self.inner.before_trial(study, trial)

        def after_trial(self, study, trial, state, values) -> None:
            self.inner.after_trial(study, trial, state, values)

        def reseed_rng(self) -> None:
            self.inner.reseed_rng()

    return TrialSeeded()


__all__ = ["check_definition", "die_with_parent", "fingerprint", "per_trial_seeded", "trial_seed"]
