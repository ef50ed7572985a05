/* spd_solve.h -- the one linear solve of skewpend's kernels: M x = b for a symmetric positive-definite
 * n x n matrix M (the mass matrix), by its LDL^T factorisation (no square roots; one reciprocal per pivot).
 *
 * Used by every generated kernel (kernel_source.py: the right-hand side, its Jacobian, Hamilton's
 * equations, the flip map's and the regions of attraction's SIMD lanes) and by the Taylor series
 * (taylor_source.py: factored once a step, the factors reused at every order).  The standalone Python,
 * C and JavaScript exports print the same steps in the same order (codegen.ldlt_steps; a test checks
 * that the two give the same bits).
 *
 * M is passed as its packed lower triangle, row by row: M11, M21, M22, M31, M32, M33, ... (entry (i, j),
 * j <= i, zero-based, at SP_SPD_IDX(i, j)); for n = 2 that is {M11, M12, M22}.  The factorisation
 * overwrites it with L below the diagonal (unit diagonal, not stored) and 1/D on the diagonal.
 *
 * The size n is an argument: called with a constant n (as every generated kernel does) the functions
 * are inlined and their loops unrolled completely (the pragmas), so the solve is straight-line code --
 * in the flip kernel's loop over SIMD lanes the compiler vectorises it with the rest (checked with
 * -fopt-info-vec).  For n = 2 (every kernel of the double pendulum) the two pivots share one
 * reciprocal: dd = M11 M22 - M21^2 (= D1 D2), w = 1/(M11 dd), r1 = dd w (= 1/D1), r2 = M11^2 w (= 1/D2),
 *     l = M21 r1,  x2 = (b2 - l b1) r2,  x1 = b1 r1 - l x2.
 * The kernels are compiled without floating-point contraction; SP_SPD_FMA(a, b, c) = a b + c may be
 * defined before the inclusion to fuse the products (the Taylor kernels do where the processor has fma).
 */
#ifndef SKEWPEND_SPD_SOLVE_H
#define SKEWPEND_SPD_SOLVE_H

#ifndef SP_SPD_FMA
#define SP_SPD_FMA(a, b, c) ((a) * (b) + (c))
#endif
/* the largest n (the scratch row of the factorisation) */
#ifndef SP_SPD_NMAX
#define SP_SPD_NMAX 16
#endif
#define SP_SPD_IDX(i, j) ((i) * ((i) + 1) / 2 + (j))
#define SP_SPD_PACKED(n) ((n) * ((n) + 1) / 2)

/* M = L D L^T in place (a: the packed lower triangle of M -> L below the diagonal, 1/D on it).
 * M positive definite: every pivot D > 0 (not checked: a kernel's mass matrix is, and a NaN or an
 * infinity from a singular one reaches the integrator's finiteness checks). */
static inline __attribute__((always_inline)) void sp_ldlt_factor(int n, double *restrict a)
{
    if (n == 2) { /* one reciprocal for both pivots (a division costs several products; the kernels' case):
                   * D1 D2 = M11 M22 - M21^2, w = 1/(D1 D1 D2), 1/D1 = D1 D2 w, 1/D2 = D1^2 w */
        const double dd = SP_SPD_FMA(-a[1], a[1], a[0] * a[2]);
        const double w = 1.0 / (a[0] * dd);
        const double r1 = dd * w;
        a[2] = a[0] * a[0] * w;
        a[1] = a[1] * r1;
        a[0] = r1;
        return;
    }
    double w[SP_SPD_NMAX]; /* row i of L times D: w[j] = L[i][j] D[j] */
#pragma GCC unroll 16
    for (int i = 0; i < n; i++) {
#pragma GCC unroll 16
        for (int j = 0; j < i; j++) {
            double u = a[SP_SPD_IDX(i, j)];
#pragma GCC unroll 16
            for (int k = 0; k < j; k++) u = SP_SPD_FMA(-w[k], a[SP_SPD_IDX(j, k)], u);
            w[j] = u;
            a[SP_SPD_IDX(i, j)] = u * a[SP_SPD_IDX(j, j)];
        }
        double d = a[SP_SPD_IDX(i, i)];
#pragma GCC unroll 16
        for (int k = 0; k < i; k++) d = SP_SPD_FMA(-w[k], a[SP_SPD_IDX(i, k)], d);
        a[SP_SPD_IDX(i, i)] = 1.0 / d;
    }
}

