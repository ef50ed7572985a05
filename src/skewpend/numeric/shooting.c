/* ---- multiple shooting's integrator: RK4 with the exact derivative of its own map ----
 *
 * Appended to a kernel built with the parameter sensitivities (kernel_source.sensitivity_c_source:
 * rhs_sens, and the defines SP_NQ, SP_NPARAM, SP_TAU_INDEX).  Model-independent: the coordinates
 * are SP_NQ, the state y = (q, q') of 2 SP_NQ entries.
 *
 * Each of nseg segments starts from its own state y0[s] and is integrated by the classical RK4 at the
 * fixed step h for L steps.  The torques are inputs: tau[s][m][j], m = 0 .. 2L, at the steps (even m)
 * and half steps (odd m), added to p's constant torques (SP_TAU_INDEX); NULL: none.  With J given, the
 * variational equations are integrated with the state in the same stages,
 *
 *     Z' = d(y')/dy Z + [0 | d(y')/dp G],   Z(0) = [I | 0],
 *
 * Z the 2 SP_NQ x (2 SP_NQ + k) derivative of the state in its start values and in k parameters theta,
 * G = dp/dtheta (SP_NPARAM x k, row-major) their chain rule into p: RK4 applied to (y, Z) at once is
 * the exact derivative of the discrete map, so the Jacobian of a fit's residuals is exact for the
 * model fitted.  Output: q[s][i][j] the coordinates at step i = 0 .. L; J[s][i][j][c] their rows of Z.
 * A segment whose values are not finite runs on (the caller's cost is then not finite).
 * Returns SP_STATUS_SUCCESS, or SP_CALL_BAD_ARGUMENTS for k outside 0 .. SP_SHOOT_KMAX. */

#define SP_SHOOT_N (2 * SP_NQ)
#define SP_SHOOT_KMAX 64
#define SP_SHOOT_W (SP_SHOOT_N + SP_SHOOT_KMAX)

/* y' and Z' at (y, Z) with torques u (SP_NQ entries) added to p */
static void shoot_stage(const double *p, const double *G, int k, const double *y, const double *Z,
                        const double *u, double *dy, double *dZ)
{
    static const int tau_index[SP_NQ] = SP_TAU_INDEX;
    double pl[SP_NPARAM], acc[SP_NQ], A[SP_NQ * SP_SHOOT_N], B[SP_NQ * SP_NPARAM];
    const int w = SP_SHOOT_N + k;
    for (int i = 0; i < SP_NPARAM; i++) pl[i] = p[i];
    if (u)
        for (int j = 0; j < SP_NQ; j++) pl[tau_index[j]] += u[j];
    if (!Z) { /* the state alone: the model's right-hand side (its last entry, the work, unused) */
        double ya[SP_SHOOT_N + 1], out[SP_SHOOT_N + 1];
        for (int i = 0; i < SP_SHOOT_N; i++) ya[i] = y[i];
        ya[SP_SHOOT_N] = 0.0;
        rhs(ya, pl, out);
        for (int i = 0; i < SP_SHOOT_N; i++) dy[i] = out[i];
        return;
    }
    rhs_sens(y, pl, acc, A, B);
    for (int j = 0; j < SP_NQ; j++) {
        dy[j] = y[SP_NQ + j];
        dy[SP_NQ + j] = acc[j];
    }
    for (int j = 0; j < SP_NQ; j++) /* (q)' = q' */
        for (int c = 0; c < w; c++) dZ[j * w + c] = Z[(SP_NQ + j) * w + c];
    for (int j = 0; j < SP_NQ; j++) { /* (q')' = A Z + [0 | B G] */
        double *row = dZ + (SP_NQ + j) * w;
        for (int c = 0; c < w; c++) {
            double v = 0.0;
            for (int r = 0; r < SP_SHOOT_N; r++) v += A[j * SP_SHOOT_N + r] * Z[r * w + c];
            row[c] = v;
        }
        for (int c = 0; c < k; c++) {
            double v = 0.0;
            for (int r = 0; r < SP_NPARAM; r++) v += B[j * SP_NPARAM + r] * G[r * k + c];
            row[SP_SHOOT_N + c] += v;
        }
    }
}

