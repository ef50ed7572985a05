/* skewpend Taylor integrator -- appended to the generated recurrences of one order (taylor_source.py).
 *
 * Contract with taylor_source.py (generated, before this file): the SP_STATUS_* and SP_CALL_* codes,
 * SP_TN (5: phi, psi, dphi, dpsi, W; a chain of n links' 2 n + 1: q, q', W), SP_TPMAX, SP_TORDER (the order p of this library),
 * SP_TAYLOR_NPC, taylor_work(p), taylor_prepare(p, pc) and taylor_jet(x, pc, work, e_out), which fills
 * the Taylor coefficients x[i][1 .. p] of the solution through x[i][0] (and, e_out not NULL, the energy
 * T + Pi at x[.][0] into *e_out).
 *
 * Order and step as Jorba & Zou (2005) and heyoka, with the step factor's exponent L a parameter: the
 * caller picks L and p = ceil(-ln(rtol) / L) + 1 (kernels.taylor_rule; heyoka: L = 2); step
 * h = rho exp(-L) exp(-0.7 / (p - 1)), rho = min over m = p - 1, p of (scale / max_i |x_i[m]|)^(1/m),
 * scale = max(atol / rtol, max_i |x_i[0]|) (heyoka's absolute / relative switch when atol = rtol).
 * Every step is accepted; the new state is the polynomial at h (Horner, each step an SP_FMA: a fused
 * multiply-add where the processor has one, see taylor_source.VECTOR_C).  Dense output evaluates
 * the last step's polynomial.  Same resumable contract, rows and return codes as sp_dop853
 * (integrators.c); results do not depend on how the work is split into calls.
 */

#include "rows.h" /* all_finite, put_row: shared with integrators.c */

typedef struct {
    double t;                                /* current time */
    double y[SP_TN];                         /* current state */
    double told, hold;                       /* dense output: the last step went from told over hold */
    double jet[SP_TN][SP_TPMAX + 2];         /* ... with these coefficients */
    int64_t nfev, naccept, nreject, order;   /* nfev: series evaluations (one per step) */
    int32_t started, dense_ok, work, pad;
} sp_taylor_state;

int64_t sp_taylor_state_size(void) { return (int64_t)sizeof(sp_taylor_state); }

static void taylor_eval(const double (*jet)[SP_TPMAX + 2], int order, int n, double h, double *out)
{
    for (int i = 0; i < n; i++) {
        double acc = jet[i][order];
        for (int k = order - 1; k >= 0; k--) acc = SP_FMA(acc, h, jet[i][k]);
        out[i] = acc;
    }
}

/* taylor_eval at this library's order for the step: the four chains of the angles and speeds side by
 * side (independent: the processor overlaps them; each value as taylor_eval's, the same operations in
 * the same order), then W's when it is integrated (n = 5) */
static inline void taylor_eval_step(const double (*jet)[SP_TPMAX + 2], int n, double h, double *out)
{
    double a0 = jet[0][SP_TORDER], a1 = jet[1][SP_TORDER], a2 = jet[2][SP_TORDER], a3 = jet[3][SP_TORDER];
    for (int k = SP_TORDER - 1; k >= 0; k--) {
        a0 = SP_FMA(a0, h, jet[0][k]);
        a1 = SP_FMA(a1, h, jet[1][k]);
        a2 = SP_FMA(a2, h, jet[2][k]);
        a3 = SP_FMA(a3, h, jet[3][k]);
    }
    out[0] = a0;
    out[1] = a1;
    out[2] = a2;
    out[3] = a3;
    if (n > 4) taylor_eval(jet + 4, SP_TORDER, n - 4, h, out + 4);
}

/* the step rule's constants (Jorba and Zou, as heyoka, whose L is 2): the safety factor, the floor of the
 * norm (atol / rtol) and the exponents 1/(order - 1), 1/order */
static inline void taylor_step_rule(int order, double rtol, double atol, double L, double *fac, double *floor_scale,
                                    double *e1, double *e2)
{
    *fac = exp(-L) * exp(-0.7 / (double)(order - 1));
    *floor_scale = atol / rtol;
    *e1 = 1.0 / (double)(order - 1);
    *e2 = 1.0 / (double)order;
}

