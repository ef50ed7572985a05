/* skewpend chaos kernel: Lyapunov exponents and Poincare sections.
 *
 * Appended to the generated model code (which defines rhs and rhs_jac, the right-hand side and
 * its Jacobian printed from the derivation) and integrators.c; it includes the DOP853 core
 * (dop853_core.h) a second time for its variational systems: the functions with suffix _v, state
 * size SP_VMAX, right-hand side var_rhs(n, ...).  Like the integrators, every routine does a
 * bounded amount of work per call and can be resumed, so the caller shows progress and handles
 * Ctrl-C between calls; return codes are the SP_STATUS_* / SP_CALL_* of integrators.c.
 */

/* The state's size SP_N2 = 2 SP_NQ (4 for the double pendulum, 2 n for a chain of n links; the model
 * code defines SP_NQ) and that of the variational systems: the state and up to SP_N2 tangent vectors
 * (kernels.lyap_state_type; the layout check of sp_lyap_state_size catches a mismatch). */
#define SP_N2 (2 * SP_NQ)
#define SP_VMAX (SP_N2 * (SP_N2 + 1))
static void var_rhs(int n, const double *y, const double *p, double *out);
#define DOP_NAME(x) x##_v
#define DOP_NDIM SP_VMAX
#define DOP_RHS(y, p, out) var_rhs(n, y, p, out)
#include "dop853_core.h"

/* ---- variational equations: the state y[0 .. N2-1] and k tangent vectors y[N2 + N2 j .. N2 + N2 j + N2-1] ---- */

/* d/dt of (y, v_1 .. v_k): (F(y), J(y) v_1, ..., J(y) v_k), with J the generated Jacobian
 * ((N2 + 1) x (N2 + 1) with the work's row and column) evaluated at the current state --
 * integrated together with the state, so the tangent dynamics are as accurate as the trajectory
 * (not a Jacobian frozen over a step).  The angles' rows of J are (0 | I) in every model (the state
 * is the angles, then their rates): J v's first SP_NQ entries are v's last SP_NQ, copied (for a
 * finite v the products by 0 and 1 gave the same numbers).  The rates' rows are summed over the
 * columns in order, as a row-by-vector product does (the same bits), SP_NQ rows at a time from J's
 * transpose so the compiler keeps them side by side in vector registers, the loop over the columns
 * unrolled (issue 52: the generic loops of de01a22 cost the double pendulum's Lyapunov spectrum 7 %
 * more instructions an evaluation than the 4 x 4 products they replaced). */
static void var_rhs(int n, const double *y, const double *p, double *out)
{
    double ys[SP_N2 + 1], f[SP_N2 + 1], J[(SP_N2 + 1) * (SP_N2 + 1)], Jt[SP_N2][SP_NQ];
    const int k = (n - SP_N2) / SP_N2, w = SP_N2 + 1;
    for (int i = 0; i < SP_N2; i++) ys[i] = y[i];
    ys[SP_N2] = 0.0;
    rhs_jac(ys, p, f, J);
    for (int i = 0; i < SP_N2; i++) out[i] = f[i];
    for (int c = 0; c < SP_N2; c++)
        for (int r = 0; r < SP_NQ; r++) Jt[c][r] = J[(SP_NQ + r) * w + c];
    for (int j = 0; j < k; j++) {
        const double *v = y + SP_N2 + SP_N2 * j;
        double *o = out + SP_N2 + SP_N2 * j, acc[SP_NQ];
        for (int r = 0; r < SP_NQ; r++) o[r] = v[SP_NQ + r];
        for (int r = 0; r < SP_NQ; r++) acc[r] = Jt[0][r] * v[0];
#pragma GCC unroll 64
        for (int c = 1; c < SP_N2; c++)
            for (int r = 0; r < SP_NQ; r++) acc[r] += Jt[c][r] * v[c];
        for (int r = 0; r < SP_NQ; r++) o[SP_NQ + r] = acc[r];
    }
}

/* Gram-Schmidt QR of the k tangent vectors (modified, with a second pass -- "twice is enough"):
 * v_j <- q_j, logs[j] <- log r_jj.  0 if a vector vanished or is non-finite. */
