"""The ``matlab`` semantics: what the Fuzzy Logic Toolbox's ``evalfis`` computes, compiled.

For inputs x (each clipped to its range, as the controller saturates its error):

1. membership of each input in each term, exact (:func:`.shapes.mf_value`);
2. rule firing w_r = weight_r · (AND: min or product / OR: max or probabilistic OR of
   the antecedent memberships, 1 − μ for NOT);
3. Mamdani: each output sampled at ``sample_points`` evenly spaced points x_k of its
   range (MATLAB's ``linspace``); implication per rule (min(w_r, μ_c(x_k)) or
   w_r·μ_c(x_k), μ_c replaced by 1 − μ_c for a negated consequent), aggregation over
   the rules (max, sum, probor), then MATLAB's ``defuzz`` on the samples: centroid
   Σx·μ/Σμ; bisector the first sample where the running sum of μ reaches half its
   total; mom the mean, som/lom the smallest/largest in magnitude of the samples where
   μ is largest;
4. Sugeno: z_r = c (constant) or c_1·x_1 + … + c_n·x_n + c_0 (linear), output
   Σw_r·z_r/Σw_r (wtaver) or Σw_r·z_r (wtsum).

When no rule fires for an output (Σw_r = 0 or the aggregate is zero everywhere) that
output is the middle of its range, as in MATLAB, and the call reports it so the caller
can warn.
"""

from __future__ import annotations

import numpy as np

from fuzzyservo._jit import njit
from fuzzyservo.controllers.fuzzy.shapes import SHAPE_CODES, mf_value
from fuzzyservo.controllers.fuzzy.system import (
    AGGREGATIONS,
    AND_METHODS,
    DEFUZZIFICATIONS,
    IMPLICATIONS,
    NO_TERM,
    OR_METHODS,
    FuzzySystem,
    Variable,
    term_index,
)
from fuzzyservo.controllers.layout import Slot, layout, pack

# header
#: the exact block's header (offsets from the block start)
EXACT_HEAD = layout(
    "ExactHead",
    Slot("n_inputs"),
    Slot("n_outputs"),
    Slot("n_rules"),
    Slot("sugeno", "1 for a Sugeno system, 0 for Mamdani", flag=True),
    Slot("and_method", "index in AND_METHODS"),
    Slot("or_method", "index in OR_METHODS"),
    Slot("implication", "index in IMPLICATIONS"),
    Slot("aggregation", "index in AGGREGATIONS"),
    Slot("defuzzification", "index in DEFUZZIFICATIONS"),
    Slot("samples", "points of the output universe (MATLAB's NumSamples)"),
    Slot("variables", "offset of the table of variable offsets"),
    Slot("rules", "offset of the rules"),
)
#: a variable's record: these slots, then the offset of each of its terms
EXACT_VARIABLE = layout("ExactVariable", Slot("low"), Slot("high"), Slot("n_terms"))
#: a term's record: these slots, then its parameters
EXACT_TERM = layout("ExactTerm", Slot("shape", "the shape's code in SHAPE_CODES"), Slot("n_params"))
#: a rule's record: one term code per input and per output, then these slots
EXACT_RULE = layout("ExactRule", Slot("weight"), Slot("connective", "0 AND, 1 OR"))
_X, _XV, _XT, _XR = EXACT_HEAD, EXACT_VARIABLE, EXACT_TERM, EXACT_RULE
_LINEAR = SHAPE_CODES["linear"]
_CONSTANT = SHAPE_CODES["constant"]