/* the step: rho = min over m = p - 1, p of (scale / d_m)^(1/m) (e1, e2: the exponents), times fac, as
 * two logarithms and one exponential, not two powers; a d_m = 0 gives no bound (both 0: an infinite
 * step, cut at the end of the run) */
static inline double taylor_log2_floor(double x) /* a lower bound of log2 x within 0.0861 (x normal, > 0) */
{
    uint64_t b;
    memcpy(&b, &x, sizeof b);
    return (double)((int)(b >> 52) - 1023) + (double)(b & 0x000fffffffffffffULL) * 0x1p-52;
}

static inline double taylor_step(double scale, double d1, double d2, double e1, double e2, double fac)
{
    double lrho = INFINITY;
    if (d1 > 0.0 && d2 > 0.0) {
        /* the smaller of the two bounds, when the exponents alone tell (one logarithm, not two: the
         * same value as the minimum of both, which is then this one); else both */
        const double x1 = scale / d1, x2 = scale / d2;
        if (x1 >= 0x1p-1000 && x1 <= 0x1p1000 && x2 >= 0x1p-1000 && x2 <= 0x1p1000) {
            const double l1 = taylor_log2_floor(x1), l2 = taylor_log2_floor(x2);
            if ((l1 + 0.087) * e1 < l2 * e2 - 1e-6) return exp(log(x1) * e1) * fac;
            if ((l2 + 0.087) * e2 < l1 * e1 - 1e-6) return exp(log(x2) * e2) * fac;
        }
    }
    if (d1 > 0.0) lrho = log(scale / d1) * e1;
    if (d2 > 0.0) lrho = fmin(lrho, log(scale / d2) * e2);
    return exp(lrho) * fac;
}

/* What both drivers do on entry: the prepared constants, the step rule's constants, and on a run's first
 * call (*first set to 1, else 0) its order and work flag; returns 0, or SP_STATUS_NONFINITE for a start
 * that is not finite. */
static int taylor_enter(sp_taylor_state *s, const double *p, double rtol, double atol, double L, double *pc,
                        double *fac, double *floor_scale, double *e1, double *e2, int *first)
{
    taylor_prepare(p, pc);
    taylor_step_rule(SP_TORDER, rtol, atol, L, fac, floor_scale, e1, e2);
    *first = !s->started;
    if (s->started) return 0;
    s->started = 1;
    s->order = SP_TORDER;
    s->work = taylor_work(p);
    return all_finite(s->y, SP_TN) ? 0 : SP_STATUS_NONFINITE;
}

/* max_i |x_i[0]|, |x_i[order - 1]|, |x_i[order]| over the first n components: as fmax from 0 (a NaN
 * skipped), written as comparisons (fmax is a library call without -ffinite-math-only) */
static inline void taylor_norms(const double (*x)[SP_TPMAX + 2], int order, int n, double *big, double *d1, double *d2)
{
    double b = 0.0, e1 = 0.0, e2 = 0.0;
    for (int i = 0; i < n; i++) {
        const double u = fabs(x[i][0]), v = fabs(x[i][order - 1]), w = fabs(x[i][order]);
        b = u > b ? u : b;
        e1 = v > e1 ? v : e1;
        e2 = w > e2 ? w : e2;
    }
    *big = b;
    *d1 = e1;
    *d2 = e2;
}