static int lyap_qr(double *y, int k, double *logs)
{
    for (int j = 0; j < k; j++) {
        double *v = y + SP_N2 + SP_N2 * j;
        for (int pass = 0; pass < 2; pass++) {
            for (int i = 0; i < j; i++) {
                const double *q = y + SP_N2 + SP_N2 * i;
                double d = q[0] * v[0];
                for (int r = 1; r < SP_N2; r++) d += q[r] * v[r];
                for (int r = 0; r < SP_N2; r++) v[r] -= d * q[r];
            }
        }
        double nrm2 = v[0] * v[0];
        for (int r = 1; r < SP_N2; r++) nrm2 += v[r] * v[r];
        double nrm = sqrt(nrm2);
        if (!(nrm > 0.0) || !isfinite(nrm)) return 0;
        for (int r = 0; r < SP_N2; r++) v[r] /= nrm;
        logs[j] = log(nrm);
    }
    return 1;
}

typedef struct {
    double t;              /* current time */
    double h;              /* next step size (<= 0: choose automatically) */
    double t0;             /* renormalisations at t0 + j every, j = 1, 2, ... */
    double every;
    double y[SP_VMAX];     /* state and tangent vectors */
    double f[SP_VMAX];     /* their derivative (first same as last) */
    int64_t nfev, naccept, nreject, nrenorm;
    int32_t k, have_f, pad0, pad1;
} sp_lyap_state;

int64_t sp_lyap_state_size(void) { return (int64_t)sizeof(sp_lyap_state); }

/* F at the start of a resumable variational run (once): 0 if the state or F is not finite */
static int var_start(sp_lyap_state *s, const double *p, int n)
{
    if (s->have_f) return 1;
    if (!all_finite(s->y, n)) return 0;
    var_rhs(n, s->y, p, s->f);
    s->nfev++;
    if (!all_finite(s->f, n)) return 0;
    s->have_f = 1;
    return 1;
}

/* Benettin's method: the state and s->k tangent vectors (1..4) by adaptive DOP853 -- error
 * control on every component, rtol/atol as in sp_dop853 -- stepping exactly onto the
 * renormalisation times t0 + j every (and t_end), where the tangent vectors are replaced by the
 * Q of their QR decomposition and a row (t, log r_11, ..., log r_kk) is written (k + 1 doubles).
 * Returns SP_STATUS_SUCCESS (reached t_end), _NONFINITE, _STEP_UNDERFLOW, _MAX_STEPS, SP_CALL_BUDGET
 * (budget of accepted steps used up: call again), _BUFFER_FULL (rows full: take them and call
 * again) or _BAD_ARGUMENTS. */
int sp_lyap(sp_lyap_state *s, const double *p, double t_end, double rtol, double atol, int64_t max_steps,
            int64_t budget, double *rows, int64_t cap, int64_t *m_out)
{
    const int k = s->k, n = SP_N2 + SP_N2 * k;
    double K[DOP_NSTAGES][SP_VMAX], ynew[SP_VMAX], ytmp[SP_VMAX];
    int64_t m = 0, done = 0;
    *m_out = 0;
    if (k < 1 || k > SP_N2 || cap < 1 || !(s->every > 0.0)) return SP_CALL_BAD_ARGUMENTS;
    if (!var_start(s, p, n)) return SP_STATUS_NONFINITE;
    for (;;) {
        double t_next = s->t0 + (double)(s->nrenorm + 1) * s->every;
        if (t_next > t_end) t_next = t_end;
        if (s->t >= t_next) {
            if (m >= cap) { *m_out = m; return SP_CALL_BUFFER_FULL; }
            double *r = rows + m * (k + 1);
            r[0] = s->t;
            if (!lyap_qr(s->y, k, r + 1)) { *m_out = m; return SP_STATUS_NONFINITE; }
            m++;
            s->nrenorm++;
            var_rhs(n, s->y, p, s->f); /* the tangent part of F changed with the vectors */
            s->nfev++;
            if (s->t >= t_end) { *m_out = m; return SP_STATUS_SUCCESS; }
            continue;
        }
        if (done >= budget) { *m_out = m; return SP_CALL_BUDGET; }
        if (s->h <= 0.0) s->h = dop_initial_step_v(s->y, s->f, p, t_next - s->t, rtol, atol, &s->nfev, n);
        const double hprop = s->h;
        double h, t_new;
        int rc = dop_advance_v(s->t, s->y, s->f, p, t_next, rtol, atol, max_steps, &s->h, s->naccept, &s->nreject,
                               &s->nfev, K, ynew, ytmp, n, &t_new, &h);
        if (rc) { *m_out = m; return rc; }
        /* a step cut short to land on a renormalisation time does not shrink the next one */
        if (t_new == t_next && h < hprop && s->h >= h) s->h = fmax(s->h, hprop);
        s->naccept++;
        done++;
        s->t = t_new;
        memcpy(s->y, ynew, (size_t)n * sizeof(double));
        memcpy(s->f, K[DOP_NS], (size_t)n * sizeof(double));
    }
}

