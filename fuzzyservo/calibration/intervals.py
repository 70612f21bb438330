"""The intervals a calibration reports: every fitted value's 95 % interval at the final
model (:func:`fitted_intervals`, the sandwich widened by each value's profile,
:mod:`~fuzzyservo.calibration.uncertainty`), and the held ends of each added effect's
parameters that a round's prediction band takes (:func:`frozen_ends`)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from fuzzyservo.calibration.candidates import (
    JACOBIAN_STEP,
    Candidate,
    Objective,
    fit_space,
    jacobian,
    start_value,
)
from fuzzyservo.calibration.joint import record_field
from fuzzyservo.calibration.replay import Replay
from fuzzyservo.calibration.uncertainty import (
    Estimate,
    effective_samples,
    estimates,
    gauss_newton_step,
    held_interval,
)
from fuzzyservo.components.effects import LIBRARY
from fuzzyservo.rig import Rig


def fitted_intervals(
    replay: Replay, rig: Rig, added: Sequence[Candidate], model: dict[str, np.ndarray]
) -> dict[str, Estimate]:
    """95 % intervals and at-bound flags of every fitted value: the rig's unknowns and the
    added effects' parameters (uncertainty.py): the sandwich of one Jacobian at the final
    model, widened by each parameter's profile on the training part (the parameters it
    is correlated with following it, uncertainty.correlated)."""
    unknowns = dict(rig.unknowns)
    for candidate in added:  # each in the box its fit had (the value's bounds as reported)
        for param in LIBRARY[candidate.name].fitted:
            unknowns.setdefault(param.field, candidate.bounds[param.field])
    if not unknowns:
        return {}
    joint = dataclasses.replace(rig, unknowns=unknowns)
    space = fit_space(joint, None)
    for name in replay.per_record:  # a per-record value (joint.py) in each record
        j = next(j for j, (_, f) in enumerate(space.names) if f == name)
        lo_hi, is_log = space.bounds.pop(j), space.log.pop(j)
        space.names.pop(j)
        for k in range(len(replay.values[name])):
            space.names.append(("", record_field(name, k)))
            space.bounds.append(lo_hi)
            space.log.append(is_log)
    objective = Objective(replay, joint, None, space)
    values = [start_value(replay, rig, f) for _, f in space.names]
    z = np.array([space.unit(j, v) for j, v in enumerate(values)])
    jac = jacobian(objective.residuals, z)
    channels = len(replay.channels)
    informed = np.flatnonzero(np.all(np.isfinite(jac), axis=0))

    def cost(j: int, v: float) -> np.ndarray:  # each training sample's, parameter j at v
        trial = z.copy()
        trial[j] = v
        r = objective.residuals(trial)
        # every other value follows it down the valley, as a profile likelihood's do
        others = informed[informed != j]
        if others.size:
            moved = trial.copy()
            moved[others] = gauss_newton_step(jac[:, others], r, z[others])
            r_moved = objective.residuals(moved)
            if np.sum(r_moved**2) < np.sum(r**2):
                r = r_moved
        return np.sum(r.reshape(channels, -1) ** 2, axis=0)

    residuals = objective.residuals(z).reshape(channels, -1)
    found = estimates(jac, residuals, z, values, space.value, space.bounds, cost, JACOBIAN_STEP,
                      replay.noise_cost(), names=[f for _, f in space.names])  # fmt: skip
    return {f: e for (_, f), e in zip(space.names, found, strict=True)}


def frozen_ends(
    replay: Replay, rig: Rig, added: Sequence[Candidate], model: dict[str, np.ndarray]
) -> list[list[dict[str, np.ndarray]]]:
    """For each fitted parameter of the effects ``added`` so far (a round's candidates
    leave them as they are): ``rig``'s channels at the ends of its 95 % interval with
    the others held (uncertainty.held_interval on its own Jacobian column), for the
    round's prediction band (null.prediction_band). Held, not marginal: the marginal
    interval of correlated parameters is reached only with the others moved along
    (Stribeck's levels on the Festo record span their whole bounds), and one parameter
    at its marginal end with the others held is a model the data reject. The band keeps
    this linearised interval, not the reported one (:func:`fitted_intervals`'s profile,
    several times wider where the cost is rough): the decision's error rate and power
    were measured with it."""
    if not added:
        return []
    unknowns = {}
    for candidate in added:
        # the box its fit had: one fitted in an earlier round's box (the rig's scales
        # move with its fitted unknowns) may lie outside today's, and an end clipped
        # onto the box would move it for no uncertainty of its own
        unknowns.update(candidate.boxes())
    space = fit_space(dataclasses.replace(rig, unknowns=unknowns), None)
    objective = Objective(replay, rig, None, space)
    values = [start_value(replay, rig, f) for _, f in space.names]
    z = np.array([space.unit(j, v) for j, v in enumerate(values)])
    jac = jacobian(objective.residuals, z)
    samples, effective = effective_samples(replay, model)
    cost_train = replay.cost(model, slice(0, replay.split))
    out = []
    for j, (_, name) in enumerate(space.names):
        held = held_interval(jac[:, j], z[j], values[j], lambda u, j=j: space.value(j, u),
                             space.bounds[j], cost_train, samples, effective)  # fmt: skip
        ends = [v for v in held.interval if math.isfinite(v) and v != held.value]
        out.append([replay.run(rig.with_params(**{name: v}))[0] for v in ends])
    return out
