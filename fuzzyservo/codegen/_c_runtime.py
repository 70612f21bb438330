"""The C99 evaluator: a line-by-line port of the compiled evaluator and control law.

The packed parameter vector (:meth:`FuzzyController.pack`) is embedded as a constant
array ``CP``; the functions below read it exactly as :mod:`fuzzyservo.controllers.fuzzy.
evaluate` (``skfuzzy`` semantics), :mod:`~fuzzyservo.controllers.fuzzy.exact`
(``matlab`` semantics) and :func:`~fuzzyservo.controllers.fuzzy.controller.fuzzy_step`
do, so the generated code computes the same numbers (to rounding). ``min``/``max``
follow Python's argument order on ties. ``@P@`` is the name prefix, ``@R@`` the real type.
"""

RUNTIME = r"""
static @R@ fs_min(@R@ a, @R@ b) { return b < a ? b : a; }
static @R@ fs_max(@R@ a, @R@ b) { return b > a ? b : a; }
static long ix(@R@ v) { return (long)v; }

/* a rule's term code decoded, as fuzzyservo.controllers.fuzzy.system.term_index does:
   the term, and in *negated whether the rule says NOT term */
static long term_index(long code, int *negated)
{
    *negated = code < NO_TERM;
    return *negated ? -code - 2 : code;
}

#if FS_SAMPLED
static @R@ interp_at(long u0, long m0, long n, long j, @R@ x)
{
    @R@ xa = CP[u0 + j], fa, slope;
    if (j >= n - 1 || x == xa) return CP[m0 + j];
    fa = CP[m0 + j];
    slope = (CP[m0 + j + 1] - fa) / (CP[u0 + j + 1] - xa);
    return slope * (x - xa) + fa;
}

static long locate(long u0, long n, @R@ x)
{
    long lo = 0, hi = n - 1, mid;
    if (x >= CP[u0 + hi]) return hi;
    while (hi - lo > 1) {
        mid = (lo + hi) >> 1;
        if (CP[u0 + mid] <= x) lo = mid; else hi = mid;
    }
    return lo;
}

/* scikit-fuzzy's defuzz formulas on a piecewise-linear set */
static @R@ defuzzify(const @R@ *x, const @R@ *y, long n, int method)
{
    long i;
    @R@ total = 0, moment = 0, x1, x2, y1, y2, mom, area, half, acc, sub, w, slope;
    if (method >= 2) {
        @R@ top = 0, s = 0, first = 0, last = 0;
        long cnt = 0;
        for (i = 0; i < n; i++) top = fs_max(top, y[i]);
        if (top <= 0) return (@R@)NAN;
        for (i = 0; i < n; i++) {
            if (y[i] == top) {
                if (cnt == 0) first = x[i];
                last = x[i];
                s += x[i];
                cnt++;
            }
        }
        if (method == 2) return s / (@R@)cnt;
        return method == 3 ? first : last;
    }
    for (i = 1; i < n; i++) {
        x1 = x[i - 1]; x2 = x[i]; y1 = y[i - 1]; y2 = y[i];
        if ((y1 == 0 && y2 == 0) || x1 == x2) continue;
        if (y1 == y2) { mom = (@R@)0.5 * (x1 + x2); area = (x2 - x1) * y1; }
        else if (y1 == 0) { mom = (@R@)(2.0 / 3.0) * (x2 - x1) + x1; area = (@R@)0.5 * (x2 - x1) * y2; }
        else if (y2 == 0) { mom = (@R@)(1.0 / 3.0) * (x2 - x1) + x1; area = (@R@)0.5 * (x2 - x1) * y1; }
        else {
            mom = ((@R@)(2.0 / 3.0) * (x2 - x1) * (y2 + (@R@)0.5 * y1)) / (y1 + y2) + x1;
            area = (@R@)0.5 * (x2 - x1) * (y1 + y2);
        }
        moment += mom * area;
        total += area;
    }
    if (total <= 0) return (@R@)NAN;
    if (method == 0) return moment / fs_max(total, (@R@)2.220446049250313e-16);
    half = total / 2;
    acc = 0;
    for (i = 1; i < n; i++) {
        x1 = x[i - 1]; x2 = x[i]; y1 = y[i - 1]; y2 = y[i];
        area = 0;
        if (!((y1 == 0 && y2 == 0) || x1 == x2))
            area = y1 == y2 ? (x2 - x1) * y1 : (@R@)0.5 * (x2 - x1) * (y1 + y2);
        if (acc + area >= half && area > 0) {
            sub = half - acc;
            w = x2 - x1;
            if (y1 == y2) return sub / y1 + x1;
            if (y1 == 0) return x1 + (@R@)sqrt(2 * sub * w / y2);
            if (y2 == 0) return x2 - (@R@)sqrt(w * w - 2 * sub * w / y1);
            slope = (y2 - y1) / w;
            return x1 - (y1 - (@R@)sqrt(y1 * y1 + 2 * slope * sub)) / slope;
        }
        acc += area;
    }
    return x[n - 1];
}

/* one output, skfuzzy semantics: sampled universes, cut levels, aggregation, defuzz */
static @R@ evaluate_output(long b, @R@ *scratch, const @R@ *xs)
{
    long n_in = ix(CP[b + H_N_INPUTS]), n_rules = ix(CP[b + H_N_RULES]);
    int and_m = (int)ix(CP[b + H_AND_METHOD]), or_m = (int)ix(CP[b + H_OR_METHOD]);
    int imp_m = (int)ix(CP[b + H_IMPLICATION]), agg_m = (int)ix(CP[b + H_AGGREGATION]);
    int defuzz_m = (int)ix(CP[b + H_DEFUZZIFICATION]);
    long n_t = ix(CP[b + H_N_TERMS]), rule_width = n_in + SR_SIZE, ins = b + ix(CP[b + H_INPUTS]);
    long t_stride = ix(CP[b + H_TERM_STRIDE]);
    @R@ *mu = scratch, *cut, *extra, *px, *py;
    long i, k, r, t, j, o, n, nt, u0, ro, q, a, oo, m0, s_lo, s_hi, z_n, z_off, j_lo, j_hi;
    long base, n_extra, x_base, width, m, e, jj, mrow, zs;
    @R@ x, lo, hi, acc, mv, f, c, z, x_lo, x_hi, fa, v, y;
    int prev, nxt, negated;

    for (i = 0; i < n_in; i++) {
        o = b + ix(CP[ins + i]);
        lo = CP[o + SV_LOW]; hi = CP[o + SV_HIGH];
        n = ix(CP[o + SV_N_POINTS]); nt = ix(CP[o + SV_N_TERMS]);
        x = fs_min(fs_max(xs[i], lo), hi);
        u0 = o + SV_SIZE;
        j = locate(u0, n, x);
        for (k = 0; k < nt; k++) mu[i * t_stride + k] = interp_at(u0, u0 + n + k * n, n, j, x);
    }
    cut = scratch + n_in * t_stride;
    for (t = 0; t < n_t; t++) cut[t] = -1;
    ro = b + ix(CP[b + H_RULES]);
    for (r = 0; r < n_rules; r++) {
        q = ro + r * rule_width;
        acc = -1;
        for (i = 0; i < n_in; i++) {
            a = ix(CP[q + i]);
            if (a == NO_TERM) continue;
            k = term_index(a, &negated);
            mv = negated ? 1 - mu[i * t_stride + k] : mu[i * t_stride + k];
            if (acc < 0) acc = mv;
            else if (CP[q + n_in + SR_CONNECTIVE] == 0) acc = and_m == 0 ? fs_min(acc, mv) : acc * mv;
            else acc = or_m == 0 ? fs_max(acc, mv) : acc + mv - acc * mv;
        }
        f = acc * CP[q + n_in + SR_WEIGHT];
        t = ix(CP[q + n_in + SR_TERM]);
        if (cut[t] < 0) cut[t] = f;
        else if (agg_m == 0) cut[t] = fs_max(cut[t], f);
        else if (agg_m == 1) cut[t] = cut[t] + f;
        else cut[t] = cut[t] + f - cut[t] * f;
    }
    oo = b + ix(CP[b + H_OUTPUT]);
    n = ix(CP[oo + SV_N_POINTS]);
    u0 = oo + SV_SIZE;
    m0 = u0 + n;
    s_lo = m0 + n_t * n;
    s_hi = s_lo + n_t;
    z_n = s_hi + 2 * n_t;
    z_off = z_n + n_t;
    j_lo = n;
    j_hi = -1;
    for (t = 0; t < n_t; t++) {
        if (cut[t] > 0) {
            if (ix(CP[s_lo + t]) < j_lo) j_lo = ix(CP[s_lo + t]);
            if (ix(CP[s_hi + t]) > j_hi) j_hi = ix(CP[s_hi + t]);
        }
    }
    if (j_hi < 0) return (@R@)NAN;
    x_lo = CP[u0 + j_lo];
    x_hi = CP[u0 + j_hi];
    base = n_in * t_stride + n_t;
    extra = scratch + base;
    n_extra = 0;
    if (imp_m == 0) {
        for (t = 0; t < n_t; t++) {
            c = cut[t];
            if (c < 0) continue;
            if (c == 0) {
                zs = b + ix(CP[z_off + t]);
                for (k = 0; k < ix(CP[z_n + t]); k++) {
                    z = CP[zs + k];
                    if (x_lo <= z && z <= x_hi) extra[n_extra++] = z;
                }
                continue;
            }
            mrow = m0 + t * n;
            prev = CP[mrow + j_lo] >= c;
            for (j = j_lo; j < j_hi; j++) {
                nxt = CP[mrow + j + 1] >= c;
                if (nxt != prev) {
                    fa = CP[mrow + j];
                    z = CP[u0 + j] + (c - fa) * (CP[u0 + j + 1] - CP[u0 + j]) / (CP[mrow + j + 1] - fa);
                    extra[n_extra++] = z;
                }
                prev = nxt;
            }
        }
    }
    for (a = 1; a < n_extra; a++) {
        v = extra[a];
        k = a - 1;
        while (k >= 0 && extra[k] > v) { extra[k + 1] = extra[k]; k--; }
        extra[k + 1] = v;
    }
    x_base = base + 4 * n_t + 2 * n;
    width = n + 4 * n_t + 2 * n;
    px = scratch + x_base;
    py = scratch + x_base + width;
    m = 0; j = j_lo; e = 0;
    while (j <= j_hi || e < n_extra) {
        if (e < n_extra && (j > j_hi || extra[e] < CP[u0 + j])) {
            x = extra[e++];
            jj = j > 0 ? j - 1 : 0;
        } else {
            x = CP[u0 + j];
            jj = j++;
        }
        if (m > 0 && x == px[m - 1]) continue;
        y = 0;
        for (t = 0; t < n_t; t++) {
            c = cut[t];
            if (c <= 0) continue;
            v = interp_at(u0, m0 + t * n, n, jj, x);
            v = imp_m == 0 ? fs_min(c, v) : c * v;
            if (agg_m == 0) y = fs_max(y, v);
            else if (agg_m == 1) y = y + v;
            else y = y + v - y * v;
        }
        px[m] = x;
        py[m] = y;
        m++;
    }
    return defuzzify(px, py, m, defuzz_m);
}
#endif

#if FS_EXACT
static @R@ sig(@R@ a, @R@ c, @R@ x) { return 1 / (1 + (@R@)exp(-a * (x - c))); }

static @R@ smf(@R@ a, @R@ b, @R@ x)
{
    @R@ t;
    if (a >= b) return x >= (@R@)0.5 * (a + b) ? 1 : 0;
    if (x <= a) return 0;
    if (x >= b) return 1;
    if (x <= (@R@)0.5 * (a + b)) { t = (x - a) / (b - a); return 2 * t * t; }
    t = (x - b) / (b - a);
    return 1 - 2 * t * t;
}

static @R@ zmf(@R@ a, @R@ b, @R@ x)
{
    @R@ t;
    if (a >= b) return x <= (@R@)0.5 * (a + b) ? 1 : 0;
    if (x <= a) return 1;
    if (x >= b) return 0;
    if (x <= (@R@)0.5 * (a + b)) { t = (x - a) / (b - a); return 1 - 2 * t * t; }
    t = (x - b) / (b - a);
    return 2 * t * t;
}

/* MATLAB's membership functions; parameters at CP[o] */
static @R@ mf_value(int code, long o, @R@ x)
{
    const @R@ *p = CP + o;
    @R@ y1, y2;
    switch (code) {
    case 0:
        if (x == p[1]) return 1;
        if (x <= p[0] || x >= p[2]) return 0;
        return x < p[1] ? (x - p[0]) / (p[1] - p[0]) : (p[2] - x) / (p[2] - p[1]);
    case 1:
        y1 = 1; y2 = 1;
        if (x < p[0]) y1 = 0; else if (x < p[1]) y1 = (x - p[0]) / (p[1] - p[0]);
        if (x > p[3]) y2 = 0; else if (x > p[2]) y2 = (p[3] - x) / (p[3] - p[2]);
        return fs_min(y1, y2);
    case 2: return (@R@)exp(-((x - p[1]) * (x - p[1])) / (2 * p[0] * p[0]));
    case 3: return 1 / (1 + (@R@)pow(fabs((x - p[2]) / p[0]), 2 * p[1]));
    case 4: return sig(p[0], p[1], x);
    case 5: return smf(p[0], p[1], x);
    case 6: return zmf(p[0], p[1], x);
    case 7: return smf(p[0], p[1], x) * zmf(p[2], p[3], x);
    case 8:
        y1 = x <= p[1] ? (@R@)exp(-((x - p[1]) * (x - p[1])) / (2 * p[0] * p[0])) : 1;
        y2 = x >= p[3] ? (@R@)exp(-((x - p[3]) * (x - p[3])) / (2 * p[2] * p[2])) : 1;
        return y1 * y2;
    case 9: return (@R@)fabs(sig(p[0], p[1], x) - sig(p[2], p[3], x));
    case 10: return sig(p[0], p[1], x) * sig(p[2], p[3], x);
    case 11: if (x < p[0]) return 0; if (x >= p[1]) return 1; return (x - p[0]) / (p[1] - p[0]);
    case 12: if (x <= p[0]) return 1; if (x > p[1]) return 0; return (p[1] - x) / (p[1] - p[0]);
    default: return (@R@)NAN;
    }
}

static @R@ term_mu(long t, @R@ x) { return mf_value((int)ix(CP[t + XT_SHAPE]), t + XT_SIZE, x); }

/* MATLAB's defuzz on ys at linspace(lo, hi, n); NAN when all zero */
static @R@ defuzz_samples(const @R@ *ys, @R@ lo, @R@ hi, @R@ step, long n, int method)
{
    @R@ total = 0, top = 0, moment = 0, acc = 0, s = 0, best = 0, xk;
    long k, cnt = 0;
    for (k = 0; k < n; k++) { total += ys[k]; top = fs_max(top, ys[k]); }
    if (total <= 0) return (@R@)NAN;
    if (method == 0) {
        for (k = 0; k < n; k++) moment += (k == n - 1 ? hi : lo + (@R@)k * step) * ys[k];
        return moment / total;
    }
    if (method == 1) {
        for (k = 0; k < n; k++) {
            acc += ys[k];
            if (acc >= (@R@)0.5 * total) return k == n - 1 ? hi : lo + (@R@)k * step;
        }
        return hi;
    }
    for (k = 0; k < n; k++) {
        if (ys[k] == top) {
            xk = k == n - 1 ? hi : lo + (@R@)k * step;
            s += xk;
            if (cnt == 0 || (method == 3 ? fabs(xk) < fabs(best) : fabs(xk) > fabs(best))) best = xk;
            cnt++;
        }
    }
    return method == 2 ? s / (@R@)cnt : best;
}

/* all outputs, matlab (evalfis) semantics; returns the outputs that fired no rule */
static int evaluate_exact(long b, @R@ *scratch, const @R@ *xs, @R@ *out)
{
    long n_in = ix(CP[b + X_N_INPUTS]), n_out = ix(CP[b + X_N_OUTPUTS]);
    long n_rules = ix(CP[b + X_N_RULES]);
    int and_m = (int)ix(CP[b + X_AND_METHOD]), or_m = (int)ix(CP[b + X_OR_METHOD]);
    int imp_m = (int)ix(CP[b + X_IMPLICATION]), agg_m = (int)ix(CP[b + X_AGGREGATION]);
    int defuzz_m = (int)ix(CP[b + X_DEFUZZIFICATION]), silent = 0, neg;
    long n_s = ix(CP[b + X_SAMPLES]), vt = b + ix(CP[b + X_VARIABLES]);
    long ro = b + ix(CP[b + X_RULES]);
    long width = n_in + n_out + XR_SIZE, t_max = 0, i, k, r, o, v, q, a, c, t;
    @R@ *mu, *x, *w, *ys, acc, mv, lo, hi, num, den, z, step, xk, value;

    for (i = 0; i < n_in; i++) {
        k = ix(CP[b + ix(CP[vt + i]) + XV_N_TERMS]);
        if (k > t_max) t_max = k;
    }
    mu = scratch;
    x = scratch + n_in * t_max;
    w = x + n_in;
    ys = w + n_rules;
    for (i = 0; i < n_in; i++) {
        v = b + ix(CP[vt + i]);
        x[i] = fs_min(fs_max(xs[i], CP[v + XV_LOW]), CP[v + XV_HIGH]);
        for (k = 0; k < ix(CP[v + XV_N_TERMS]); k++)
            mu[i * t_max + k] = term_mu(b + ix(CP[v + XV_SIZE + k]), x[i]);
    }
    for (r = 0; r < n_rules; r++) {
        q = ro + r * width;
        acc = -1;
        for (i = 0; i < n_in; i++) {
            a = ix(CP[q + i]);
            if (a == NO_TERM) continue;
            k = term_index(a, &neg);
            mv = neg ? 1 - mu[i * t_max + k] : mu[i * t_max + k];
            if (acc < 0) acc = mv;
            else if (CP[q + n_in + n_out + XR_CONNECTIVE] == 0) acc = and_m == 0 ? fs_min(acc, mv) : acc * mv;
            else acc = or_m == 0 ? fs_max(acc, mv) : acc + mv - acc * mv;
        }
        w[r] = acc * CP[q + n_in + n_out + XR_WEIGHT];
    }
    for (o = 0; o < n_out; o++) {
        v = b + ix(CP[vt + n_in + o]);
        lo = CP[v + XV_LOW];
        hi = CP[v + XV_HIGH];
        if (CP[b + X_SUGENO] == 1) {
            num = 0; den = 0;
            for (r = 0; r < n_rules; r++) {
                c = ix(CP[ro + r * width + n_in + o]);
                k = term_index(c, &neg);
                if (c == NO_TERM || neg || w[r] == 0) continue;
                t = b + ix(CP[v + XV_SIZE + k]);
                if (ix(CP[t + XT_SHAPE]) == @CONSTANT@) z = CP[t + XT_SIZE];
                else {
                    z = CP[t + XT_SIZE + n_in];
                    for (i = 0; i < n_in; i++) z += CP[t + XT_SIZE + i] * x[i];
                }
                num += w[r] * z;
                den += w[r];
            }
            if (den == 0) { out[o] = (@R@)0.5 * (lo + hi); silent++; }
            else out[o] = defuzz_m == 6 ? num : num / den;
            continue;
        }
        step = (hi - lo) / (@R@)(n_s - 1);
        for (k = 0; k < n_s; k++) ys[k] = 0;
        for (r = 0; r < n_rules; r++) {
            c = ix(CP[ro + r * width + n_in + o]);
            if (c == NO_TERM || w[r] == 0) continue;
            t = b + ix(CP[v + XV_SIZE + term_index(c, &neg)]);
            for (k = 0; k < n_s; k++) {
                xk = k == n_s - 1 ? hi : lo + (@R@)k * step;
                mv = term_mu(t, xk);
                if (neg) mv = 1 - mv;
                mv = imp_m == 0 ? fs_min(w[r], mv) : w[r] * mv;
                if (agg_m == 0) ys[k] = fs_max(ys[k], mv);
                else if (agg_m == 1) ys[k] = ys[k] + mv;
                else ys[k] = ys[k] + mv - ys[k] * mv;
            }
        }
        value = defuzz_samples(ys, lo, hi, step, n_s, defuzz_m);
        if (value != value) { out[o] = (@R@)0.5 * (lo + hi); silent++; }
        else out[o] = value;
    }
    return silent;
}
#endif

/* all outputs of the system block at CP[b]; returns the outputs that fired no rule */
static int evaluate_point(long b, @R@ *scratch, const @R@ *xs, @R@ *out)
{
    int silent = 0;
    long o;
#if FS_EXACT
    if (CP[b + T_SEMANTICS] == SEM_EXACT) return evaluate_exact(b + ix(CP[b + T_BLOCKS]), scratch, xs, out);
#endif
#if FS_SAMPLED
    for (o = 0; o < ix(CP[b + T_N_OUTPUTS]); o++) {
        out[o] = evaluate_output(b + ix(CP[b + T_BLOCKS + o]), scratch, xs);
        if (out[o] != out[o]) silent++;
    }
#else
    (void)o;
#endif
    return silent;
}
"""