/* The flow and its derivative: the state and s->k tangent vectors (1..4) integrated together
 * from s->t to t_end by adaptive DOP853 (error control on every component, as sp_lyap) with no
 * renormalisation, so that starting from the identity the tangent vectors end as the columns of
 * the state-transition matrix d y(t_end) / d y(s->t) -- over one period, the monodromy matrix.
 * Resumable like sp_lyap: SP_STATUS_SUCCESS (reached t_end), _NONFINITE, _STEP_UNDERFLOW,
 * _MAX_STEPS, SP_CALL_BUDGET (call again) or _BAD_ARGUMENTS. */
int sp_flow(sp_lyap_state *s, const double *p, double t_end, double rtol, double atol, int64_t max_steps,
            int64_t budget)
{
    const int k = s->k, n = SP_N2 + SP_N2 * k;
    double K[DOP_NSTAGES][SP_VMAX], ynew[SP_VMAX], ytmp[SP_VMAX];
    int64_t done = 0;
    if (k < 1 || k > SP_N2 || !(t_end >= s->t)) return SP_CALL_BAD_ARGUMENTS;
    if (!var_start(s, p, n)) return SP_STATUS_NONFINITE;
    while (s->t < t_end) {
        if (done >= budget) return SP_CALL_BUDGET;
        if (s->h <= 0.0) s->h = dop_initial_step_v(s->y, s->f, p, t_end - s->t, rtol, atol, &s->nfev, n);
        double h, t_new;
        int rc = dop_advance_v(s->t, s->y, s->f, p, t_end, rtol, atol, max_steps, &s->h, s->naccept, &s->nreject,
                               &s->nfev, K, ynew, ytmp, n, &t_new, &h);
        if (rc) return rc;
        s->naccept++;
        done++;
        s->t = t_new;
        memcpy(s->y, ynew, (size_t)n * sizeof(double));
        memcpy(s->f, K[DOP_NS], (size_t)n * sizeof(double));
    }
    return SP_STATUS_SUCCESS;
}

/* The largest exponent of m starts y0s[m][N2] (rows of N2 doubles): one tangent vector from
 * (1, ..., 1)/sqrt(N2) ((1, 1, 1, 1)/2 for the double pendulum), renormalised every `every` seconds up to t_end; the growth after the first
 * n_skip renormalisations (the transient) divided by the time it covers.  out_lambda[i] is
 * NaN, and status[i] the failure code (1..3), when a trajectory fails; steps[i] counts its
 * accepted steps, rejected[i] its rejected ones. */
void sp_lyap1_many(const double *p, const double *y0s, int64_t m, double t_end, double every, int64_t n_skip,
                   double rtol, double atol, int64_t max_steps, double *out_lambda, int32_t *status, int64_t *steps,
                   int64_t *rejected)
{
    double rows[64 * 2];
    for (int64_t i = 0; i < m; i++) {
        sp_lyap_state s;
        memset(&s, 0, sizeof s);
        s.k = 1;
        s.every = every;
        for (int r = 0; r < SP_N2; r++) s.y[r] = y0s[SP_N2 * i + r];
        for (int r = 0; r < SP_N2; r++) s.y[SP_N2 + r] = 1.0 / sqrt((double)SP_N2);
        double sum = 0.0, t_from = 0.0;
        int64_t seen = 0;
        int rc;
        do {
            int64_t got = 0;
            rc = sp_lyap(&s, p, t_end, rtol, atol, max_steps, INT64_MAX, rows, 64, &got);
            for (int64_t j = 0; j < got; j++, seen++) {
                if (seen >= n_skip) sum += rows[2 * j + 1];
                else t_from = rows[2 * j];
            }
        } while (rc == SP_CALL_BUFFER_FULL);
        status[i] = rc;
        steps[i] = s.naccept;
        rejected[i] = s.nreject;
        out_lambda[i] = (rc == SP_STATUS_SUCCESS && t_end > t_from) ? sum / (t_end - t_from) : NAN;
    }
}