/* M x = b with the factors of sp_ldlt_factor: b is overwritten by x */
static inline __attribute__((always_inline)) void sp_ldlt_solve(int n, const double *restrict a, double *restrict b)
{
#pragma GCC unroll 16
    for (int i = 1; i < n; i++) { /* L z = b */
#pragma GCC unroll 16
        for (int k = 0; k < i; k++) b[i] = SP_SPD_FMA(-a[SP_SPD_IDX(i, k)], b[k], b[i]);
    }
#pragma GCC unroll 16
    for (int i = 0; i < n; i++) b[i] *= a[SP_SPD_IDX(i, i)]; /* D y = z */
#pragma GCC unroll 16
    for (int i = n - 2; i >= 0; i--) { /* L^T x = y */
#pragma GCC unroll 16
        for (int k = i + 1; k < n; k++) b[i] = SP_SPD_FMA(-a[SP_SPD_IDX(k, i)], b[k], b[i]);
    }
}

/* M^-1 from the factors of sp_ldlt_factor, as a packed lower triangle into inv (column j: the solve of
 * M x = e_j, its rows from j on; no scratch memory).  For one matrix applied to many right-hand sides one after another, where each product
 * sp_spd_mul is a shorter chain of dependent operations than the substitutions (the Taylor series:
 * M[0] factored once a step, its inverse applied at every order). */
static inline __attribute__((always_inline)) void sp_ldlt_inverse(int n, const double *restrict a, double *restrict inv)
{
#pragma GCC unroll 16
    for (int j = 0; j < n; j++) { /* column j, rows j .. n - 1 (M^-1 is symmetric), in place */
        inv[SP_SPD_IDX(j, j)] = 1.0; /* L z = e_j: z_i = 0 above j */
#pragma GCC unroll 16
        for (int i = j + 1; i < n; i++) {
            double z = -a[SP_SPD_IDX(i, j)];
#pragma GCC unroll 16
            for (int k = j + 1; k < i; k++) z = SP_SPD_FMA(-a[SP_SPD_IDX(i, k)], inv[SP_SPD_IDX(k, j)], z);
            inv[SP_SPD_IDX(i, j)] = z;
        }
#pragma GCC unroll 16
        for (int i = j; i < n; i++) inv[SP_SPD_IDX(i, j)] *= a[SP_SPD_IDX(i, i)]; /* D y = z */
#pragma GCC unroll 16
        for (int i = n - 2; i >= j; i--) { /* L^T x = y, the rows from j on */
#pragma GCC unroll 16
            for (int k = i + 1; k < n; k++)
                inv[SP_SPD_IDX(i, j)] = SP_SPD_FMA(-a[SP_SPD_IDX(k, i)], inv[SP_SPD_IDX(k, j)], inv[SP_SPD_IDX(i, j)]);
        }
    }
}

/* x = S b for a symmetric S given as its packed lower triangle (such as sp_ldlt_inverse's):
 * x_i = S_i1 b_1 + (S_i2 b_2 + (... + S_in b_n)) */
static inline __attribute__((always_inline)) void sp_spd_mul(int n, const double *restrict s, const double *restrict b,
                                                             double *restrict x)
{
#pragma GCC unroll 16
    for (int i = 0; i < n; i++) {
        double acc = s[SP_SPD_IDX(n - 1, i)] * b[n - 1]; /* n - 1 >= i */
#pragma GCC unroll 16
        for (int j = n - 2; j >= 0; j--) acc = SP_SPD_FMA(s[i >= j ? SP_SPD_IDX(i, j) : SP_SPD_IDX(j, i)], b[j], acc);
        x[i] = acc;
    }
}

/* M x = b in one call (a is overwritten by the factors, b by x) */
static inline __attribute__((always_inline)) void sp_spd_solve(int n, double *restrict a, double *restrict b)
{
    sp_ldlt_factor(n, a);
    sp_ldlt_solve(n, a, b);
}

#endif /* SKEWPEND_SPD_SOLVE_H */
