"""The lookup-table variant of a generated controller: the static map F sampled on an n
(× n) grid over the input universes and interpolated (bi)linearly, and how far the table
is from F."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fuzzyservo.controllers.fuzzy.controller import FuzzyController
from fuzzyservo.controllers.fuzzy.evaluate import evaluate_inputs


@dataclass(frozen=True)
class LutError:
    """How far the table is from the map: the largest error found on a grid ``refine``
    times finer, and a bound that adds the Lipschitz estimate of the error over half a
    fine-grid step (in output units, before the output gain)."""

    found: float
    bound: float
    span: float
    refine: int


def lut_table(controller: FuzzyController, n: int) -> tuple[list[np.ndarray], np.ndarray]:
    """Grids over the input universes and the static map F on them, shape (n,) or (n, n)."""
    if n < 2:
        raise ValueError(f"a lookup table needs n >= 2 points per input, got {n}")
    grids = [np.linspace(v.low, v.high, n) for v in controller.system.inputs]
    return grids, _map(controller, np.meshgrid(*grids, indexing="ij"))


def _map(controller: FuzzyController, mesh: list[np.ndarray]) -> np.ndarray:
    """F on raw universe inputs (the evaluator behind ``curve``, gains taken out)."""
    xs = np.column_stack([m.ravel() for m in mesh])
    out, _ = evaluate_inputs(controller.system, xs)
    return out[:, 0].reshape(mesh[0].shape)


def lut_interp(grids: list[np.ndarray], table: np.ndarray, points: list[np.ndarray]) -> np.ndarray:
    """The table read as the generated code reads it (uniform grid, clipped, (bi)linear)."""
    idx, frac = [], []
    for g, x in zip(grids, points, strict=True):
        n = g.size
        h = (g[-1] - g[0]) / (n - 1)
        t = (np.clip(x, g[0], g[-1]) - g[0]) / h
        k = np.minimum(np.floor(t).astype(int), n - 2)
        idx.append(k)
        frac.append(t - k)
    if len(grids) == 1:
        (k,), (f,) = idx, frac
        return table[k] + f * (table[k + 1] - table[k])
    (k, l), (f, g) = idx, frac
    a = table[k, l] + g * (table[k, l + 1] - table[k, l])
    b = table[k + 1, l] + g * (table[k + 1, l + 1] - table[k + 1, l])
    return a + f * (b - a)


def lut_error(controller: FuzzyController, n: int, refine: int | None = None) -> LutError:
    """Largest |table − F| over the input range, on a grid ``refine`` times finer than the
    table (16 for one input, 6 for two), and a bound from the error's slope there."""
    grids, table = lut_table(controller, n)
    refine = refine or (16 if len(grids) == 1 else 6)
    fine = [np.linspace(g[0], g[-1], (g.size - 1) * refine + 1) for g in grids]
    mesh = np.meshgrid(*fine, indexing="ij")
    err = lut_interp(grids, table, mesh) - _map(controller, mesh)
    slope = max(
        float(np.max(np.abs(np.diff(err, axis=a)))) / (f[1] - f[0]) for a, f in enumerate(fine)
    )
    steps = [f[1] - f[0] for f in fine]
    found = float(np.max(np.abs(err)))
    out = controller.system.output
    return LutError(found, found + slope * 0.5 * math.hypot(*steps), out.high - out.low, refine)