def pack_exact(system: FuzzySystem) -> tuple[np.ndarray, int]:
    """Flatten ``system`` for :func:`evaluate_exact`; also the scratch size it needs.

    Layout: :data:`EXACT_HEAD`; a table of variable offsets (inputs, then outputs); each
    variable :data:`EXACT_VARIABLE` and its term offsets, each term :data:`EXACT_TERM` and
    its parameters; the rules, the term codes of :class:`.Rule` and :data:`EXACT_RULE`.
    """
    block: list[float] = [0.0] * len(_X)
    variables: list[Variable] = [*system.inputs, *system.outputs]
    table_at = len(block)
    block += [0.0] * len(variables)
    for v, var in enumerate(variables):
        block[table_at + v] = len(block)
        terms_at = len(block) + len(_XV)
        block += [*pack(_XV, low=var.low, high=var.high, n_terms=len(var.terms))]
        block += [0.0] * len(var.terms)
        for k, term in enumerate(var.terms):
            block[terms_at + k] = len(block)
            block += [*pack(_XT, shape=SHAPE_CODES[term.shape], n_params=len(term.params))]
            block += term.params
    rules_at = len(block)
    for rule in system.rules:
        connective = 0.0 if rule.connective == "and" else 1.0
        block += [*rule.antecedent, *rule.consequents]
        block += [*pack(_XR, weight=rule.weight, connective=connective)]
    n_in, n_out = len(system.inputs), len(system.outputs)
    block[_X.n_inputs], block[_X.n_outputs], block[_X.n_rules] = n_in, n_out, len(system.rules)
    block[_X.sugeno] = 1.0 if system.type == "sugeno" else 0.0
    block[_X.and_method] = AND_METHODS.index(system.and_method)
    block[_X.or_method] = OR_METHODS.index(system.or_method)
    block[_X.implication] = IMPLICATIONS.index(system.implication)
    block[_X.aggregation] = AGGREGATIONS.index(system.aggregation)
    block[_X.defuzzification] = DEFUZZIFICATIONS.index(system.defuzzification)
    block[_X.samples] = system.sample_points
    block[_X.variables], block[_X.rules] = table_at, rules_at
    t_max = max(len(v.terms) for v in system.inputs)
    scratch = n_in * t_max + len(system.rules) + n_in + system.sample_points
    return np.asarray(block, dtype=np.float64), scratch


@njit(cache=True, inline="always")
def antecedent(
    cp: np.ndarray,
    q: int,
    n_in: int,
    conn: float,
    mu: np.ndarray,
    t_stride: int,
    and_m: int,
    or_m: int,
) -> float:
    """A rule's antecedent: its term codes at ``cp[q:q + n_in]`` (:func:`.term_index`)
    combined by AND (``conn`` 0: min or product) or OR (1: max or probabilistic OR) over the
    memberships ``mu[i*t_stride + k]``. Shared by both semantics."""
    acc = -1.0
    for i in range(n_in):
        a = int(cp[q + i])
        if a == NO_TERM:
            continue
        k, negated = term_index(a)
        m = 1.0 - mu[i * t_stride + k] if negated else mu[i * t_stride + k]
        if acc < 0.0:
            acc = m
        elif conn == 0.0:
            acc = min(acc, m) if and_m == 0 else acc * m
        else:
            acc = max(acc, m) if or_m == 0 else acc + m - acc * m
    return acc


@njit(cache=True, inline="always")
def _term_mu(cp: np.ndarray, t: int, x: float) -> float:
    return mf_value(int(cp[t + _XT.shape]), cp, t + len(_XT), x)