int sp_taylor(sp_taylor_state *s, const double *p, double t_end, double rtol, double atol, double L,
              int64_t max_steps, int64_t budget, double dt_out, int64_t n_grid, int64_t *k_out, double *rows,
              int64_t cap, int64_t *m_out)
{
    const int n = SP_TN, dense = dt_out > 0.0;
    double pc[SP_TAYLOR_NPC], x[SP_TN][SP_TPMAX + 2], ynew[SP_TN];
    int64_t m = 0, done = 0;
    *m_out = 0;
    if (cap < 2 || !(rtol > 0.0) || !(atol > 0.0) || !(L > 0.0 && L < 64.0)) return SP_CALL_BAD_ARGUMENTS;
    const int order = SP_TORDER;
    double fac, floor_scale, e1, e2;
    int first;
    if (taylor_enter(s, p, rtol, atol, L, pc, &fac, &floor_scale, &e1, &e2, &first)) return SP_STATUS_NONFINITE;
    if (first && !dense) put_row(rows, m++, n, s->t, s->y);
    const int nc = s->work ? n : n - 1; /* W is left out of the norms when it is not integrated */
    for (;;) {
        if (dense) {
            while (*k_out < n_grid) {
                double tk = (double)(*k_out) * dt_out;
                if (tk > s->t && s->t < t_end) break;
                if (m >= cap) { *m_out = m; return SP_CALL_BUFFER_FULL; }
                double *r = rows + m * (n + 1);
                r[0] = tk;
                if (tk >= s->t || !s->dense_ok) {
                    memcpy(r + 1, s->y, (size_t)n * sizeof(double));
                } else {
                    taylor_eval((const double (*)[SP_TPMAX + 2])s->jet, (int)s->order, n, tk - s->told, r + 1);
                    if (!all_finite(r + 1, n)) { *m_out = m; return SP_STATUS_NONFINITE; }
                }
                m++;
                (*k_out)++;
            }
        }
        if (s->t >= t_end) { *m_out = m; return SP_STATUS_SUCCESS; }
        if (done >= budget) { *m_out = m; return SP_CALL_BUDGET; }
        if (!dense && m >= cap) { *m_out = m; return SP_CALL_BUFFER_FULL; }
        if (s->naccept >= max_steps) { *m_out = m; return SP_STATUS_MAX_STEPS; }

        for (int i = 0; i < n; i++) x[i][0] = s->y[i];
        taylor_jet(x, pc, s->work, NULL);
        s->nfev++;
        double big, d1, d2;
        taylor_norms((const double (*)[SP_TPMAX + 2])x, order, nc, &big, &d1, &d2);
        const double scale = big > floor_scale ? big : floor_scale; /* fmax: neither is a NaN */
        double h = taylor_step(scale, d1, d2, e1, e2, fac);
        if (!(h == h)) { *m_out = m; return SP_STATUS_NONFINITE; }
        const double left = t_end - s->t;
        int last = 0;
        if (h >= left) { h = left; last = 1; }
        if (!last && s->t + h == s->t) { *m_out = m; return SP_STATUS_STEP_UNDERFLOW; }
        taylor_eval_step((const double (*)[SP_TPMAX + 2])x, nc, h, ynew);
        if (nc < n) ynew[SP_TN - 1] = s->y[SP_TN - 1]; /* W' = 0 identically: W stays */
        if (!all_finite(ynew, n)) { *m_out = m; return SP_STATUS_NONFINITE; }
        s->naccept++;
        done++;
        s->dense_ok = 0;
        if (dense && *k_out < n_grid && (double)(*k_out) * dt_out < (last ? t_end : s->t + h)) {
            memcpy(s->jet, x, sizeof x);
            s->told = s->t;
            s->hold = h;
            s->dense_ok = 1;
        }
        s->t = last ? t_end : s->t + h;
        memcpy(s->y, ynew, (size_t)n * sizeof(double));
        if (!dense) put_row(rows, m++, n, s->t, s->y);
    }
}

/* The account of rows m0 .. m - 1 (their energies in e[], their works in w[]): as sp_energy_account in
 * the model's kernel (acc[0] = max |E - W - E0|, acc[1] = max |E|, E0 = acc[2] from the first row ever,
 * acc[3] = 1 then). */
static void taylor_account(const double *w, const double *e, int64_t m0, int64_t m, double *acc)
{
    for (int64_t r = m0; r < m; r++) {
        const double en = e[r], wr = w[r];
        if (acc[3] == 0.0) {
            acc[2] = en;
            acc[3] = 1.0;
        }
        const double d = fabs((en - wr) - acc[2]);
        if (d > acc[0] || d != d) acc[0] = d;
        if (fabs(en) > acc[1] || en != en) acc[1] = fabs(en);
    }
}

/* a row of sp_taylor_rows: the time, the state and W as columns (cols: t at [0, cap), the SP_TN - 1 state
 * components at [cap, SP_TN cap) a row after another, W at [SP_TN cap, (SP_TN + 1) cap)) */
static inline void put_cols(double *cols, int64_t cap, int64_t m, double t, const double *y)
{
    double *yr = cols + cap + (SP_TN - 1) * m;
    cols[m] = t;
    for (int i = 0; i < SP_TN - 1; i++) yr[i] = y[i];
    cols[SP_TN * cap + m] = y[SP_TN - 1];
}

