/* The DOP853 core -- one step with error control, the error norm, the dense output and the initial
 * step -- generic in the state size n (a run-time argument), written once and included once per
 * instance (integrators.c: the plain systems; chaos.c: the variational ones).  The includer defines
 *
 *     DOP_NAME(x)          the name of this instance's function x (x, or x##_v)
 *     DOP_NDIM             the array size of a state (SP_NMAX, SP_VMAX)
 *     DOP_RHS(y, p, out)   the right-hand side y' = F(y; p) (the state size n is in scope)
 *
 * and has the tables DOP_*, their dimension-free helpers dop_* (integrators.c), all_finite and
 * the SP_STATUS_* codes in scope.  They are undefined at
 * the end, so the next instance defines its own.  No include guard: included once per instance.
 */

/* the stages K[first..last-1] from y, given the earlier ones */
static void DOP_NAME(dop_stages)(const double *y, double h, const double *p, double K[][DOP_NDIM], double *ytmp, int n, int first,
                       int last)
{
    for (int s = first; s < last; s++) {
        for (int i = 0; i < n; i++) {
            double acc = 0.0;
            for (int j = 0; j < s; j++) acc += DOP_A[s][j] * K[j][i];
            ytmp[i] = y[i] + h * acc;
        }
        DOP_RHS(ytmp, p, K[s]);
    }
}

/* one step from y with K[0] = F(y): stages K[1..12] and ynew */
static void DOP_NAME(dop_step)(const double *y, double h, const double *p, double K[][DOP_NDIM], double *ynew, double *ytmp, int n)
{
    DOP_NAME(dop_stages)(y, h, p, K, ytmp, n, 1, DOP_NS);
    for (int i = 0; i < n; i++) {
        double acc = 0.0;
        for (int j = 0; j < DOP_NS; j++) acc += DOP_A[DOP_NS][j] * K[j][i];
        ynew[i] = y[i] + h * acc;
    }
    DOP_RHS(ynew, p, K[DOP_NS]);
}

/* Hairer's combined 5th/3rd-order error norm (inf if anything is non-finite) */
static double DOP_NAME(dop_error)(double K[][DOP_NDIM], double h, const double *y, const double *ynew, double rtol, double atol, int n)
{
    double e5 = 0.0, e3 = 0.0;
    for (int i = 0; i < n; i++) {
        double sc = atol + rtol * fmax(fabs(y[i]), fabs(ynew[i]));
        double a5 = 0.0, a3 = 0.0;
        for (int j = 0; j < DOP_NS + 1; j++) {
            a5 += DOP_E5[j] * K[j][i];
            a3 += DOP_E3[j] * K[j][i];
        }
        a5 /= sc;
        a3 /= sc;
        e5 += a5 * a5;
        e3 += a3 * a3;
    }
    if (!(isfinite(e5) && isfinite(e3))) return INFINITY;
    if (e5 == 0.0 && e3 == 0.0) return 0.0;
    return fabs(h) * e5 / sqrt((e5 + 0.01 * e3) * n);
}

/* the 3 extra stages and the 7 coefficient rows F of the 7th-order interpolant */
static void DOP_NAME(dop_dense_coeffs)(const double *y, const double *ynew, double h, const double *p, double K[][DOP_NDIM],
                             double *F, double *ytmp, int n)
{
    DOP_NAME(dop_stages)(y, h, p, K, ytmp, n, DOP_NS + 1, DOP_NSTAGES);
    for (int i = 0; i < n; i++) dop_dense_component(y[i], ynew[i], h, &K[0][i], DOP_NDIM, F + i, DOP_NDIM);
}

/* the interpolant at x = (t - told) / h in [0, 1]; 0 if non-finite */
static int DOP_NAME(dop_dense_eval)(const double *y, const double *F, double x, double *out, int n)
{
    for (int i = 0; i < n; i++) {
        out[i] = dop_dense_value(y[i], F + i, DOP_NDIM, x);
        if (!isfinite(out[i])) return 0;
    }
    return 1;
}

/* Hairer's initial step (Hairer, Norsett & Wanner I, II.4; as SciPy's select_initial_step) */
static double DOP_NAME(dop_initial_step)(const double *y, const double *f0, const double *p, double span, double rtol,
                               double atol, int64_t *nfev, int n)
{
    double sc[DOP_NDIM], ytmp[DOP_NDIM], f1[DOP_NDIM];
    for (int i = 0; i < n; i++) sc[i] = atol + fabs(y[i]) * rtol;
    const double d1 = dop_rms(f0, 1, sc, 1, n), ha = dop_trial_step(dop_rms(y, 1, sc, 1, n), d1, span);
    for (int i = 0; i < n; i++) ytmp[i] = y[i] + ha * f0[i];
    DOP_RHS(ytmp, p, f1);
    (*nfev)++;
    for (int i = 0; i < n; i++) f1[i] -= f0[i];
    return dop_first_step(ha, d1, dop_rms(f1, 1, sc, 1, n) / ha, span);
}
/* One accepted step from (t, y), F(y) = f, ending at t_stop at the latest: the step size *h is
 * tried and shrunk until the error norm is below 1 (a trial with a non-finite value is rejected
 * like a failed one, factor 0.2), and *h is set for the next step (factor 0.9 err^(-1/8) in
 * [0.2, 10], no increase right after a rejection).  On success (0) ynew, K[0..12] = the stages
 * and *t_new, *h_used describe the step.  Else 1 (non-finite state: step size underflow after a
 * non-finite trial), 2 (step size underflow) or 3 (naccept + nreject reached max_steps). */
static int DOP_NAME(dop_advance)(double t, const double *y, const double *f, const double *p, double t_stop, double rtol,
                       double atol, int64_t max_steps, double *hio, int64_t naccept, int64_t *nreject, int64_t *nfev,
                       double K[][DOP_NDIM], double *ynew, double *ytmp, int n, double *t_new_out, double *h_used)
{
    int rejected = 0, nonfinite = 0;
    memcpy(K[0], f, (size_t)n * sizeof(double));
    for (;;) {
        if (naccept + *nreject >= max_steps) return SP_STATUS_MAX_STEPS;
        double min_step = 10.0 * (nextafter(t, INFINITY) - t);
        if (*hio < min_step) return nonfinite ? SP_STATUS_NONFINITE : SP_STATUS_STEP_UNDERFLOW;
        double t_new = t + *hio;
        if (t_new >= t_stop) t_new = t_stop;
        double h = t_new - t;
        DOP_NAME(dop_step)(y, h, p, K, ynew, ytmp, n);
        *nfev += DOP_NS;
        double err = (all_finite(ynew, n) && all_finite(K[DOP_NS], n)) ? DOP_NAME(dop_error)(K, h, y, ynew, rtol, atol, n)
                                                                     : INFINITY;
        nonfinite = !isfinite(err);
        if (err < 1.0) {
            const double fac = DOP_FACTOR_ACCEPTED(err, DOP_SAFETY * pow(err, -1.0 / 8.0), rejected);
            *hio = h * fac;
            *t_new_out = t_new;
            *h_used = h;
            return SP_STATUS_SUCCESS;
        }
        const double fac = DOP_FACTOR_REJECTED(nonfinite, DOP_SAFETY * pow(err, -1.0 / 8.0));
        *hio = h * fac;
        rejected = 1;
        (*nreject)++;
    }
}

#undef DOP_NAME
#undef DOP_NDIM
#undef DOP_RHS