/* ---- Poincare sections: crossings of y[coord] = level (mod period); two-dimensional by definition:
 * the double pendulum's only ---- */
#if SP_NQ == 2

/* Hénon's trick: from y (the start of the step that crossed) integrate with the crossing
 * coordinate as the independent variable, d(t, y)/dy_c = (1, F(y)) / F_c(y), from y[coord] to
 * `target` by classical Runge-Kutta in substeps of at most 5e-4 (at least 16): the state on the
 * section, found without the dense output.  0 if y_c is not monotonic on the way (F_c vanishes or
 * changes sign at a stage: y_c cannot serve as the independent variable) or the state becomes
 * non-finite. */
static int henon_locate(double t, const double *y, const double *p, int coord, double target, double *t_out,
                        double *y_out)
{
    double z[5], k[4][5], tmp[5], f[8];
    const double span = target - y[coord];
    int nsub = (int)ceil(fabs(span) / 5e-4);
    if (nsub < 16) nsub = 16;
    const double dq = span / nsub;
    z[0] = t;
    for (int i = 0; i < 4; i++) z[1 + i] = y[i];
    for (int step = 0; step < nsub; step++) {
        for (int st = 0; st < 4; st++) {
            const double c = st == 0 ? 0.0 : (st == 3 ? 1.0 : 0.5);
            for (int i = 0; i < 5; i++) tmp[i] = z[i] + (st == 0 ? 0.0 : c * dq * k[st - 1][i]);
            rhs(tmp + 1, p, f);
            const double inv = 1.0 / f[coord];
            if (!isfinite(inv) || (f[coord] > 0.0) != (span > 0.0)) return 0; /* not monotonic: no parametrisation */
            k[st][0] = inv;
            for (int i = 0; i < 4; i++) k[st][1 + i] = f[i] * inv;
        }
        for (int i = 0; i < 5; i++) z[i] += dq / 6.0 * (k[0][i] + 2.0 * (k[1][i] + k[2][i]) + k[3][i]);
    }
    *t_out = z[0];
    for (int i = 0; i < 4; i++) y_out[i] = z[1 + i];
    y_out[coord] = target;
    return all_finite(z, 5);
}

#define SP_SCAN 16

/* The first crossing of y_c = target by the step's interpolant in the direction of the sign of
 * `up` (+1 increasing, -1 decreasing): the interpolant is sampled at SP_SCAN equal subintervals of
 * [0, 1] and the first bracket with that sign change refined by Illinois regula falsi (a bisection
 * step when it stalls) until |g| <= 1e-15 max(1, |target|) or the bracket is below 1e-16.
 * 0 if the interpolant is non-finite or has no such bracket. */
static int dense_locate(const double *yold, const double *F, int coord, double target, double up,
                        double *x_out, double *y_out)
{
    double a = 0.0, b = 1.0, ga = yold[coord] - target, gb = 0.0, x = 0.5;
    int found = 0;
    for (int i = 1; i <= SP_SCAN; i++) {
        double xi = (double)i / SP_SCAN;
        if (!dop_dense_eval(yold, F, xi, y_out, 4)) return 0;
        double gi = y_out[coord] - target;
        if ((up > 0.0 && ga < 0.0 && gi >= 0.0) || (up < 0.0 && ga > 0.0 && gi <= 0.0)) {
            b = xi; gb = gi; found = 1;
            break;
        }
        a = xi; ga = gi;
    }
    if (!found) return 0;
    if (gb == 0.0) { *x_out = b; return dop_dense_eval(yold, F, b, y_out, 4); }
    int side = 0;
    const double tol = 1e-15 * fmax(1.0, fabs(target));
    for (int it = 0; it < 200; it++) {
        x = (it % 4 == 3) ? 0.5 * (a + b) : (a * gb - b * ga) / (gb - ga);
        if (!(x > a && x < b)) x = 0.5 * (a + b);
        if (!dop_dense_eval(yold, F, x, y_out, 4)) return 0;
        double g = y_out[coord] - target;
        if (fabs(g) <= tol || b - a < 1e-16) break;
        if ((g < 0.0) == (ga < 0.0)) {
            a = x; ga = g;
            if (side == -1) gb *= 0.5;
            side = -1;
        } else {
            b = x; gb = g;
            if (side == 1) ga *= 0.5;
            side = 1;
        }
    }
    *x_out = x;
    return 1;
}

