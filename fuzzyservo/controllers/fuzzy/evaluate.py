"""The compiled evaluator of a :class:`FuzzySystem`, and the tables it runs on.

:func:`pack_system` turns a system into one float64 vector (sampled universes and
membership tables, rules, methods); :func:`evaluate` computes the crisp output for one
or two inputs inside compiled code, allocating nothing (scratch space is passed in);
:func:`evaluate_point` / :func:`evaluate_inputs` every output for any number of inputs.
The ``matlab`` semantics and Sugeno systems are evaluated by :mod:`.exact`, dispatched
from the same packed vector.

It reproduces ``skfuzzy.control.ControlSystemSimulation.compute`` step by step:
memberships by linear interpolation on the sampled universes (``np.interp``), rule
firing with AND/OR and the rule weight, accumulation per output term with max, the
output universe upsampled at every term's cut level (``_interp_universe_fast`` and
``np.union1d``), min implication, max aggregation, and the defuzzification formulas
of ``skfuzzy.defuzzify.defuzz``. Only the part of the universe where the aggregated
set can be non-zero is visited, which is what makes it fast.

Inputs outside a universe are clipped to it (scikit-fuzzy would give them zero
membership everywhere and fail): a controller saturates its error, as an analog one
would. Implication is per rule, then aggregation: with max aggregation the rules sharing
a consequent term are merged first (max commutes with min and product implication);
with sum or probor each rule keeps its own implied set (:func:`_pack_output`). A
negated consequent implies the complement of its term; multi-output systems get one
block per output.
"""

from __future__ import annotations

import math

import numpy as np

from fuzzyservo._jit import njit
from fuzzyservo.controllers.fuzzy.exact import antecedent, evaluate_exact
from fuzzyservo.controllers.fuzzy.system import (
    AGGREGATIONS,
    AND_METHODS,
    DEFUZZIFICATIONS,
    IMPLICATIONS,
    NO_TERM,
    OR_METHODS,
    FuzzySystem,
    term_index,
)
from fuzzyservo.controllers.layout import Slot, layout, pack

#: the top of a packed system: these slots, then from ``blocks`` on the offset of each
#: output's block (``SAMPLED``) or of the exact block (``EXACT``)
SYSTEM_HEAD = layout(
    "SystemHead",
    Slot("semantics", "SAMPLED or EXACT"),
    Slot("n_inputs"),
    Slot("n_outputs"),
    Slot("blocks", "offset of the first block, from the top"),
)
#: one output's block header in the ``skfuzzy`` semantics (offsets from the block start)
OUTPUT_HEAD = layout(
    "OutputHead",
    Slot("n_inputs"),
    Slot("n_rules"),
    Slot("and_method", "index in AND_METHODS"),
    Slot("or_method", "index in OR_METHODS"),
    Slot("implication", "index in IMPLICATIONS"),
    Slot("aggregation", "index in AGGREGATIONS"),
    Slot("defuzzification", "index in DEFUZZIFICATIONS"),
    Slot("inputs", "offset of the table of input offsets"),
    Slot("term_stride", "the most terms of an input"),
    Slot("output", "offset of the output variable"),
    Slot("rules", "offset of the rules"),
    Slot("n_terms", "the output's (virtual) terms"),
)
#: a sampled variable's record: these slots, then its universe (``n_points``) and its
#: membership table (``n_terms`` rows); an output's then the supports and zero crossings
SAMPLED_VARIABLE = layout(
    "SampledVariable", Slot("low"), Slot("high"), Slot("n_points"), Slot("n_terms")
)
#: a rule's record: one term code per input, then these slots
SAMPLED_RULE = layout(
    "SampledRule",
    Slot("term", "the output's (virtual) term"),
    Slot("weight"),
    Slot("connective", "0 AND, 1 OR"),
)
_T, _H, _SV, _SR = SYSTEM_HEAD, OUTPUT_HEAD, SAMPLED_VARIABLE, SAMPLED_RULE
SAMPLED, EXACT = 0, 1