/* sp_taylor at the integrator's own steps (dt_out = 0), the rows as columns into cols (put_cols: the
 * caller copies each out in one piece), each row's energy T + Pi into e[row] (from the order 0 of the
 * next step's series: the sines and cosines shared; the last row's by one more series evaluation) and
 * the rows' energy account into acc[4] (taylor_account).  y0 not NULL: the run starts here, from t = 0,
 * y = (y0[0 .. SP_TN - 2], W = 0) (the state and acc are reset).  The same steps, rows and codes as sp_taylor. */
int sp_taylor_rows(sp_taylor_state *s, const double *y0, const double *p, double t_end, double rtol, double atol,
                   double L, int64_t max_steps, int64_t budget, double *cols, int64_t cap, double *e, double *acc,
                   int64_t *m_out)
{
    const int n = SP_TN;
    double pc[SP_TAYLOR_NPC], x[SP_TN][SP_TPMAX + 2], ynew[SP_TN];
    int64_t m = 0, done = 0;
    int code, pending = 0; /* pending: row m - 1 is the current state, its energy not yet known */
    *m_out = 0;
    if (cap < 2 || !(rtol > 0.0) || !(atol > 0.0) || !(L > 0.0 && L < 64.0)) return SP_CALL_BAD_ARGUMENTS;
    if (y0) {
        memset(s, 0, sizeof *s);
        memcpy(s->y, y0, (SP_TN - 1) * sizeof(double));
        memset(acc, 0, 4 * sizeof(double));
    }
    const int order = SP_TORDER;
    double fac, floor_scale, e1, e2;
    int first;
    if (taylor_enter(s, p, rtol, atol, L, pc, &fac, &floor_scale, &e1, &e2, &first)) return SP_STATUS_NONFINITE;
    if (first) {
        put_cols(cols, cap, m++, s->t, s->y);
        pending = 1;
    }
    const int nc = s->work ? n : n - 1;
    for (;;) {
        if (s->t >= t_end) { code = SP_STATUS_SUCCESS; break; }
        if (done >= budget) { code = SP_CALL_BUDGET; break; }
        if (m >= cap) { code = SP_CALL_BUFFER_FULL; break; }
        if (s->naccept >= max_steps) { code = SP_STATUS_MAX_STEPS; break; }

        for (int i = 0; i < n; i++) x[i][0] = s->y[i];
        double en;
        taylor_jet(x, pc, s->work, pending ? &en : NULL);
        if (pending) { e[m - 1] = en; pending = 0; }
        s->nfev++;
        double big, d1, d2;
        taylor_norms((const double (*)[SP_TPMAX + 2])x, order, nc, &big, &d1, &d2);
        const double scale = big > floor_scale ? big : floor_scale; /* fmax: neither is a NaN */
        double h = taylor_step(scale, d1, d2, e1, e2, fac);
        if (!(h == h)) { code = SP_STATUS_NONFINITE; break; }
        const double left = t_end - s->t;
        int last = 0;
        if (h >= left) { h = left; last = 1; }
        if (!last && s->t + h == s->t) { code = SP_STATUS_STEP_UNDERFLOW; break; }
        taylor_eval_step((const double (*)[SP_TPMAX + 2])x, nc, h, ynew);
        if (nc < n) ynew[SP_TN - 1] = s->y[SP_TN - 1];
        if (!all_finite(ynew, n)) { code = SP_STATUS_NONFINITE; break; }
        s->naccept++;
        done++;
        s->dense_ok = 0;
        s->t = last ? t_end : s->t + h;
        memcpy(s->y, ynew, (size_t)n * sizeof(double));
        put_cols(cols, cap, m++, s->t, s->y);
        pending = 1;
    }
    if (pending) { /* the last row's energy: one more series evaluation (its coefficients unused) */
        double en;
        for (int i = 0; i < n; i++) x[i][0] = s->y[i];
        taylor_jet(x, pc, s->work, &en);
        e[m - 1] = en;
    }
    taylor_account(cols + SP_TN * cap, e, 0, m, acc);
    *m_out = m;
    return code;
}