@njit(cache=True)
def evaluate_exact(
    cp: np.ndarray, b: int, scratch: np.ndarray, xs: np.ndarray, out: np.ndarray
) -> int:
    """All outputs of the system packed at ``cp[b:]`` for inputs ``xs`` into ``out``.

    Returns the number of outputs for which no rule fired (set to mid-range).
    """
    n_in = int(cp[b + _X.n_inputs])
    n_out = int(cp[b + _X.n_outputs])
    n_rules = int(cp[b + _X.n_rules])
    and_m = int(cp[b + _X.and_method])
    or_m = int(cp[b + _X.or_method])
    imp_m = int(cp[b + _X.implication])
    agg_m = int(cp[b + _X.aggregation])
    defuzz_m = int(cp[b + _X.defuzzification])
    n_s = int(cp[b + _X.samples])
    vt = b + int(cp[b + _X.variables])
    ro = b + int(cp[b + _X.rules])
    width = n_in + n_out + len(_XR)

    # 1. inputs clipped, membership in every term
    t_max = 0
    for i in range(n_in):
        t_max = max(t_max, int(cp[b + int(cp[vt + i]) + _XV.n_terms]))
    mu = scratch[: n_in * t_max]
    x = scratch[n_in * t_max : n_in * t_max + n_in]
    for i in range(n_in):
        v = b + int(cp[vt + i])
        x[i] = min(max(xs[i], cp[v + _XV.low]), cp[v + _XV.high])
        for k in range(int(cp[v + _XV.n_terms])):
            mu[i * t_max + k] = _term_mu(cp, b + int(cp[v + len(_XV) + k]), x[i])

    # 2. firing strengths
    w = scratch[n_in * t_max + n_in : n_in * t_max + n_in + n_rules]
    for r in range(n_rules):
        q = ro + r * width
        tail = q + n_in + n_out
        w[r] = antecedent(cp, q, n_in, cp[tail + _XR.connective], mu, t_max, and_m, or_m)
        w[r] *= cp[tail + _XR.weight]

    # 3./4. each output
    ys = scratch[n_in * t_max + n_in + n_rules : n_in * t_max + n_in + n_rules + n_s]
    silent = 0
    for o in range(n_out):
        v = b + int(cp[vt + n_in + o])
        lo = cp[v + _XV.low]
        hi = cp[v + _XV.high]
        if cp[b + _X.sugeno] == 1.0:
            num = 0.0
            den = 0.0
            for r in range(n_rules):
                c = int(cp[ro + r * width + n_in + o])
                k, negated = term_index(c)
                if c == NO_TERM or negated or w[r] == 0.0:
                    continue
                t = b + int(cp[v + len(_XV) + k])
                coeffs = t + len(_XT)
                if int(cp[t + _XT.shape]) == _CONSTANT:
                    z = cp[coeffs]
                else:
                    z = cp[coeffs + n_in]
                    for i in range(n_in):
                        z += cp[coeffs + i] * x[i]
                num += w[r] * z
                den += w[r]
            if den == 0.0:
                out[o] = 0.5 * (lo + hi)
                silent += 1
            elif defuzz_m == 6:  # wtsum
                out[o] = num
            else:
                out[o] = num / den
            continue
        step = (hi - lo) / (n_s - 1)
        for k in range(n_s):
            ys[k] = 0.0
        for r in range(n_rules):
            c = int(cp[ro + r * width + n_in + o])
            if c == NO_TERM or w[r] == 0.0:
                continue
            k, neg = term_index(c)
            t = b + int(cp[v + len(_XV) + k])
            for k in range(n_s):
                xk = hi if k == n_s - 1 else lo + k * step
                m = _term_mu(cp, t, xk)
                if neg:
                    m = 1.0 - m
                m = min(w[r], m) if imp_m == 0 else w[r] * m
                if agg_m == 0:
                    ys[k] = max(ys[k], m)
                elif agg_m == 1:
                    ys[k] = ys[k] + m
                else:
                    ys[k] = ys[k] + m - ys[k] * m
        value = _defuzz(ys, lo, hi, step, n_s, defuzz_m)
        if np.isnan(value):
            out[o] = 0.5 * (lo + hi)
            silent += 1
        else:
            out[o] = value
    return silent


@njit(cache=True)
def _defuzz(ys: np.ndarray, lo: float, hi: float, step: float, n: int, method: int) -> float:
    """MATLAB's ``defuzz`` on the samples ``ys`` at ``linspace(lo, hi, n)``; NaN if all zero."""
    total = 0.0
    top = 0.0
    for k in range(n):
        total += ys[k]
        top = max(top, ys[k])
    if total <= 0.0:
        return np.nan
    if method == 0:
        moment = 0.0
        for k in range(n):
            xk = hi if k == n - 1 else lo + k * step
            moment += xk * ys[k]
        return moment / total
    if method == 1:
        acc = 0.0
        for k in range(n):
            acc += ys[k]
            if acc >= 0.5 * total:
                return hi if k == n - 1 else lo + k * step
        return hi
    s = 0.0
    cnt = 0
    best = np.nan
    for k in range(n):
        if ys[k] == top:
            xk = hi if k == n - 1 else lo + k * step
            s += xk
            cnt += 1
            if np.isnan(best) or (abs(xk) < abs(best) if method == 3 else abs(xk) > abs(best)):
                best = xk
    if method == 2:
        return s / cnt
    return best