def pack_system(system: FuzzySystem) -> tuple[np.ndarray, int]:
    """Flatten a system into a float64 vector for :func:`evaluate`; also the scratch size needed.

    Mamdani systems in the ``skfuzzy`` semantics get one block per output
    (:func:`_pack_output`); the ``matlab`` semantics, and Sugeno systems in both (scikit-fuzzy
    has none, so there is nothing to sample after), the exact block of :mod:`.exact`.
    """
    from fuzzyservo.controllers.fuzzy.exact import pack_exact

    n_in, n_out = len(system.inputs), len(system.outputs)
    head = np.zeros(_T.blocks + n_out)
    head[_T.n_inputs] = n_in
    head[_T.n_outputs] = n_out
    if system.semantics == "matlab" or system.type == "sugeno":
        head[_T.semantics] = EXACT
        block, scratch = pack_exact(system)
        head[_T.blocks] = head.size
        return np.concatenate([head, block]), scratch + n_in + n_out
    head[_T.semantics] = SAMPLED
    blocks = []
    scratch = 0
    for o in range(n_out):
        block, need = _pack_output(system, o)
        head[_T.blocks + o] = head.size + sum(b.size for b in blocks)
        blocks.append(block)
        scratch = max(scratch, need)
    return np.concatenate([head, *blocks]), scratch + n_in + n_out


def _pack_output(system: FuzzySystem, output: int) -> tuple[np.ndarray, int]:
    """One output's block. Its terms are virtual: each consequent the rules name (NOT k:
    the complement of term k); with sum or probor aggregation one per rule, so that the
    evaluator's per-term accumulation is an implication per rule followed by the
    aggregation (max aggregation commutes with min and product implication)."""
    parts: list[np.ndarray] = []
    size = len(_H)

    def add(arr) -> int:
        nonlocal size
        a = np.asarray(arr, dtype=np.float64).ravel()
        parts.append(a)
        start = size
        size += a.size
        return start

    n_in = len(system.inputs)
    ins_at = add(np.zeros(n_in))
    offsets = []
    t_max = 0
    for var in system.inputs:
        u, table = var.table()
        t_max = max(t_max, len(var.terms))
        offsets.append(
            add(pack(_SV, low=var.low, high=var.high, n_points=u.size, n_terms=len(var.terms)))
        )
        add(u)
        add(table)
    out = system.outputs[output]
    u, term_table = out.table()
    rules = [r for r in system.rules if r.consequents[output] != NO_TERM]
    per_rule = system.aggregation != "max"
    virtual: dict[object, int] = {}  # (term, negated) or rule number -> virtual term
    rows = []
    rule_terms = []
    for n, rule in enumerate(rules):
        k, negated = term_index(rule.consequents[output])
        key = n if per_rule else (k, negated)
        if key not in virtual:
            virtual[key] = len(rows)
            rows.append(1.0 - term_table[k] if negated else term_table[k])
        rule_terms.append(virtual[key])
    table = np.array(rows).reshape(len(rows), u.size)
    n_t = len(rows)
    referenced = np.ones(n_t)
    support_lo = np.empty(n_t)
    support_hi = np.empty(n_t)
    zero_crossings: list[np.ndarray] = []
    for t in range(n_t):
        nz = np.nonzero(table[t] > 0)[0]
        support_lo[t] = max(nz[0] - 1, 0) if nz.size else 0
        support_hi[t] = min(nz[-1] + 1, u.size - 1) if nz.size else 0
        # the points scikit-fuzzy adds for a term cut at level 0
        idx = np.nonzero(np.diff(table[t] > 0))[0]
        zero_crossings.append(
            u[idx]
            + (0.0 - table[t][idx]) * (u[idx + 1] - u[idx]) / (table[t][idx + 1] - table[t][idx])
        )
    off_out = add(pack(_SV, low=out.low, high=out.high, n_points=u.size, n_terms=n_t))
    add(u)
    add(table)
    add(support_lo)
    add(support_hi)
    add(referenced)
    add([z.size for z in zero_crossings])
    zc_offsets_at = add(np.zeros(n_t))
    zc_starts = []
    for z in zero_crossings:
        zc_starts.append(add(z) if z.size else size)
    off_rules = add(
        [
            v
            for rule, t in zip(rules, rule_terms, strict=True)
            for v in (
                *rule.antecedent,
                *pack(
                    _SR,
                    term=t,
                    weight=rule.weight,
                    connective=0.0 if rule.connective == "and" else 1.0,
                ),
            )
        ]
    )
    block = np.concatenate([np.zeros(len(_H)), *parts])
    block[zc_offsets_at : zc_offsets_at + n_t] = zc_starts
    block[ins_at : ins_at + n_in] = offsets
    block[_H.n_inputs] = n_in
    block[_H.n_rules] = len(rules)
    block[_H.and_method] = AND_METHODS.index(system.and_method)
    block[_H.or_method] = OR_METHODS.index(system.or_method)
    block[_H.implication] = IMPLICATIONS.index(system.implication)
    block[_H.aggregation] = AGGREGATIONS.index(system.aggregation)
    block[_H.defuzzification] = DEFUZZIFICATIONS.index(system.defuzzification)
    block[_H.inputs] = ins_at
    block[_H.term_stride] = t_max
    block[_H.output] = off_out
    block[_H.rules] = off_rules
    block[_H.n_terms] = n_t
    extra = 4 * n_t + 2 * u.size  # cut-level points: at most 2 per unimodal term, with margin
    scratch = n_in * t_max + n_t + extra + 2 * (u.size + extra)
    return block, scratch


