"""MATLAB's type-1 membership functions, exactly as the Fuzzy Logic Toolbox defines them.

One compiled scalar function, :func:`mf_value`, reads a shape code and its parameters
from a float64 vector; :func:`mf_array` applies it to an array. Definitions (Fuzzy
Logic Toolbox reference pages of the functions of the same name; extra parameters
beyond the ones listed are ignored, as MATLAB does):

* ``trimf [a b c]``, ``trapmf [a b c d]``: piecewise linear; ``x == b`` gives 1 even
  when ``a == b`` (a vertical side);
* ``gaussmf [σ c]``: exp(−(x − c)²/(2σ²)); ``gauss2mf [σ1 c1 σ2 c2]``: left Gaussian
  below c1, right Gaussian above c2, 1 between (their product when c1 > c2);
* ``gbellmf [a b c]``: 1/(1 + |(x − c)/a|^(2b));
* ``sigmf [a c]``: 1/(1 + exp(−a(x − c))); ``dsigmf``: |sig1 − sig2|;
  ``psigmf``: sig1·sig2 (parameters ``[a1 c1 a2 c2]``);
* ``smf [a b]``, ``zmf [a b]``: quadratic splines from 0 to 1 (1 to 0) between a and b;
  a step at (a + b)/2 when a >= b; ``pimf [a b c d]``: smf(a, b)·zmf(c, d);
* ``linsmf [a b]``, ``linzmf [a b]``: linear ramps up (down) between a and b.
"""

from __future__ import annotations

import math

import numpy as np

from fuzzyservo._jit import njit

#: parameters each input/Mamdani-output shape reads (more are kept but ignored)
MF_SHAPES = {
    "trimf": 3,
    "trapmf": 4,
    "gaussmf": 2,
    "gbellmf": 3,
    "sigmf": 2,
    "smf": 2,
    "zmf": 2,
    "pimf": 4,
    "gauss2mf": 4,
    "dsigmf": 4,
    "psigmf": 4,
    "linsmf": 2,
    "linzmf": 2,
}
#: Sugeno output terms: a constant, or coefficients of the inputs and a constant
SUGENO_SHAPES = ("constant", "linear")
SHAPE_CODES = {name: k for k, name in enumerate((*MF_SHAPES, *SUGENO_SHAPES))}
#: shapes whose corners are their only non-smooth points (sampled universes keep them)
PIECEWISE_LINEAR = ("trimf", "trapmf", "linsmf", "linzmf")


@njit(cache=True, inline="always")
def _sig(a: float, c: float, x: float) -> float:
    return 1.0 / (1.0 + math.exp(-a * (x - c)))


@njit(cache=True, inline="always")
def _smf(a: float, b: float, x: float) -> float:
    if a >= b:
        return 1.0 if x >= 0.5 * (a + b) else 0.0
    if x <= a:
        return 0.0
    if x >= b:
        return 1.0
    t = (x - a) / (b - a)
    if x <= 0.5 * (a + b):
        return 2.0 * t * t
    t = (x - b) / (b - a)
    return 1.0 - 2.0 * t * t


@njit(cache=True, inline="always")
def _zmf(a: float, b: float, x: float) -> float:
    if a >= b:
        return 1.0 if x <= 0.5 * (a + b) else 0.0
    if x <= a:
        return 1.0
    if x >= b:
        return 0.0
    t = (x - a) / (b - a)
    if x <= 0.5 * (a + b):
        return 1.0 - 2.0 * t * t
    t = (x - b) / (b - a)
    return 2.0 * t * t


@njit(cache=True)
def mf_value(code: int, p: np.ndarray, o: int, x: float) -> float:
    """Membership of ``x`` in the shape ``code`` whose parameters start at ``p[o]``."""
    if code == 0:  # trimf
        a, b, c = p[o], p[o + 1], p[o + 2]
        if x == b:
            return 1.0
        if x <= a or x >= c:
            return 0.0
        if x < b:
            return (x - a) / (b - a)
        return (c - x) / (c - b)
    if code == 1:  # trapmf
        a, b, c, d = p[o], p[o + 1], p[o + 2], p[o + 3]
        y1 = 1.0
        if x < a:
            y1 = 0.0
        elif x < b:
            y1 = (x - a) / (b - a)
        y2 = 1.0
        if x > d:
            y2 = 0.0
        elif x > c:
            y2 = (d - x) / (d - c)
        return min(y1, y2)
    if code == 2:  # gaussmf [sigma c]
        s, c = p[o], p[o + 1]
        return math.exp(-((x - c) ** 2) / (2.0 * s * s))
    if code == 3:  # gbellmf
        a, b, c = p[o], p[o + 1], p[o + 2]
        return 1.0 / (1.0 + abs((x - c) / a) ** (2.0 * b))
    if code == 4:  # sigmf [a c]
        return _sig(p[o], p[o + 1], x)
    if code == 5:
        return _smf(p[o], p[o + 1], x)
    if code == 6:
        return _zmf(p[o], p[o + 1], x)
    if code == 7:  # pimf
        return _smf(p[o], p[o + 1], x) * _zmf(p[o + 2], p[o + 3], x)
    if code == 8:  # gauss2mf [s1 c1 s2 c2]
        s1, c1, s2, c2 = p[o], p[o + 1], p[o + 2], p[o + 3]
        y1 = math.exp(-((x - c1) ** 2) / (2.0 * s1 * s1)) if x <= c1 else 1.0
        y2 = math.exp(-((x - c2) ** 2) / (2.0 * s2 * s2)) if x >= c2 else 1.0
        return y1 * y2
    if code == 9:  # dsigmf
        return abs(_sig(p[o], p[o + 1], x) - _sig(p[o + 2], p[o + 3], x))
    if code == 10:  # psigmf
        return _sig(p[o], p[o + 1], x) * _sig(p[o + 2], p[o + 3], x)
    if code == 11:  # linsmf
        a, b = p[o], p[o + 1]
        if x < a:
            return 0.0
        if x >= b:
            return 1.0
        return (x - a) / (b - a)
    if code == 12:  # linzmf
        a, b = p[o], p[o + 1]
        if x <= a:
            return 1.0
        if x > b:
            return 0.0
        return (b - x) / (b - a)
    return np.nan


@njit(cache=True)
def _mf_array(code: int, p: np.ndarray, x: np.ndarray, out: np.ndarray) -> None:
    for k in range(x.size):
        out[k] = mf_value(code, p, 0, x[k])


def mf_array(shape: str, params: tuple[float, ...], x: np.ndarray) -> np.ndarray:
    """:func:`mf_value` of a named shape on an array."""
    x = np.ascontiguousarray(x, dtype=float)
    out = np.empty(x.shape)
    _mf_array(SHAPE_CODES[shape], np.asarray(params, dtype=float), x.ravel(), out.reshape(-1))
    return out