int sp_shoot(const double *p, const double *G, int64_t k, int64_t nseg, int64_t L, double h, const double *y0,
             const double *tau, double *q, double *J)
{
    if (k < 0 || k > SP_SHOOT_KMAX || L < 0 || nseg < 0) return SP_CALL_BAD_ARGUMENTS;
    const int n = SP_SHOOT_N, w = SP_SHOOT_N + (int)k, nz = n * w;
    const int sens = J != 0;
    double y[SP_SHOOT_N], yt[SP_SHOOT_N], k1[SP_SHOOT_N], k2[SP_SHOOT_N], k3[SP_SHOOT_N], k4[SP_SHOOT_N];
    double Z[SP_SHOOT_N * SP_SHOOT_W], Zt[SP_SHOOT_N * SP_SHOOT_W];
    double K1[SP_SHOOT_N * SP_SHOOT_W], K2[SP_SHOOT_N * SP_SHOOT_W], K3[SP_SHOOT_N * SP_SHOOT_W],
        K4[SP_SHOOT_N * SP_SHOOT_W];
    const double half = 0.5 * h, sixth = h / 6.0;
    for (int64_t s = 0; s < nseg; s++) {
        const double *us = tau ? tau + s * (2 * L + 1) * SP_NQ : 0;
        double *qs = q + s * (L + 1) * SP_NQ;
        double *Js = sens ? J + s * (L + 1) * SP_NQ * w : 0;
        for (int i = 0; i < n; i++) y[i] = y0[s * n + i];
        if (sens)
            for (int r = 0; r < n; r++)
                for (int c = 0; c < w; c++) Z[r * w + c] = (r == c) ? 1.0 : 0.0;
        for (int64_t i = 0; i <= L; i++) {
            for (int j = 0; j < SP_NQ; j++) qs[i * SP_NQ + j] = y[j];
            if (sens)
                for (int j = 0; j < SP_NQ; j++)
                    for (int c = 0; c < w; c++) Js[(i * SP_NQ + j) * w + c] = Z[j * w + c];
            if (i == L) break;
            const double *u0 = us ? us + (2 * i) * SP_NQ : 0, *u1 = us ? us + (2 * i + 1) * SP_NQ : 0,
                         *u2 = us ? us + (2 * i + 2) * SP_NQ : 0;
            double *Zp = sens ? Z : 0, *Ztp = sens ? Zt : 0;
            shoot_stage(p, G, (int)k, y, Zp, u0, k1, K1);
            for (int r = 0; r < n; r++) yt[r] = y[r] + half * k1[r];
            if (sens)
                for (int r = 0; r < nz; r++) Zt[r] = Z[r] + half * K1[r];
            shoot_stage(p, G, (int)k, yt, Ztp, u1, k2, K2);
            for (int r = 0; r < n; r++) yt[r] = y[r] + half * k2[r];
            if (sens)
                for (int r = 0; r < nz; r++) Zt[r] = Z[r] + half * K2[r];
            shoot_stage(p, G, (int)k, yt, Ztp, u1, k3, K3);
            for (int r = 0; r < n; r++) yt[r] = y[r] + h * k3[r];
            if (sens)
                for (int r = 0; r < nz; r++) Zt[r] = Z[r] + h * K3[r];
            shoot_stage(p, G, (int)k, yt, Ztp, u2, k4, K4);
            for (int r = 0; r < n; r++) y[r] = y[r] + sixth * (((k1[r] + 2.0 * k2[r]) + 2.0 * k3[r]) + k4[r]);
            if (sens)
                for (int r = 0; r < nz; r++) Z[r] = Z[r] + sixth * (((K1[r] + 2.0 * K2[r]) + 2.0 * K3[r]) + K4[r]);
        }
    }
    return SP_STATUS_SUCCESS;
}