@njit(cache=True, inline="always")
def _interp_at(cp: np.ndarray, u0: int, m0: int, n: int, j: int, x: float) -> float:
    """np.interp on the table row starting at ``m0`` for x in [u[j], u[j+1]], with numpy's
    rounding (``slope·(x − x_j) + f_j``): som/lom compare memberships for equality."""
    xa = cp[u0 + j]
    if j >= n - 1 or x == xa:
        return cp[m0 + j]
    fa = cp[m0 + j]
    slope = (cp[m0 + j + 1] - fa) / (cp[u0 + j + 1] - xa)
    return slope * (x - xa) + fa


@njit(cache=True, inline="always")
def _locate(cp: np.ndarray, u0: int, n: int, x: float) -> int:
    """Index j with u[j] <= x < u[j+1] (binary search; n − 1 at the top end)."""
    lo = 0
    hi = n - 1
    if x >= cp[u0 + hi]:
        return hi
    while hi - lo > 1:
        mid = (lo + hi) >> 1
        if cp[u0 + mid] <= x:
            lo = mid
        else:
            hi = mid
    return lo


@njit(cache=True)
def evaluate(cp: np.ndarray, b: int, scratch: np.ndarray, x0: float, x1: float) -> float:
    """First output of the system packed at ``cp[b:]`` for inputs ``x0`` (and ``x1``): the
    controller's call. NaN when no rule fires in the ``skfuzzy`` semantics (cannot happen
    for a system that passed the coverage check at build time)."""
    n_in = int(cp[b + _T.n_inputs])
    n_out = int(cp[b + _T.n_outputs])
    xs = scratch[:n_in]
    xs[0] = x0
    if n_in > 1:
        xs[1] = x1
    out = scratch[n_in : n_in + n_out]
    evaluate_point(cp, b, scratch[n_in + n_out :], xs, out)
    return out[0]


@njit(cache=True)
def evaluate_point(
    cp: np.ndarray, b: int, scratch: np.ndarray, xs: np.ndarray, out: np.ndarray
) -> int:
    """All outputs for the inputs ``xs`` into ``out``; returns how many outputs fired no rule
    (``matlab``: those are mid-range, ``skfuzzy``: NaN)."""
    if cp[b + _T.semantics] == EXACT:
        return evaluate_exact(cp, b + int(cp[b + _T.blocks]), scratch, xs, out)
    silent = 0
    for o in range(int(cp[b + _T.n_outputs])):
        out[o] = _evaluate_output(cp, b + int(cp[b + _T.blocks + o]), scratch, xs)
        if np.isnan(out[o]):
            silent += 1
    return silent


@njit(cache=True)
def evaluate_many(cp: np.ndarray, scratch: np.ndarray, xs: np.ndarray, out: np.ndarray) -> int:
    """:func:`evaluate_point` for each row of ``xs`` (m, n_in) into ``out`` (m, n_out); the
    number of (row, output) pairs where no rule fired."""
    silent = 0
    for k in range(xs.shape[0]):
        silent += evaluate_point(cp, 0, scratch, xs[k], out[k])
    return silent