/* Integrate the state (4 components of s->y) by DOP853 from s->t until `want` crossings of the
 * section y[coord] = level + j period (any integer j when period > 0; period <= 0: the level
 * alone) in the given direction (+1: increasing, -1: decreasing, 0: both) have been found, or
 * until t_end.  Each crossing is located on the step that made it, by the 7th-order dense output
 * and root finding (method 0) or by Hénon's trick (method 1; where the section coordinate is not
 * monotonic over the step, the dense output instead, counted in s->aux), and written as a row
 * (t, y[0..3]); y[coord] is written as the exact section value.  At most one crossing per step
 * (the first in the direction wanted).  s->step counts the crossings found.  A start
 * on the section is not a crossing.  Returns SP_STATUS_SUCCESS (want crossings found),
 * SP_STATUS_SHORT (t_end reached first), the failures and SP_CALL_* codes of sp_dop853. */
int sp_section(sp_state *s, const double *p, int coord, double level, double period, int direction, int method,
               int64_t want, double t_end, double rtol, double atol, int64_t max_steps, int64_t budget, double *rows,
               int64_t cap, int64_t *m_out)
{
    const int n = 4;
    double K[DOP_NSTAGES][SP_NMAX], ynew[SP_NMAX], ytmp[SP_NMAX], yc[SP_NMAX];
    int64_t m = 0, done = 0;
    *m_out = 0;
    if (coord < 0 || coord > 3 || cap < 1 || (method != 0 && method != 1)) return SP_CALL_BAD_ARGUMENTS;
    if (!s->have_f) {
        if (!all_finite(s->y, n)) return SP_STATUS_NONFINITE;
        s->y[4] = 0.0;
        rhs(s->y, p, s->f);
        s->nfev++;
        if (!all_finite(s->f, n)) return SP_STATUS_NONFINITE;
        s->have_f = 1;
    }
    for (;;) {
        if (s->step >= want) { *m_out = m; return SP_STATUS_SUCCESS; }
        if (s->t >= t_end) { *m_out = m; return SP_STATUS_SHORT; }
        if (done >= budget) { *m_out = m; return SP_CALL_BUDGET; }
        if (m >= cap) { *m_out = m; return SP_CALL_BUFFER_FULL; }
        if (s->h <= 0.0) s->h = dop_initial_step(s->y, s->f, p, t_end - s->t, rtol, atol, &s->nfev, n);
        double h, t_new;
        int rc = dop_advance(s->t, s->y, s->f, p, t_end, rtol, atol, max_steps, &s->h, s->naccept, &s->nreject,
                             &s->nfev, K, ynew, ytmp, n, &t_new, &h);
        if (rc) { *m_out = m; return rc; }
        s->naccept++;
        done++;
        /* the section level crossed by this step, if any */
        double u0 = s->y[coord] - level, u1 = ynew[coord] - level, target = NAN;
        if (period > 0.0) {
            double j0 = floor(u0 / period), j1 = floor(u1 / period);
            if (j1 > j0 && direction >= 0) target = level + j1 * period;
            else if (j1 < j0 && direction <= 0) target = level + j0 * period;
        } else {
            if (u0 < 0.0 && u1 >= 0.0 && direction >= 0) target = level;
            else if (u0 > 0.0 && u1 <= 0.0 && direction <= 0) target = level;
        }
        if (!isnan(target) && s->y[coord] != target) {
            double tc;
            int ok;
            const double up = ynew[coord] > s->y[coord] ? 1.0 : -1.0;
            ok = method == 1 && henon_locate(s->t, s->y, p, coord, target, &tc, yc);
            if (method == 1 && !ok) s->aux++; /* Hénon impossible on this step: the dense output instead */
            if (!ok) {
                double x;
                dop_dense_coeffs(s->y, ynew, h, p, K, s->F, ytmp, n);
                s->nfev += DOP_NSTAGES - DOP_NS - 1;
                ok = dense_locate(s->y, s->F, coord, target, up, &x, yc);
                tc = s->t + x * h;
                yc[coord] = target;
            }
            if (!ok) { *m_out = m; return SP_STATUS_NONFINITE; }
            put_row(rows, m++, n, tc, yc);
            s->step++;
        }
        s->t = t_new;
        memcpy(s->y, ynew, (size_t)n * sizeof(double));
        memcpy(s->f, K[DOP_NS], (size_t)n * sizeof(double));
    }
}
#endif /* SP_NQ == 2 */
