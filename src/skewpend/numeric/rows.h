/* skewpend: helpers shared by the integrators (integrators.c) and the Taylor driver (taylor.c): a
 * state's finiteness, and one output row (t, y[0..n-1]) at index m of a row-major table. */
#ifndef SKEWPEND_ROWS_H
#define SKEWPEND_ROWS_H

#include <math.h>
#include <stdint.h>
#include <string.h>

static int all_finite(const double *x, int n)
{
    for (int i = 0; i < n; i++)
        if (!isfinite(x[i])) return 0;
    return 1;
}

static void put_row(double *rows, int64_t m, int n, double t, const double *y)
{
    double *r = rows + m * (n + 1);
    r[0] = t;
    memcpy(r + 1, y, (size_t)n * sizeof(double));
}

#endif