@njit(cache=True)
def _evaluate_output(cp: np.ndarray, b: int, scratch: np.ndarray, xs: np.ndarray) -> float:
    """One output in the ``skfuzzy`` semantics (module docstring); NaN when no rule fires."""
    n_in = int(cp[b + _H.n_inputs])
    n_rules = int(cp[b + _H.n_rules])
    and_m = int(cp[b + _H.and_method])
    or_m = int(cp[b + _H.or_method])
    imp_m = int(cp[b + _H.implication])
    agg_m = int(cp[b + _H.aggregation])
    defuzz_m = int(cp[b + _H.defuzzification])
    n_t = int(cp[b + _H.n_terms])
    rule_width = n_in + len(_SR)
    ins = b + int(cp[b + _H.inputs])

    # 1. fuzzification: mu[i*t_stride + k]
    t_stride = int(cp[b + _H.term_stride])
    mu = scratch[: n_in * t_stride]
    for i in range(n_in):
        o = b + int(cp[ins + i])
        lo = cp[o + _SV.low]
        hi = cp[o + _SV.high]
        n = int(cp[o + _SV.n_points])
        nt = int(cp[o + _SV.n_terms])
        x = min(max(xs[i], lo), hi)
        u0 = o + len(_SV)
        j = _locate(cp, u0, n, x)
        for k in range(nt):
            mu[i * t_stride + k] = _interp_at(cp, u0, u0 + n + k * n, n, j, x)

    # 2. rule firing, accumulated per output term (-1: term not referenced by any rule)
    cut = scratch[n_in * t_stride : n_in * t_stride + n_t]
    for t in range(n_t):
        cut[t] = -1.0
    ro = b + int(cp[b + _H.rules])
    for r in range(n_rules):
        q = ro + r * rule_width
        tail = q + n_in
        acc = antecedent(cp, q, n_in, cp[tail + _SR.connective], mu, t_stride, and_m, or_m)
        f = acc * cp[tail + _SR.weight]
        t = int(cp[tail + _SR.term])
        if cut[t] < 0.0:
            cut[t] = f
        elif agg_m == 0:
            cut[t] = max(cut[t], f)
        elif agg_m == 1:
            cut[t] = cut[t] + f
        else:
            cut[t] = cut[t] + f - cut[t] * f

    # 3. output universe: the span where the aggregate may be non-zero
    oo = b + int(cp[b + _H.output])
    n = int(cp[oo + _SV.n_points])
    u0 = oo + len(_SV)
    m0 = u0 + n
    s_lo = m0 + n_t * n
    s_hi = s_lo + n_t
    z_n = s_hi + 2 * n_t
    z_off = z_n + n_t
    j_lo = n
    j_hi = -1
    for t in range(n_t):
        if cut[t] > 0.0:
            j_lo = min(j_lo, int(cp[s_lo + t]))
            j_hi = max(j_hi, int(cp[s_hi + t]))
    if j_hi < 0:
        return np.nan
    x_lo = cp[u0 + j_lo]
    x_hi = cp[u0 + j_hi]

    # 4. extra points at the cut levels (min implication), kept inside the span, sorted
    base = n_in * t_stride + n_t
    extra = scratch[base : base + 4 * n_t + 2 * n]
    n_extra = 0
    if imp_m == 0:
        for t in range(n_t):
            c = cut[t]
            if c < 0.0:
                continue
            if c == 0.0:
                zs = b + int(cp[z_off + t])
                for k in range(int(cp[z_n + t])):
                    z = cp[zs + k]
                    if x_lo <= z <= x_hi:
                        extra[n_extra] = z
                        n_extra += 1
                continue
            mrow = m0 + t * n
            prev = cp[mrow + j_lo] >= c
            for j in range(j_lo, j_hi):
                nxt = cp[mrow + j + 1] >= c
                if nxt != prev:
                    fa = cp[mrow + j]
                    z = cp[u0 + j] + (c - fa) * (cp[u0 + j + 1] - cp[u0 + j]) / (
                        cp[mrow + j + 1] - fa
                    )
                    extra[n_extra] = z
                    n_extra += 1
                prev = nxt
    for a in range(1, n_extra):  # insertion sort: a handful of points
        v = extra[a]
        k = a - 1
        while k >= 0 and extra[k] > v:
            extra[k + 1] = extra[k]
            k -= 1
        extra[k + 1] = v

    # 5. merge universe and extra points (union: sorted, exact duplicates once) and aggregate
    x_base = base + 4 * n_t + 2 * n
    width = n + 4 * n_t + 2 * n
    xs = scratch[x_base : x_base + width]
    ys = scratch[x_base + width : x_base + 2 * width]
    m = 0
    j = j_lo
    e = 0
    while j <= j_hi or e < n_extra:
        if e < n_extra and (j > j_hi or extra[e] < cp[u0 + j]):
            x = extra[e]
            e += 1
            jj = j - 1 if j > 0 else 0
        else:
            x = cp[u0 + j]
            jj = j
            j += 1
        if m > 0 and x == xs[m - 1]:
            continue
        y = 0.0
        for t in range(n_t):
            c = cut[t]
            if c <= 0.0:
                continue
            v = _interp_at(cp, u0, m0 + t * n, n, jj, x)
            v = min(c, v) if imp_m == 0 else c * v
            if agg_m == 0:
                y = max(y, v)
            elif agg_m == 1:
                y = y + v
            else:
                y = y + v - y * v
        xs[m] = x
        ys[m] = y
        m += 1
    return _defuzzify(xs[:m], ys[:m], defuzz_m)


@njit(cache=True)
def _defuzzify(x: np.ndarray, y: np.ndarray, method: int) -> float:
    """scikit-fuzzy's ``defuzz`` formulas on a piecewise-linear set (skfuzzy/defuzzify/defuzz.py)."""
    n = x.size
    if method >= 2:  # mom, som, lom on the sampled points
        top = 0.0
        for i in range(n):
            top = max(top, y[i])
        if top <= 0.0:
            return np.nan
        s = 0.0
        cnt = 0
        first = np.nan
        last = np.nan
        for i in range(n):
            if y[i] == top:
                if cnt == 0:
                    first = x[i]
                last = x[i]
                s += x[i]
                cnt += 1
        if method == 2:
            return s / cnt
        return first if method == 3 else last
    total = 0.0
    moment = 0.0
    for i in range(1, n):
        x1 = x[i - 1]
        x2 = x[i]
        y1 = y[i - 1]
        y2 = y[i]
        if (y1 == 0.0 and y2 == 0.0) or x1 == x2:
            continue
        if y1 == y2:
            mom = 0.5 * (x1 + x2)
            area = (x2 - x1) * y1
        elif y1 == 0.0:
            mom = 2.0 / 3.0 * (x2 - x1) + x1
            area = 0.5 * (x2 - x1) * y2
        elif y2 == 0.0:
            mom = 1.0 / 3.0 * (x2 - x1) + x1
            area = 0.5 * (x2 - x1) * y1
        else:
            mom = (2.0 / 3.0 * (x2 - x1) * (y2 + 0.5 * y1)) / (y1 + y2) + x1
            area = 0.5 * (x2 - x1) * (y1 + y2)
        moment += mom * area
        total += area
    if total <= 0.0:
        return np.nan
    if method == 0:
        return moment / max(total, 2.220446049250313e-16)
    # bisector: the point that halves the area
    half = total / 2.0
    acc = 0.0
    for i in range(1, n):
        x1 = x[i - 1]
        x2 = x[i]
        y1 = y[i - 1]
        y2 = y[i]
        area = 0.0
        if not ((y1 == 0.0 and y2 == 0.0) or x1 == x2):
            area = (x2 - x1) * y1 if y1 == y2 else 0.5 * (x2 - x1) * (y1 + y2)
        if acc + area >= half and area > 0.0:
            sub = half - acc
            w = x2 - x1
            if y1 == y2:
                return sub / y1 + x1
            if y1 == 0.0:
                return x1 + math.sqrt(2.0 * sub * w / y2)
            if y2 == 0.0:
                return x2 - math.sqrt(w * w - 2.0 * sub * w / y1)
            slope = (y2 - y1) / w
            return x1 - (y1 - math.sqrt(y1 * y1 + 2.0 * slope * sub)) / slope
        acc += area
    return x[n - 1]


def evaluate_inputs(system: FuzzySystem, inputs: np.ndarray) -> tuple[np.ndarray, int]:
    """What ``evalfis`` does for a table: outputs (m, n_outputs) for inputs (m, n_inputs),
    in the system's semantics; also how many (row, output) pairs fired no rule (``matlab``:
    mid-range there, ``skfuzzy``: NaN)."""
    xs = np.ascontiguousarray(inputs, dtype=np.float64)
    if xs.ndim != 2 or xs.shape[1] != len(system.inputs):
        raise ValueError(
            f"inputs must have shape (m, {len(system.inputs)}): one column per input, got {xs.shape}"
        )
    cp, scratch = pack_system(system)
    out = np.empty((xs.shape[0], len(system.outputs)))
    silent = evaluate_many(cp, np.zeros(scratch), xs, out)
    return out, int(silent)
