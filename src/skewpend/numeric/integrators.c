/* skewpend integrator template -- appended to the generated model code.
 *
 * Contract with the code generator (skewpend.numeric.kernel_source): the text before this template defines
 *
 *     static void rhs(const double *y, const double *p, double *out);      y' = F(y; p)
 *     static void ham_rhs(const double *z, const double *p, double *out);  the same in (q, p_q)
 *     static double energy(const double *y, const double *p);              E = T + Pi (swing-up inputs)
 *     #define SP_NQ, SP_NPARAM, SP_TAU_INDEX the coordinates, the length of p and where its constant
 *                                          torques are ({i_1, ..., i_n}: one per coordinate)
 *
 * for states of at most SP_NMAX components.  Everything here is generic in the state size n.
 * The flip kernel (SP_FLIP_KERNEL defined) also has sp_flip at the end, for ensembles of starts
 * at rest, with its own contract (see there); the simulation kernel compiles without it.
 *
 * Every integrator is *resumable*: its whole state lives in an sp_state owned by the caller,
 * and one call does a bounded amount of work (at most `budget` accepted steps, at most `cap`
 * output rows) and returns.  The caller (skewpend.numeric.driver.drive) loops, takes the rows,
 * shows progress and lets Python handle Ctrl-C between calls.  Results do not depend on how
 * the work is split into calls.
 *
 * Output rows are (t, y[0..n-1]), row-major, n + 1 doubles each.  Return values: the
 * SP_STATUS_* codes (>= 0: the run is over; 0 reached the end, 1 non-finite state, 2 step size
 * underflow, 3 max_steps, 4 no convergence of the implicit stages) or the SP_CALL_* codes (< 0:
 * -1 the step budget of this call is used up, call again; -2 the row buffer is full, take the
 * rows and call again; -3 the arguments were refused -- an internal error, the callers check
 * them first).  They are #defines generated from skewpend.status (kernel_source.status_defines),
 * the one list, and driven by skewpend.numeric.driver.drive.
 * Rows are never non-finite.
 *
 * Why one file of ~880 lines: it is appended to the generated model code as one translation unit,
 * so rhs/ham_rhs and the shared static helpers (the DOP853 core of dop853_core.h, the Gauss
 * stages, the lane loops of sp_flip) are inlined across integrators; a split would need a
 * header of internal functions and a second template to keep in step with kernel_source.
 */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#ifndef SP_NQ
#define SP_NQ 2 /* coordinates: the double pendulum's 2; a chain defines its own */
#endif
#define SP_NX (2 * SP_NQ) /* the mechanical state: angles and speeds */
#define SP_NT (SP_NX + 1)  /* the time's place in the state of a run whose inputs read it (after W) */
#ifndef SP_NMAX
#define SP_NMAX 8 /* the largest state: the double pendulum's 5 (6 with a controller's clock); a chain defines its own */
#endif

typedef struct {
    double t;                 /* current time */
    double h;                 /* dop853: next step size (<= 0: choose automatically) */
    double y[SP_NMAX];        /* current state */
    double f[SP_NMAX];        /* dop853: F(y) (first same as last); gauss: first stage guess */
    double g[SP_NMAX];        /* gauss: second stage guess */
    double comp[SP_NMAX];     /* gauss: compensated-summation remainder */
    double told;              /* dop853 dense output: the last step went from told ... */
    double hseg;              /* ... over hseg */
    double yold[SP_NMAX];     /* ... starting at yold, */
    double F[7 * SP_NMAX];    /* ... with these interpolant coefficients */
    int64_t nfev, naccept, nreject, step;
    int32_t started, have_f, dense_ok, aux; /* aux: a counter of chaos.c's sp_section */
} sp_state;

int64_t sp_state_size(void) { return (int64_t)sizeof(sp_state); }

#include "rows.h" /* all_finite, put_row: shared with taylor.c */

/* ---- DOP853: Hairer's Dormand-Prince 8(5,3); coefficient tables as tabulated in SciPy ---- */
static const double DOP_C[16] = {0.0, 0.05260015195876773, 0.0789002279381516, 0.1183503419072274, 0.2816496580927726, 0.3333333333333333, 0.25, 0.3076923076923077, 0.6512820512820513, 0.6, 0.8571428571428571, 1.0, 1.0, 0.1, 0.2, 0.7777777777777778};
static const double DOP_A[16][16] = {
    {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
    {0.05260015195876773, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
    {0.0197250569845379, 0.0591751709536137, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
    {0.02958758547680685, 0.0, 0.08876275643042054, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
    {0.2413651341592667, 0.0, -0.8845494793282861, 0.924834003261792, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
    {0.037037037037037035, 0.0, 0.0, 0.17082860872947386, 0.12546768756682242, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
    {0.037109375, 0.0, 0.0, 0.17025221101954405, 0.06021653898045596, -0.017578125, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
    {0.03709200011850479, 0.0, 0.0, 0.17038392571223998, 0.10726203044637328, -0.015319437748624402, 0.008273789163814023, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
    {0.6241109587160757, 0.0, 0.0, -3.3608926294469414, -0.868219346841726, 27.59209969944671, 20.154067550477894, -43.48988418106996, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
    {0.47766253643826434, 0.0, 0.0, -2.4881146199716677, -0.590290826836843, 21.230051448181193, 15.279233632882423, -33.28821096898486, -0.020331201708508627, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
    {-0.9371424300859873, 0.0, 0.0, 5.186372428844064, 1.0914373489967295, -8.149787010746927, -18.52006565999696, 22.739487099350505, 2.4936055526796523, -3.0467644718982196, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
    {2.273310147516538, 0.0, 0.0, -10.53449546673725, -2.0008720582248625, -17.9589318631188, 27.94888452941996, -2.8589982771350235, -8.87285693353063, 12.360567175794303, 0.6433927460157636, 0.0, 0.0, 0.0, 0.0, 0.0},
    {0.054293734116568765, 0.0, 0.0, 0.0, 0.0, 4.450312892752409, 1.8915178993145003, -5.801203960010585, 0.3111643669578199, -0.1521609496625161, 0.20136540080403034, 0.04471061572777259, 0.0, 0.0, 0.0, 0.0},
    {0.056167502283047954, 0.0, 0.0, 0.0, 0.0, 0.0, 0.25350021021662483, -0.2462390374708025, -0.12419142326381637, 0.15329179827876568, 0.00820105229563469, 0.007567897660545699, -0.008298, 0.0, 0.0, 0.0},
    {0.03183464816350214, 0.0, 0.0, 0.0, 0.0, 0.028300909672366776, 0.053541988307438566, -0.05492374857139099, 0.0, 0.0, -0.00010834732869724932, 0.0003825710908356584, -0.00034046500868740456, 0.1413124436746325, 0.0, 0.0},
    {-0.42889630158379194, 0.0, 0.0, 0.0, 0.0, -4.697621415361164, 7.683421196062599, 4.06898981839711, 0.3567271874552811, 0.0, 0.0, 0.0, -0.0013990241651590145, 2.9475147891527724, -9.15095847217987, 0.0}
};
static const double DOP_E3[13] = {-0.18980075407240762, 0.0, 0.0, 0.0, 0.0, 4.450312892752409, 1.8915178993145003, -5.801203960010585, -0.4226823213237919, -0.1521609496625161, 0.20136540080403034, 0.02265179219836082, 0.0};
static const double DOP_E5[13] = {0.01312004499419488, 0.0, 0.0, 0.0, 0.0, -1.2251564463762044, -0.4957589496572502, 1.6643771824549864, -0.35032884874997366, 0.3341791187130175, 0.08192320648511571, -0.022355307863886294, 0.0};
static const double DOP_D[4][16] = {
    {-8.428938276109013, 0.0, 0.0, 0.0, 0.0, 0.5667149535193777, -3.0689499459498917, 2.38466765651207, 2.117034582445028, -0.871391583777973, 2.2404374302607883, 0.6315787787694688, -0.08899033645133331, 18.148505520854727, -9.194632392478356, -4.436036387594894},
    {10.427508642579134, 0.0, 0.0, 0.0, 0.0, 242.28349177525817, 165.20045171727028, -374.5467547226902, -22.113666853125306, 7.733432668472264, -30.674084731089398, -9.332130526430229, 15.697238121770845, -31.139403219565178, -9.35292435884448, 35.81684148639408},
    {19.985053242002433, 0.0, 0.0, 0.0, 0.0, -387.0373087493518, -189.17813819516758, 527.8081592054236, -11.57390253995963, 6.8812326946963, -1.0006050966910838, 0.7777137798053443, -2.778205752353508, -60.19669523126412, 84.32040550667716, 11.99229113618279},
    {-25.69393346270375, 0.0, 0.0, 0.0, 0.0, -154.18974869023643, -231.5293791760455, 357.6391179106141, 93.40532418362432, -37.45832313645163, 104.0996495089623, 29.8402934266605, -43.53345659001114, 96.32455395918828, -39.17726167561544, -149.72683625798564}
};

#define DOP_NS 12           /* stages of the main method; K[12] = F(t + h, y_new) (FSAL) */
#define DOP_NSTAGES 16      /* with the 3 extra stages of the dense output */
#define DOP_SAFETY 0.9
#define DOP_MIN_FACTOR 0.2
#define DOP_MAX_FACTOR 10.0

/* ---- the tableau's helpers, free of the state's dimension and layout: one component, or one
 * number, at a time, with its elements `stride` doubles apart -- shared by the DOP853 core (stride
 * 1 or the state size) and the lanes of sp_flip (stride SP_LANES), so every integrator takes the
 * same initial step, interpolant and dense coefficients ---- */

/* the RMS norm of x[i * xs] / scale[i * ss], i < n */
static double dop_rms(const double *x, ptrdiff_t xs, const double *scale, ptrdiff_t ss, int n)
{
    double s = 0.0;
    for (int i = 0; i < n; i++) {
        double v = x[i * xs] / scale[i * ss];
        s += v * v;
    }
    return sqrt(s / n);
}

/* Hairer's initial step (Hairer, Norsett & Wanner I, II.4; as SciPy's select_initial_step), in two
 * halves: the trial step from d0 = |y|, d1 = |f(y)| (scaled RMS norms) ... */
static inline double dop_trial_step(double d0, double d1, double span)
{
    double ha = (d0 < 1e-5 || d1 < 1e-5) ? 1e-6 : 0.01 * d0 / d1;
    return fmin(ha, span);
}

/* ... and the first step from d2 = |f(y + ha f) - f(y)| / ha */
static inline double dop_first_step(double ha, double d1, double d2, double span)
{
    double h1;
    if (!isfinite(d2))
        h1 = ha * 1e-3;
    else if (d1 <= 1e-15 && d2 <= 1e-15)
        h1 = fmax(1e-6, ha * 1e-3);
    else
        h1 = pow(0.01 / fmax(d1, d2), 1.0 / 8.0);
    return fmin(fmin(100.0 * ha, h1), span);
}

/* the 7 coefficients F[k * fs] of the 7th-order interpolant of one component over a step of h from
 * y to ynew, from its 16 stages K[j * ks] */
static inline void dop_dense_component(double y, double ynew, double h, const double *K, ptrdiff_t ks, double *F,
                                       ptrdiff_t fs)
{
    double dy = ynew - y;
    F[0 * fs] = dy;
    F[1 * fs] = h * K[0] - dy;
    F[2 * fs] = 2.0 * dy - h * (K[DOP_NS * ks] + K[0]);
    for (int r = 0; r < 4; r++) {
        double acc = 0.0;
        for (int j = 0; j < DOP_NSTAGES; j++) acc += DOP_D[r][j] * K[j * ks];
        F[(3 + r) * fs] = h * acc;
    }
}

/* Hairer's step-size rule: the factor of the next step after an accepted one with error norm err in
 * [0, 1) -- GROW, the safety factor times err^(-1/8) (evaluated only when err > 0), at most
 * DOP_MAX_FACTOR, and at most 1 right after a rejection -- and after a rejected one (DOP_MIN_FACTOR
 * after a non-finite trial).  Macros, so that GROW is computed only where it is used. */
#define DOP_FACTOR_UP(err, GROW) ((err) == 0.0 ? DOP_MAX_FACTOR : fmin(DOP_MAX_FACTOR, (GROW)))
#define DOP_FACTOR_ACCEPTED(err, GROW, after_rejection) \
    ((after_rejection) ? fmin(1.0, DOP_FACTOR_UP(err, GROW)) : DOP_FACTOR_UP(err, GROW))
#define DOP_FACTOR_REJECTED(nonfinite, GROW) ((nonfinite) ? DOP_MIN_FACTOR : fmax(DOP_MIN_FACTOR, (GROW)))

/* the interpolant of one component at x = (t - told) / h in [0, 1] from its coefficients F[k * fs] */
static inline double dop_dense_value(double y, const double *F, ptrdiff_t fs, double x)
{
    double v = 0.0;
    for (int k = 6; k >= 0; k--) {
        v += F[k * fs];
        v *= ((6 - k) % 2 == 0) ? x : 1.0 - x;
    }
    return y + v;
}

/* ---- inputs: joint torques that vary, evaluated inside the integrators (no Python per step) ----
 *
 * A run with inputs passes an sp_control to sp_dop853_ctl / sp_rk4_ctl, which make it this
 * thread's active control for the call; model_rhs then adds the input u(y) to the constant torques
 * tau of p before calling the generated rhs -- so the work W of Q = tau + u - c q' includes the
 * inputs' work and E - W stays conserved.  Laws (kind):
 *   SP_CTL_FEEDBACK  u = u* - K (x - x*), the angles of x - x* wrapped to (-pi, pi];
 *   SP_CTL_SWINGUP   energy shaping u_j = ke (E* - E) q'_j on the actuated joints (E = T + Pi, the
 *                    generated energy), the elbow also held towards its target by a PD law
 *                    -kp (psi - psi*) - kd psi', switched to the feedback inside
 *                    (x - x*)' P (x - x*) < rho;
 *   SP_CTL_TABLE     u(t) interpolated linearly in a table (held at its ends); the state then has a
 *                    sixth component, the time (t' = 1), which the input reads;
 *   SP_CTL_CALLBACK  u = callback(t, y): a function of the caller's (Python's slow path), with the time
 *                    as a sixth state too;
 *   SP_CTL_TRACK     tracking of a reference sampled every dt_table: sample k's law u_k - K_k (x - x_k)
 *                    (the angles of x - x_k wrapped; table row k: x_k[SP_NX], u_k[SP_NQ], K_k[SP_NQ x
 *                    SP_NX] row-major), the sample n_table's the goal's feedback u* - K (x - x*); at time
 *                    t the laws of the samples floor(t / dt_table) and the next blended linearly (sample 0
 *                    before it, the goal's from n_table dt_table on); the time is a state too;
 *   SP_CTL_HELD      u = us: a sampled law held over a step (a digital controller's zero-order hold).  A
 *                    control whose hold is > 0 (a callback sampled every hold seconds) runs with sp_rk4_ctl
 *                    only, its step dt = hold: rk4_run evaluates the law once at each step's start, at the
 *                    accepted state, and holds that input over the step's four stages (Python refuses it
 *                    with the adaptive methods, whose trial stages are no samples).
 * Then the joints not actuated get u = 0 and every u_j is clipped to [-umax_j, umax_j]. */
#define SP_CTL_FEEDBACK 1
#define SP_CTL_SWINGUP 2
#define SP_CTL_TABLE 3
#define SP_CTL_CALLBACK 4
#define SP_CTL_TRACK 5
#define SP_CTL_HELD 6
#define SP_TRACK_W (SP_NX + SP_NQ + SP_NQ * SP_NX) /* a tracking table's row */
typedef struct {
    int32_t kind;              /* SP_CTL_* */
    int32_t actuated;          /* bit j: joint j + 1 driven (the double pendulum's bit 0 the shoulder, bit 1 the elbow) */
    double umax[SP_NQ];        /* saturation of each joint's input [N m] (inf: none) */
    double K[SP_NQ * SP_NX];   /* feedback gain, SP_NQ x SP_NX row-major */
    double xs[SP_NX];          /* target state x* */
    double us[SP_NQ];          /* feedforward input u* at the target */
    double ke;                 /* swing-up: energy gain [N m s / J] */
    double kp, kd;             /* swing-up: the PD gains holding joints 2.. [N m, N m s] */
    double E_target;           /* swing-up: the energy E* [J] */
    double P[SP_NX * SP_NX];   /* swing-up: the region (x - x*)' P (x - x*) < rho where the feedback takes over */
    double rho;
    int64_t n_table;           /* table: n_table rows of (t, u1 .. u_SP_NQ) */
    const double *table;
    void (*callback)(double t, const double *y, double *u); /* callback: u[SP_NQ] at time t and state y[SP_NX] */
    double dt_table;           /* tracking: the reference's sampling step [s] */
    double hold;               /* > 0: the law is sampled every hold seconds and held (rk4's step) */
} sp_control;

/* the active control of this thread (a run with inputs sets it for the duration of a call); the
 * initial-exec model makes reading it one load, not a call, in every right-hand side (one pointer
 * fits the static TLS that the C library keeps for libraries loaded later) */
#if defined(__ELF__) && (defined(__GNUC__) || defined(__clang__))
static _Thread_local const sp_control *sp_ctl __attribute__((tls_model("initial-exec"))) = 0;
#else
static _Thread_local const sp_control *sp_ctl = 0;
#endif

static double sp_wrap(double x)
{
    const double pi = 3.141592653589793, two_pi = 6.283185307179586;
    double w = fmod(x + pi, two_pi);
    if (w < 0.0) w += two_pi;
    return w - pi;
}

/* the state's deviation from the target of c, the angles wrapped */
static inline void sp_deviation(const sp_control *c, const double *y, double *dx)
{
    for (int i = 0; i < SP_NQ; i++) dx[i] = sp_wrap(y[i] - c->xs[i]);
    for (int i = SP_NQ; i < SP_NX; i++) dx[i] = y[i] - c->xs[i];
}

/* dx' P dx about the target of c, the angles of dx wrapped */
static double sp_region(const sp_control *c, const double *P, const double *y)
{
    double dx[SP_NX], v = 0.0;
    sp_deviation(c, y, dx);
    for (int i = 0; i < SP_NX; i++)
        for (int j = 0; j < SP_NX; j++) v += dx[i] * P[SP_NX * i + j] * dx[j];
    return v;
}

/* a tracking law's sample k at state y: u_k - K_k (x - x_k), the goal's u* - K (x - x*) for k = n_table */
static void sp_track_law(const sp_control *c, int64_t k, const double *y, double *u)
{
    const int goal = k >= c->n_table;
    const double *row = goal ? 0 : c->table + k * SP_TRACK_W;
    const double *xk = goal ? c->xs : row, *uk = goal ? c->us : row + SP_NX;
    double e[SP_NX];
    for (int i = 0; i < SP_NQ; i++) e[i] = sp_wrap(y[i] - xk[i]);
    for (int i = SP_NQ; i < SP_NX; i++) e[i] = y[i] - xk[i];
    for (int r = 0; r < SP_NQ; r++) {
        const double *Kr = goal ? c->K + SP_NX * r : row + SP_NX + SP_NQ + SP_NX * r;
        double acc = uk[r];
        for (int j = 0; j < SP_NX; j++) acc -= Kr[j] * e[j];
        u[r] = acc;
    }
}

/* the input u[SP_NQ] at state y (y[SP_NT] the time for a table or a callback) */
static void sp_input(const sp_control *c, const double *y, const double *p, double *u)
{
    double dx[SP_NX];
    sp_deviation(c, y, dx);
    int feedback = c->kind == SP_CTL_FEEDBACK;
    for (int r = 0; r < SP_NQ; r++) u[r] = 0.0;
    if (c->kind == SP_CTL_SWINGUP) {
        if (sp_region(c, c->P, y) < c->rho) {
            feedback = 1;
        } else {
            double e = c->E_target - energy(y, p);
            u[0] = c->ke * e * y[SP_NQ];
            for (int r = 1; r < SP_NQ; r++) u[r] = c->ke * e * y[SP_NQ + r] - c->kp * dx[r] - c->kd * y[SP_NQ + r];
        }
    } else if (c->kind == SP_CTL_CALLBACK) {
        c->callback(y[SP_NT], y, u);
    } else if (c->kind == SP_CTL_HELD) {
        for (int r = 0; r < SP_NQ; r++) u[r] = c->us[r];
    } else if (c->kind == SP_CTL_TRACK) {
        /* the laws of the samples k and k + 1 around t blended linearly (sample n_table: the goal's) */
        const double tk = y[SP_NT] / c->dt_table;
        const double k = floor(tk);
        if (!(k < (double)c->n_table)) {
            feedback = 1;
        } else {
            double a = tk - k, v[SP_NQ];
            int64_t lo = (int64_t)k;
            if (k < 0.0) { lo = 0; a = 0.0; }
            sp_track_law(c, lo, y, u);
            if (a > 0.0) {
                sp_track_law(c, lo + 1, y, v);
                for (int r = 0; r < SP_NQ; r++) u[r] += a * (v[r] - u[r]);
            }
        }
    } else if (c->kind == SP_CTL_TABLE) {
        const double *T = c->table;
        const int64_t n = c->n_table, w = SP_NQ + 1;
        const double t = y[SP_NT];
        if (t <= T[0]) { for (int r = 0; r < SP_NQ; r++) u[r] = T[1 + r]; }
        else if (t >= T[w * (n - 1)]) { for (int r = 0; r < SP_NQ; r++) u[r] = T[w * (n - 1) + 1 + r]; }
        else {
            int64_t lo = 0, hi = n - 1;  /* T[w lo] <= t < T[w hi] */
            while (hi - lo > 1) { int64_t mid = (lo + hi) / 2; if (T[w * mid] <= t) lo = mid; else hi = mid; }
            const double a = (t - T[w * lo]) / (T[w * hi] - T[w * lo]);
            for (int r = 0; r < SP_NQ; r++) u[r] = T[w * lo + 1 + r] + a * (T[w * hi + 1 + r] - T[w * lo + 1 + r]);
        }
    }
    if (feedback) {
        for (int r = 0; r < SP_NQ; r++) {
            double acc = c->us[r];
            for (int j = 0; j < SP_NX; j++) acc -= c->K[SP_NX * r + j] * dx[j];
            u[r] = acc;
        }
    }
    for (int r = 0; r < SP_NQ; r++) {
        if (!(c->actuated & (1 << r))) u[r] = 0.0;
        if (u[r] > c->umax[r]) u[r] = c->umax[r];
        if (u[r] < -c->umax[r]) u[r] = -c->umax[r];
    }
}

/* the model's right-hand side with this thread's active inputs, if any */
static inline void model_rhs(const double *y, const double *p, double *out)
{
    if (__builtin_expect(sp_ctl == 0, 1)) {
        rhs(y, p, out);
        return;
    }
    static const int tau_index[SP_NQ] = SP_TAU_INDEX;
    double q[SP_NPARAM], u[SP_NQ];
    memcpy(q, p, sizeof q);
    sp_input(sp_ctl, y, p, u);
    for (int r = 0; r < SP_NQ; r++) q[tau_index[r]] += u[r];
    rhs(y, q, out);
    if (sp_ctl->kind >= SP_CTL_TABLE) out[SP_NT] = 1.0; /* a table or callback reads the time, a state after W */
}

/* the DOP853 core for the model's own state (chaos.c includes it again for the variational systems) */
#define DOP_NAME(x) x
#define DOP_NDIM SP_NMAX
#define DOP_RHS(y, p, out) model_rhs(y, p, out)
#include "dop853_core.h"


/* The end of the step from t: t_end, or a torque table's first knot after t when that comes first.  The
 * table's u(t) is linear between knots, so a knot is a kink of the right-hand side: a step across one
 * loses the method's order and its error estimate, and how far off the run ends depends on where the
 * steps happen to fall (a rounding's change moved a chain's run by 3.7e-8 at rtol 1e-12, 37x its error
 * with steps ending on the knots).  Every step ends at or before the next knot instead. */
static double table_stop(double t, double t_end)
{
    if (sp_ctl == 0 || sp_ctl->kind != SP_CTL_TABLE) return t_end;
    const double *T = sp_ctl->table;
    const int64_t n = sp_ctl->n_table, w = SP_NQ + 1;
    if (n < 2 || t >= T[w * (n - 1)]) return t_end;
    int64_t lo = -1, hi = n - 1;  /* the first knot after t: T[w hi] > t >= T[w lo] (lo = -1: before the table) */
    while (hi - lo > 1) { int64_t mid = (lo + hi) / 2; if (T[w * mid] <= t) lo = mid; else hi = mid; }
    return T[w * hi] < t_end ? T[w * hi] : t_end;
}

/* Adaptive DOP853 for y' = rhs(y, p) from s->t to t_end (t_end > s->t on the first call).
 *
 * Error control per step with the combined 5th/3rd-order estimate scaled by
 * atol + rtol * max(|y|, |y_new|) (RMS norm); step factor 0.9 err^(-1/8) in [0.2, 10], no
 * increase right after a rejection; a trial step with a non-finite value is rejected like a
 * failed one (factor 0.2).  Output: dt_out <= 0 -- every accepted step (and t0 first);
 * dt_out > 0 -- the grid k dt_out, k = 0 .. n_grid - 1, by the 7th-order dense output (grid
 * points up to rounding beyond t_end get the final state).  *k_out is the next grid index.
 * max_steps bounds accepted + rejected steps over the whole run.  Under a torque table every step ends
 * at or before the table's next knot (table_stop). */
static int dop853_run(sp_state *s, int n, const double *p, double t_end, double rtol, double atol, int64_t max_steps,
                      int64_t budget, double dt_out, int64_t n_grid, int64_t *k_out, double *rows, int64_t cap,
                      int64_t *m_out)
{
    double K[DOP_NSTAGES][SP_NMAX], ynew[SP_NMAX], ytmp[SP_NMAX];
    const int dense = dt_out > 0.0;
    int64_t m = 0, done = 0;
    *m_out = 0;
    if (n < 1 || n > SP_NMAX || cap < 2) return SP_CALL_BAD_ARGUMENTS;
    if (!s->started) {
        s->started = 1;
        if (!all_finite(s->y, n)) return SP_STATUS_NONFINITE;
        if (!dense) put_row(rows, m++, n, s->t, s->y);
    }
    if (!s->have_f) {
        model_rhs(s->y, p, s->f);
        s->nfev++;
        if (!all_finite(s->f, n)) { *m_out = m; return SP_STATUS_NONFINITE; }
        s->have_f = 1;
    }
    for (;;) {
        /* rows owed on the grid up to the current time */
        if (dense) {
            while (*k_out < n_grid) {
                double tk = (double)(*k_out) * dt_out;
                if (tk > s->t && s->t < t_end) break;
                if (m >= cap) { *m_out = m; return SP_CALL_BUFFER_FULL; }
                double *r = rows + m * (n + 1);
                r[0] = tk;
                if (tk >= s->t || !s->dense_ok) {
                    memcpy(r + 1, s->y, (size_t)n * sizeof(double));
                } else if (!dop_dense_eval(s->yold, s->F, (tk - s->told) / s->hseg, r + 1, n)) {
                    *m_out = m;
                    return SP_STATUS_NONFINITE;
                }
                m++;
                (*k_out)++;
            }
        }
        if (s->t >= t_end) { *m_out = m; return SP_STATUS_SUCCESS; }
        if (done >= budget) { *m_out = m; return SP_CALL_BUDGET; }
        if (!dense && m >= cap) { *m_out = m; return SP_CALL_BUFFER_FULL; }

        /* one accepted step (or failure) */
        if (s->h <= 0.0) s->h = dop_initial_step(s->y, s->f, p, t_end - s->t, rtol, atol, &s->nfev, n);
        double h, t_new;
        int rc = dop_advance(s->t, s->y, s->f, p, table_stop(s->t, t_end), rtol, atol, max_steps, &s->h, s->naccept,
                             &s->nreject, &s->nfev, K, ynew, ytmp, n, &t_new, &h);
        if (rc) { *m_out = m; return rc; }
        s->naccept++;
        done++;
        /* the interpolant, when a grid point lies inside this step */
        s->dense_ok = 0;
        if (dense && *k_out < n_grid && (double)(*k_out) * dt_out < t_new) {
            dop_dense_coeffs(s->y, ynew, h, p, K, s->F, ytmp, n);
            s->nfev += DOP_NSTAGES - DOP_NS - 1;
            memcpy(s->yold, s->y, (size_t)n * sizeof(double));
            s->told = s->t;
            s->hseg = h;
            s->dense_ok = 1;
        }
        s->t = t_new;
        memcpy(s->y, ynew, (size_t)n * sizeof(double));
        memcpy(s->f, K[DOP_NS], (size_t)n * sizeof(double));
        if (!dense) put_row(rows, m++, n, s->t, s->y);
    }
}

/* ---- fixed-step methods: nsteps steps of dt from t0; rows every stride-th step and the last ---- */

/* A fixed-step method stops early with `code` at step s->step, whose state is z: the output ends
 * with that last finite state (written even if it is not on the stride). */
static int fixed_stop(const sp_state *s, const double *z, int n, double t0, double dt, int64_t stride, double *rows,
                      int64_t m, int64_t *m_out, int code)
{
    if (s->step % stride != 0) put_row(rows, m++, n, t0 + (double)s->step * dt, z);
    *m_out = m;
    return code;
}

/* Classical Runge-Kutta of order 4.  On a non-finite state the output ends with the last
 * finite state (stored even if it is not on the stride). */
static int rk4_run(sp_state *s, int n, const double *p, double t0, double dt, int64_t nsteps, int64_t stride,
                   int64_t budget, double *rows, int64_t cap, int64_t *m_out)
{
    double k1[SP_NMAX], k2[SP_NMAX], k3[SP_NMAX], k4[SP_NMAX], tmp[SP_NMAX];
    const double half = 0.5 * dt, sixth = dt / 6.0;
    int64_t m = 0, done = 0;
    *m_out = 0;
    if (n < 1 || n > SP_NMAX || cap < 2 || stride < 1) return SP_CALL_BAD_ARGUMENTS;
    if (!s->started) {
        s->started = 1;
        if (!all_finite(s->y, n)) return SP_STATUS_NONFINITE;
        put_row(rows, m++, n, t0, s->y);
    }
    /* a sampled law (hold > 0): evaluated once a step at its start, held over the stages (SP_CTL_HELD) */
    const sp_control *law = sp_ctl;
    sp_control held;
    const int holding = law != 0 && law->hold > 0.0;
    if (holding) { held = *law; held.kind = SP_CTL_HELD; }
    while (s->step < nsteps) {
        if (done >= budget) { *m_out = m; return SP_CALL_BUDGET; }
        if (m >= cap - 1) { *m_out = m; return SP_CALL_BUFFER_FULL; }
        if (holding) { sp_ctl = law; sp_input(law, s->y, p, held.us); sp_ctl = &held; }
        model_rhs(s->y, p, k1);
        for (int i = 0; i < n; i++) tmp[i] = s->y[i] + half * k1[i];
        model_rhs(tmp, p, k2);
        for (int i = 0; i < n; i++) tmp[i] = s->y[i] + half * k2[i];
        model_rhs(tmp, p, k3);
        for (int i = 0; i < n; i++) tmp[i] = s->y[i] + dt * k3[i];
        model_rhs(tmp, p, k4);
        s->nfev += 4;
        for (int i = 0; i < n; i++) tmp[i] = s->y[i] + sixth * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i]);
        if (!all_finite(tmp, n)) return fixed_stop(s, s->y, n, t0, dt, stride, rows, m, m_out, SP_STATUS_NONFINITE);
        memcpy(s->y, tmp, (size_t)n * sizeof(double));
        s->step++;
        s->naccept++;
        done++;
        s->t = t0 + (double)s->step * dt;
        if (s->step % stride == 0 || s->step == nsteps) put_row(rows, m++, n, s->t, s->y);
    }
    *m_out = m;
    return SP_STATUS_SUCCESS;
}

/* The entry points: each makes its control (none for the plain ones) this thread's active control
 * for the duration of the call and gives the caller's back on return.  The active control is thus
 * scoped to one call, never shared between calls: a Python law (SP_CTL_CALLBACK) that runs a
 * simulation of its own -- with inputs or without -- runs it with that simulation's inputs, and
 * the outer run resumes with its own (issue 36; test_simulate's re-entrancy test). */
int sp_dop853(sp_state *s, int n, const double *p, double t_end, double rtol, double atol, int64_t max_steps,
              int64_t budget, double dt_out, int64_t n_grid, int64_t *k_out, double *rows, int64_t cap,
              int64_t *m_out)
{
    const sp_control *outer = sp_ctl;
    sp_ctl = 0;
    int rc = dop853_run(s, n, p, t_end, rtol, atol, max_steps, budget, dt_out, n_grid, k_out, rows, cap, m_out);
    sp_ctl = outer;
    return rc;
}

int sp_rk4(sp_state *s, int n, const double *p, double t0, double dt, int64_t nsteps, int64_t stride,
           int64_t budget, double *rows, int64_t cap, int64_t *m_out)
{
    const sp_control *outer = sp_ctl;
    sp_ctl = 0;
    int rc = rk4_run(s, n, p, t0, dt, nsteps, stride, budget, rows, cap, m_out);
    sp_ctl = outer;
    return rc;
}

int sp_dop853_ctl(const sp_control *c, sp_state *s, int n, const double *p, double t_end, double rtol, double atol,
                  int64_t max_steps, int64_t budget, double dt_out, int64_t n_grid, int64_t *k_out, double *rows,
                  int64_t cap, int64_t *m_out)
{
    const sp_control *outer = sp_ctl;
    sp_ctl = c;
    int rc = dop853_run(s, n, p, t_end, rtol, atol, max_steps, budget, dt_out, n_grid, k_out, rows, cap, m_out);
    sp_ctl = outer;
    return rc;
}

int sp_rk4_ctl(const sp_control *c, sp_state *s, int n, const double *p, double t0, double dt, int64_t nsteps,
               int64_t stride, int64_t budget, double *rows, int64_t cap, int64_t *m_out)
{
    const sp_control *outer = sp_ctl;
    sp_ctl = c;
    int rc = rk4_run(s, n, p, t0, dt, nsteps, stride, budget, rows, cap, m_out);
    sp_ctl = outer;
    return rc;
}

/* the inputs at nrows states (`stride` doubles apart, the time at offset SP_NT for a table) into
 * out[SP_NQ nrows] */
void sp_inputs_many(const sp_control *c, const double *rows, int64_t nrows, int64_t stride, const double *p, double *out)
{
    for (int64_t r = 0; r < nrows; r++) sp_input(c, rows + r * stride, p, out + SP_NQ * r);
}

/* the closed loop's right-hand side y' (SP_NMAX doubles per row, of which the state's) at nrows states
 * (`stride` doubles apart, SP_NX + 1 or SP_NX + 2 components each) into out[nrows * stride] */
void sp_rhs_ctl_many(const sp_control *c, const double *rows, int64_t nrows, int64_t stride, const double *p,
                     double *out)
{
    double y[SP_NMAX], f[SP_NMAX];
    const sp_control *outer = sp_ctl;
    sp_ctl = c;
    for (int64_t r = 0; r < nrows; r++) {
        memset(y, 0, sizeof y);
        memcpy(y, rows + r * stride, (size_t)stride * sizeof(double));
        model_rhs(y, p, f);
        memcpy(out + r * stride, f, (size_t)stride * sizeof(double));
    }
    sp_ctl = outer;
}

int64_t sp_control_size(void) { return (int64_t)sizeof(sp_control); }

/* Sampled inputs (a digital controller's zero-order hold): one classical RK4 step of dt from the
 * mechanical state y[SP_NX] with the torques u[SP_NQ] added to p's constant torques and held over the
 * step, into out[SP_NX] (y and out may be the same array) -- the step of the RealAIGym leaderboard's
 * simulator.  The work W is not carried. */
void sp_rk4_hold(const double *y, const double *p, const double *u, double dt, double *out)
{
    static const int tau_index[SP_NQ] = SP_TAU_INDEX;
    double q[SP_NPARAM], y0[SP_NMAX], k[4][SP_NMAX], s[SP_NMAX];
    memcpy(q, p, sizeof q);
    for (int r = 0; r < SP_NQ; r++) q[tau_index[r]] += u[r];
    memset(y0, 0, sizeof y0);
    memcpy(y0, y, SP_NX * sizeof(double));
    const double c[3] = {0.5 * dt, 0.5 * dt, dt};
    rhs(y0, q, k[0]);
    for (int st = 0; st < 3; st++) {
        memcpy(s, y0, sizeof s);
        for (int i = 0; i < SP_NX; i++) s[i] = y0[i] + c[st] * k[st][i];
        rhs(s, q, k[st + 1]);
    }
    for (int i = 0; i < SP_NX; i++) out[i] = y0[i] + dt / 6.0 * (k[0][i] + 2.0 * (k[1][i] + k[2][i]) + k[3][i]);
}

/* The RealAIGym leaderboard's simulator loop with the compiled law c (sp_input: its limits and actuated
 * joints), from x0[SP_NX] for `steps` steps of dt: at step k (t = k dt) the law sees the state of step
 * max(k - delay, 0), its speeds plus vnoise[k] (SP_NQ per step; NULL: none) -- or, with estimate = 1, the
 * speeds the law's own observer takes from the positions it has seen at this step and the two before
 * (backward differences of second order, of first order at the second step, the measured speeds at the
 * first); the applied torque is the
 * previous one (0 at first) plus resp times the change to the law's, plus unoise[k] on the actuated
 * joints (NULL: none), clipped to the limits, plus pert[k] on the actuated joints (NULL: none, after the
 * clip), held over the RK4 step (sp_rk4_hold).  xs[k] (SP_NX) and us[k] (SP_NQ) are the state and the
 * applied torques at step k, xf (SP_NX) the state after the last step.  Returns the steps done: `steps`,
 * or the first k whose torque or next state is not finite. */
int64_t sp_protocol(const sp_control *c, const double *p, const double *x0, int64_t steps, double dt, int64_t delay,
                    double resp, const double *vnoise, const double *unoise, const double *pert, int32_t estimate,
                    double *xs, double *us, double *xf)
{
    double y[SP_NMAX], u[SP_NQ], last[SP_NQ], x[SP_NX];
    memcpy(x, x0, sizeof x);
    for (int r = 0; r < SP_NQ; r++) last[r] = 0.0;
    for (int64_t k = 0; k < steps; k++) {
        memcpy(xs + k * SP_NX, x, sizeof x);
        const int64_t seen = k - delay > 0 ? k - delay : 0;
        memset(y, 0, sizeof y);
        memcpy(y, xs + seen * SP_NX, sizeof x);
        if (vnoise)
            for (int r = 0; r < SP_NQ; r++) y[SP_NQ + r] += vnoise[k * SP_NQ + r];
        if (estimate && k >= 1) { /* the positions the law saw at this step and the two before */
            const int64_t s1 = k - 1 - delay > 0 ? k - 1 - delay : 0, s2 = k - 2 - delay > 0 ? k - 2 - delay : 0;
            const double *q0 = xs + seen * SP_NX, *q1 = xs + s1 * SP_NX, *q2 = xs + s2 * SP_NX;
            for (int r = 0; r < SP_NQ; r++)
                y[SP_NQ + r] = k >= 2 ? (3.0 * q0[r] - 4.0 * q1[r] + q2[r]) / (2.0 * dt) : (q0[r] - q1[r]) / dt;
        }
        y[SP_NT] = (double)k * dt;
        sp_input(c, y, p, u);
        for (int r = 0; r < SP_NQ; r++) {
            double v = last[r] + resp * (u[r] - last[r]);
            if (!(c->actuated & (1 << r))) { u[r] = 0.0; continue; }
            if (unoise) v += unoise[k * SP_NQ + r];
            if (v > c->umax[r]) v = c->umax[r];
            if (v < -c->umax[r]) v = -c->umax[r];
            if (pert) v += pert[k * SP_NQ + r];
            u[r] = v;
        }
        int finite = 1;
        for (int r = 0; r < SP_NQ; r++) { finite &= isfinite(u[r]) != 0; last[r] = u[r]; us[k * SP_NQ + r] = u[r]; }
        if (!finite) return k;
        sp_rk4_hold(x, p, u, dt, x);
        for (int i = 0; i < SP_NX; i++) finite &= isfinite(x[i]) != 0;
        if (!finite) return k;
    }
    memcpy(xf, x, sizeof x);
    return steps;
}

/* Each of m starts (SP_NX doubles: angles and speeds) integrated by DOP853 (the core above, on the SP_NX
 * mechanical components; the active control c, if any, inside) until the test stop(y, data, &which) holds
 * -- time[k] is the first point where it does, located by bisection on the 7th-order dense output of the
 * first step that ends where it holds (0 when it holds at the start) -- or until t_end (time[k] = NaN).
 * status[k] is SP_STATUS_SUCCESS, or the code of a failed integration (time NaN); steps[k] counts its
 * accepted steps, rejected[k] its rejected ones (the result protocol's steps and rejected); which[k] (if
 * given) is what the test said when it held (-1: it did not).  Every start's arithmetic is its own: the
 * results do not depend on m or on which starts share a call. */
typedef int (*sp_stop_test)(const double *y, const void *data, int *which);

static void sp_until_many(const sp_control *c, sp_stop_test stop, const void *data, const double *p,
                          const double *starts, int64_t m, double t_end, double rtol, double atol, int64_t max_steps,
                          double *time, int32_t *which_out, int64_t *steps, int64_t *rejected, int8_t *status)
{
    double K[DOP_NSTAGES][SP_NMAX], ynew[SP_NMAX], ytmp[SP_NMAX], y[SP_NMAX], f[SP_NMAX], F[7 * SP_NMAX];
    const int n = SP_NX;
    const sp_control *outer = sp_ctl;
    sp_ctl = c;
    for (int64_t k = 0; k < m; k++) {
        double t = 0.0, h = 0.0, hused, t_new, when = NAN;
        int64_t nacc = 0, nrej = 0, nfev = 0;
        int rc = SP_STATUS_SUCCESS, which = -1, w;
        memset(y, 0, sizeof y);
        memcpy(y, starts + SP_NX * k, SP_NX * sizeof(double));
        model_rhs(y, p, f);
        if (!all_finite(y, n) || !all_finite(f, n)) rc = SP_STATUS_NONFINITE;
        else if (stop(y, data, &which)) when = 0.0;
        while (rc == SP_STATUS_SUCCESS && isnan(when) && t < t_end) {
            if (h <= 0.0) h = dop_initial_step(y, f, p, t_end - t, rtol, atol, &nfev, n);
            rc = dop_advance(t, y, f, p, t_end, rtol, atol, max_steps, &h, nacc, &nrej, &nfev, K, ynew, ytmp, n,
                             &t_new, &hused);
            if (rc) break;
            nacc++;
            if (stop(ynew, data, &which)) {
                /* it held at the step's end: bisect the dense output for the first point where it does */
                double lo = 0.0, hi = 1.0;
                dop_dense_coeffs(y, ynew, hused, p, K, F, ytmp, n);
                for (int it = 0; it < 60 && (hi - lo) * hused > 1e-14 * fmax(1.0, t_new); it++) {
                    double mid = 0.5 * (lo + hi);
                    if (dop_dense_eval(y, F, mid, ytmp, n) && stop(ytmp, data, &w)) { hi = mid; which = w; }
                    else lo = mid;
                }
                when = t + hi * hused;
            }
            t = t_new;
            memcpy(y, ynew, (size_t)n * sizeof(double));
            memcpy(f, K[DOP_NS], (size_t)n * sizeof(double));
        }
        time[k] = when;
        if (which_out) which_out[k] = isnan(when) ? -1 : which;
        steps[k] = nacc;
        rejected[k] = nrej;
        status[k] = (int8_t)rc;
    }
    sp_ctl = outer;
}

typedef struct { const sp_control *c; const double *P; double rho; } sp_region_test;

static int sp_in_region(const double *y, const void *data, int *which)
{
    const sp_region_test *r = (const sp_region_test *)data;
    *which = 0;
    return sp_region(r->c, r->P, y) < r->rho;
}

/* Capture of m closed-loop starts (regions of attraction): sp_until_many with the control c until the
 * state enters the region dx' P dx < rho about the target c->xs (angles wrapped) -- captured: time[k] is
 * the entry -- or reaches t_end (time[k] = NaN). */
void sp_capture_many(const sp_control *c, const double *p, const double *starts, int64_t m, double t_end,
                     double rtol, double atol, int64_t max_steps, const double *P, double rho, double *time,
                     int64_t *steps, int64_t *rejected, int8_t *status)
{
    const sp_region_test region = {c, P, rho};
    sp_until_many(c, sp_in_region, &region, p, starts, m, t_end, rtol, atol, max_steps, time, 0, steps, rejected,
                  status);
}

static int sp_flipped(const double *y, const void *data, int *which)
{
    (void)data;
    const double pi = 3.141592653589793;
    for (int i = 0; i < SP_NQ; i++)
        if (fabs(y[i]) >= pi) { *which = i; return 1; }
    return 0;
}

/* Flips of m starts without inputs (a chain's flip map; the double pendulum's runs in SIMD lanes, sp_flip):
 * sp_until_many until an angle leaves (-pi, pi) -- time[k] the first such time, which[k] that joint (0 ..
 * SP_NQ - 1; -1 none) -- or t_end (time[k] = NaN). */
void sp_flip_many(const double *p, const double *starts, int64_t m, double t_end, double rtol, double atol,
                  int64_t max_steps, double *time, int32_t *which, int64_t *steps, int64_t *rejected, int8_t *status)
{
    sp_until_many(0, sp_flipped, 0, p, starts, m, t_end, rtol, atol, max_steps, time, which, steps, rejected, status);
}

/* 2-stage Gauss-Legendre collocation (order 4, symplectic) for z' = ham_rhs(z, p).
 * The stage equations K_i = f(z + dt sum_j a_ij K_j) are solved by fixed-point iteration,
 * started from the previous step's collocation polynomial extrapolated to the new stages,
 * until the max-norm change of the stage values is <= tol max|z| -- or stops decreasing at
 * the rounding level (<= 64 eps of the state) -- within max_iter iterations.  The update
 * uses compensated summation. */
int sp_gauss(sp_state *s, int n, const double *p, double t0, double dt, int64_t nsteps, int64_t stride,
             double tol, int64_t max_iter, int64_t budget, double *rows, int64_t cap, int64_t *m_out)
{
    const double r3 = sqrt(3.0);
    const double a11 = 0.25, a12 = 0.25 - r3 / 6.0, a21 = 0.25 + r3 / 6.0, a22 = 0.25;
    const double w1 = r3, w2 = 1.0 + r3, eps = 2.220446049250313e-16;
    double *k1 = s->f, *k2 = s->g, *z = s->y;
    double f1[SP_NMAX], f2[SP_NMAX], y1[SP_NMAX], y2[SP_NMAX];
    int64_t m = 0, done = 0;
    *m_out = 0;
    if (n < 1 || n > SP_NMAX || cap < 2 || stride < 1) return SP_CALL_BAD_ARGUMENTS;
    if (!s->started) {
        s->started = 1;
        if (!all_finite(z, n)) return SP_STATUS_NONFINITE;
        put_row(rows, m++, n, t0, z);
        memset(s->comp, 0, sizeof(s->comp));
    }
    if (!s->have_f && s->step < nsteps) {
        ham_rhs(z, p, k1);
        s->nfev++;
        if (!all_finite(k1, n)) { *m_out = m; return SP_STATUS_NONFINITE; }
        memcpy(k2, k1, (size_t)n * sizeof(double));
        s->have_f = 1;
    }
    while (s->step < nsteps) {
        if (done >= budget) { *m_out = m; return SP_CALL_BUDGET; }
        if (m >= cap - 1) { *m_out = m; return SP_CALL_BUFFER_FULL; }
        double scale = 0.0, prev = INFINITY;
        int converged = 0;
        for (int i = 0; i < n; i++) scale = fmax(scale, fabs(z[i]));
        for (int64_t it = 0; it < max_iter; it++) {
            for (int i = 0; i < n; i++) {
                y1[i] = z[i] + dt * (a11 * k1[i] + a12 * k2[i]);
                y2[i] = z[i] + dt * (a21 * k1[i] + a22 * k2[i]);
            }
            ham_rhs(y1, p, f1);
            ham_rhs(y2, p, f2);
            s->nfev += 2;
            if (!(all_finite(f1, n) && all_finite(f2, n))) {
                return fixed_stop(s, z, n, t0, dt, stride, rows, m, m_out, SP_STATUS_NONFINITE);
            }
            double delta = 0.0, size = scale;
            for (int i = 0; i < n; i++) {
                double d1 = f1[i] - k1[i], d2 = f2[i] - k2[i];
                delta = fmax(delta, fmax(fabs(dt * (a11 * d1 + a12 * d2)), fabs(dt * (a21 * d1 + a22 * d2))));
                size = fmax(size, fmax(fabs(y1[i]), fabs(y2[i])));
                k1[i] = f1[i];
                k2[i] = f2[i];
            }
            if (delta <= tol * scale || delta == 0.0) { converged = 1; break; }
            if (delta >= prev && delta <= 64.0 * eps * size) { converged = 1; break; } /* rounding level */
            prev = delta;
        }
        if (!converged) {
            return fixed_stop(s, z, n, t0, dt, stride, rows, m, m_out, SP_STATUS_NO_CONVERGENCE);
        }
        int ok = 1;
        for (int i = 0; i < n; i++) {  /* z += dt/2 (k1 + k2), compensated */
            double inc = 0.5 * dt * (k1[i] + k2[i]) + s->comp[i];
            double nz = z[i] + inc;
            s->comp[i] = inc - (nz - z[i]);
            y1[i] = nz;
            if (!isfinite(nz)) ok = 0;
        }
        if (!ok) {
            return fixed_stop(s, z, n, t0, dt, stride, rows, m, m_out, SP_STATUS_NONFINITE);
        }
        for (int i = 0; i < n; i++) {
            z[i] = y1[i];
            double d = k2[i] - k1[i], a = k1[i];  /* starting guess for the next step */
            k1[i] = a + w1 * d;
            k2[i] = a + w2 * d;
        }
        s->step++;
        s->naccept++;
        done++;
        s->t = t0 + (double)s->step * dt;
        if (s->step % stride == 0 || s->step == nsteps) put_row(rows, m++, n, s->t, z);
    }
    *m_out = m;
    return SP_STATUS_SUCCESS;
}

#ifdef SP_FLIP_KERNEL /* only in the flip kernel (kernel_module(..., flip=True)) */
/* ---- flip times: DOP853 over SP_LANES trajectories at once -----------------------------------------
 *
 * Contract with the code generator (kernel_source.flip_c_source): the generated text defines
 * SP_LANES, SP_FLIP_N (state size; components 0 and 1 are the joint angles phi and psi, 2 and 3
 * their rates), SP_FLIP_NPP and
 *
 *     static void flip_prepare(const double *p, double *pp);      parameter-only constants, once
 *     static void flip_rhs(const double (*y)[SP_LANES], const double *pp, double (*out)[SP_LANES]);
 *                                       y' of SP_LANES states: component k of lane l is y[k][l]
 *     static void flip_init(double phi, double psi, double *y);   the state released at rest
 *
 * sp_flip integrates each of m cells (phi0, psi0) released at rest with the DOP853 method, error
 * norm and step-size rule of sp_dop853 (but the safety factor SP_FLIP_SAFETY, and err^(-1/8) as
 * three square roots), until t_end or until |phi| or |psi| reaches pi.  Each lane carries its own
 * trajectory, with its own time, step size and accept/reject decisions; a lane whose trajectory
 * ends takes the next cell.  The lane loops have a fixed trip count and
 * no dependence between lanes, so the compiler turns them into SIMD instructions (the function
 * is compiled for AVX-512, AVX2 and the baseline, picked at load time, where GCC can); every
 * operation is element-wise IEEE arithmetic without contraction, so a cell's result is bitwise
 * the same whichever lane, call, chunk or instruction set computes it.
 *
 * The flip is located on the 7th-order dense output of the step in which an angle reaches pi:
 * the first x in (0, 1] with |angle(told + x h)| >= pi, by sampling and bisection to ~1e-13 s.
 * A step that ends below pi but turns around close to it is checked the same way (touch and
 * return within one step).
 *
 * Resumable like the other integrators: the state between calls lives in the caller's zeroed
 * sp_flip_ws; a call makes at most `budget` steps (of all lanes at once) and returns -1 (call
 * again) or 0 (all cells done).  Per cell: tflip (NaN: no flip by t_end), which (0 phi, 1 psi,
 * -1 none, -2 the integration failed: non-finite state, step size underflow or more than
 * max_steps attempted steps), accepted and rejected steps.
 */
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__)
#define SP_MULTIVERSION __attribute__((target_clones("avx512f", "avx2", "default")))
#else
#define SP_MULTIVERSION
#endif
#define SP_LANE_LOOP for (int l = 0; l < SP_LANES; l++)
/* Safety factor of the step-size rule: 0.8 rather than sp_dop853's 0.9 -- measured on the flip map
 * of issue 9 it trades 20% rejected steps for 6% (and 9% more accepted ones): 7% fewer in all. */
#define SP_FLIP_SAFETY 0.8

typedef struct {
    int64_t started, next;                 /* next: the next cell to start */
    int64_t cell[SP_LANES];                /* the cell in each lane, -1 idle */
    double t[SP_LANES], h[SP_LANES];       /* time and next step size of each lane */
    int64_t nacc[SP_LANES], nrej[SP_LANES], last_rejected[SP_LANES];
    double y[SP_FLIP_N][SP_LANES];         /* state, component-major */
    double f[SP_FLIP_N][SP_LANES];         /* its derivative (first same as last) */
    double pp[SP_FLIP_NPP];
} sp_flip_ws;

/* the flip library's layout in one call: out[0] the bytes of the sp_flip workspace, out[1] the lanes
 * (trajectories side by side), out[2] whether the equations without torques are odd under
 * (q, q') -> -(q, q') (a symbolic check of the generator) */
void sp_flip_layout(int64_t *out)
{
    out[0] = (int64_t)sizeof(sp_flip_ws);
    out[1] = SP_LANES;
    out[2] = SP_FLIP_ODD;
}

/* the non-zero coefficients of the DOP853 tables as (index, value) lists */
typedef struct {
    int na[DOP_NSTAGES], ja[DOP_NSTAGES][DOP_NSTAGES];
    double a[DOP_NSTAGES][DOP_NSTAGES];
    int ne5, je5[DOP_NS + 1], ne3, je3[DOP_NS + 1];
    double e5[DOP_NS + 1], e3[DOP_NS + 1];
} flip_tables;

static void flip_tables_init(flip_tables *T)
{
    for (int s = 0; s < DOP_NSTAGES; s++) {
        T->na[s] = 0;
        for (int j = 0; j < s; j++)
            if (DOP_A[s][j] != 0.0) {
                T->ja[s][T->na[s]] = j;
                T->a[s][T->na[s]++] = DOP_A[s][j];
            }
    }
    T->ne5 = T->ne3 = 0;
    for (int j = 0; j < DOP_NS + 1; j++) {
        if (DOP_E5[j] != 0.0) { T->je5[T->ne5] = j; T->e5[T->ne5++] = DOP_E5[j]; }
        if (DOP_E3[j] != 0.0) { T->je3[T->ne3] = j; T->e3[T->ne3++] = DOP_E3[j]; }
    }
}

/* out = y + h * sum_j A[s][j] K[j] over the non-zero coefficients of row s, every lane */
static inline __attribute__((always_inline)) void flip_stage_arg(
    const double (*restrict y)[SP_LANES], const double *restrict h, const flip_tables *restrict T, int s,
    const double (*restrict K)[SP_FLIP_N][SP_LANES], double (*restrict out)[SP_LANES])
{
    const int na = T->na[s];
    const int *ja = T->ja[s];
    const double *a = T->a[s];
    for (int i = 0; i < SP_FLIP_N; i++) {
        double acc[SP_LANES];
        const double a0 = a[0], *K0 = K[ja[0]][i];
        SP_LANE_LOOP acc[l] = a0 * K0[l];
        for (int k = 1; k < na; k++) {
            const double ak = a[k], *Kk = K[ja[k]][i];
            SP_LANE_LOOP acc[l] = acc[l] + ak * Kk[l];
        }
        SP_LANE_LOOP out[i][l] = y[i][l] + h[l] * acc[l];
    }
}

/* Hairer's initial step (as dop_initial_step), lane by lane, for the lanes marked fresh: first half,
 * from f = K0 (the derivative at y): the Euler point ytmp = y + ha f; a fresh lane whose state or
 * derivative is not finite gets h = -1 (it fails at its first step), dropped[l] = 1 and fresh[l] = 0 */
static inline __attribute__((always_inline)) void lanes_first_step_begin(
    const double (*restrict y)[SP_LANES], const double (*restrict K0)[SP_LANES], double (*restrict f)[SP_LANES],
    int *restrict fresh, int *restrict dropped, double rtol, double atol, double t_end, double *restrict ha,
    double *restrict d1, double (*restrict sc)[SP_LANES], double (*restrict ytmp)[SP_LANES], double *restrict h)
{
    const int n = SP_FLIP_N;
    for (int l = 0; l < SP_LANES; l++) {
        ha[l] = 0.0;
        dropped[l] = 0;
        if (!fresh[l]) continue;
        int finite = 1;
        for (int i = 0; i < n; i++) {
            f[i][l] = K0[i][l];
            if (!isfinite(f[i][l]) || !isfinite(y[i][l])) finite = 0;
            sc[i][l] = atol + fabs(y[i][l]) * rtol;
        }
        if (!finite) { fresh[l] = 0; h[l] = -1.0; dropped[l] = 1; continue; }  /* fails below */
        d1[l] = dop_rms(&f[0][l], SP_LANES, &sc[0][l], SP_LANES, n);
        ha[l] = dop_trial_step(dop_rms(&y[0][l], SP_LANES, &sc[0][l], SP_LANES, n), d1[l], t_end);
    }
    for (int i = 0; i < n; i++) SP_LANE_LOOP ytmp[i][l] = y[i][l] + ha[l] * f[i][l];
}

/* ... second half, from K1 (the derivative at ytmp): the first step h of every fresh lane */
static inline __attribute__((always_inline)) void lanes_first_step_end(
    const double (*restrict K1)[SP_LANES], const double (*restrict f)[SP_LANES], const int *restrict fresh,
    double t_end, const double *restrict ha, const double *restrict d1, const double (*restrict sc)[SP_LANES],
    double *restrict h)
{
    const int n = SP_FLIP_N;
    for (int l = 0; l < SP_LANES; l++) {
        if (!fresh[l]) continue;
        double df[SP_FLIP_N];
        for (int i = 0; i < n; i++) df[i] = K1[i][l] - f[i][l];
        h[l] = dop_first_step(ha[l], d1[l], dop_rms(df, 1, &sc[0][l], SP_LANES, n) / ha[l], t_end);
    }
}

/* Hairer's combined 5th/3rd-order error norm of a DOP853 step, per lane: its sums e5, e3, err, root =
 * err^(1/8) for the step-size factor (special cases by the caller), bad = NaN where anything is not finite */
static inline __attribute__((always_inline)) void flip_error_norm(
    const double (*restrict y)[SP_LANES], const double (*restrict ynew)[SP_LANES],
    const double (*restrict K)[SP_FLIP_N][SP_LANES], const flip_tables *restrict T, const double *restrict H,
    double rtol, double atol, double *restrict e5, double *restrict e3, double *restrict err, double *restrict root,
    double *restrict bad)
{
    const int n = SP_FLIP_N;
    SP_LANE_LOOP e5[l] = e3[l] = bad[l] = 0.0;
    for (int i = 0; i < n; i++) {
        double a5[SP_LANES], a3[SP_LANES];
        SP_LANE_LOOP { a5[l] = T->e5[0] * K[T->je5[0]][i][l]; a3[l] = T->e3[0] * K[T->je3[0]][i][l]; }
        for (int k = 1; k < T->ne5; k++) {
            const double c = T->e5[k], *Kk = K[T->je5[k]][i];
            SP_LANE_LOOP a5[l] = a5[l] + c * Kk[l];
        }
        for (int k = 1; k < T->ne3; k++) {
            const double c = T->e3[k], *Kk = K[T->je3[k]][i];
            SP_LANE_LOOP a3[l] = a3[l] + c * Kk[l];
        }
        SP_LANE_LOOP {
            double ay = y[i][l] < 0.0 ? -y[i][l] : y[i][l], an = ynew[i][l] < 0.0 ? -ynew[i][l] : ynew[i][l];
            double r = 1.0 / (atol + rtol * (ay > an ? ay : an));
            double u = a5[l] * r, v = a3[l] * r;
            e5[l] = e5[l] + u * u;
            e3[l] = e3[l] + v * v;
            bad[l] = bad[l] + 0.0 * ynew[i][l] + 0.0 * K[DOP_NS][i][l];
        }
    }
    SP_LANE_LOOP {
        err[l] = fabs(H[l]) * e5[l] / sqrt((e5[l] + 0.01 * e3[l]) * n);
        root[l] = sqrt(sqrt(sqrt(err[l])));
    }
}

/* the interpolant of one component at x in [0, 1] (as dop_dense_eval) from its 7 coefficients */
static double flip_dense(double y0, const double *F, double x) { return dop_dense_value(y0, F, 1, x); }

/* The first x in (0, 1] with |q(x)| >= pi on the interpolant of one angle over a step of h
 * seconds, or -1 if there is none.  `crossed`: the step's end is at or past pi. */
static double flip_locate(double y0, const double *F, double h, int crossed)
{
    const double pi = 3.141592653589793;
    const int ns = 16;
    double lo = 0.0, hi = -1.0, best = -1.0;
    int kbest = 1;
    for (int k = 1; k <= ns; k++) {
        double x = (double)k / ns, v = fabs(flip_dense(y0, F, x));
        if (v >= pi) { hi = x; break; }
        lo = x;
        if (v > best) { best = v; kbest = k; }
    }
    if (hi < 0.0 && crossed) { lo = (double)(ns - 1) / ns; hi = 1.0; }
    if (hi < 0.0) {
        /* touch and return: the largest |q| around the largest sample, by golden-section search */
        const double r = 0.6180339887498949;
        double a = (double)(kbest - 1) / ns, b = fmin(1.0, (double)(kbest + 1) / ns);
        double x1 = b - r * (b - a), x2 = a + r * (b - a);
        double v1 = fabs(flip_dense(y0, F, x1)), v2 = fabs(flip_dense(y0, F, x2));
        for (int it = 0; it < 80 && (b - a) * h > 1e-14 && v1 < pi && v2 < pi; it++) {
            if (v1 > v2) {
                b = x2; x2 = x1; v2 = v1;
                x1 = b - r * (b - a);
                v1 = fabs(flip_dense(y0, F, x1));
            } else {
                a = x1; x1 = x2; v1 = v2;
                x2 = a + r * (b - a);
                v2 = fabs(flip_dense(y0, F, x2));
            }
        }
        if (v1 >= pi) hi = x1;
        else if (v2 >= pi) hi = x2;
        else return -1.0;
        lo = (double)(kbest - 1) / ns;  /* the samples up to kbest - 1 are below pi */
        if (lo >= hi) lo = 0.0;
    }
    for (int it = 0; it < 80 && (hi - lo) * h > 1e-13; it++) {
        double mid = 0.5 * (lo + hi);
        if (fabs(flip_dense(y0, F, mid)) >= pi) hi = mid;
        else lo = mid;
    }
    return hi;
}

SP_MULTIVERSION
int sp_flip(sp_flip_ws *w, const double *p, const double *cells, int64_t m, double t_end, double rtol, double atol,
            int64_t max_steps, int64_t budget, double *tflip, int32_t *which, int64_t *naccept, int64_t *nreject)
{
    const int n = SP_FLIP_N;
    const double pi = 3.141592653589793;
    double y[SP_FLIP_N][SP_LANES], f[SP_FLIP_N][SP_LANES], ynew[SP_FLIP_N][SP_LANES], ytmp[SP_FLIP_N][SP_LANES];
    double K[DOP_NSTAGES][SP_FLIP_N][SP_LANES];
    double H[SP_LANES], tnew[SP_LANES], e5[SP_LANES], e3[SP_LANES], bad[SP_LANES], err[SP_LANES], root[SP_LANES];
    int accept[SP_LANES], fail[SP_LANES], event[SP_LANES];
    flip_tables T;
    if (m < 0 || !(t_end > 0.0) || !(rtol > 0.0) || !(atol > 0.0) || budget < 1) return SP_CALL_BAD_ARGUMENTS;
    flip_tables_init(&T);
    if (!w->started) {
        flip_prepare(p, w->pp);
        for (int l = 0; l < SP_LANES; l++) w->cell[l] = -1;
        w->next = 0;
        w->started = 1;
    }
    const double *pp = w->pp;
    memcpy(y, w->y, sizeof(y));
    memcpy(f, w->f, sizeof(f));
    int status;
    for (int64_t it = 0;; it++) {
        /* idle lanes take the next cells: the state at rest, F(y0), Hairer's initial step */
        int fresh[SP_LANES], nfresh = 0;
        for (int l = 0; l < SP_LANES; l++) {
            fresh[l] = 0;
            if (w->cell[l] < 0 && w->next < m) {
                int64_t c = w->next++;
                double y0[SP_FLIP_N];
                flip_init(cells[2 * c], cells[2 * c + 1], y0);
                for (int i = 0; i < n; i++) y[i][l] = y0[i];
                w->cell[l] = c;
                w->t[l] = 0.0;
                w->h[l] = 0.0;
                w->nacc[l] = w->nrej[l] = w->last_rejected[l] = 0;
                fresh[l] = 1;
                nfresh++;
            }
        }
        if (nfresh) {
            double ha[SP_LANES], d1[SP_LANES], sc[SP_FLIP_N][SP_LANES];
            int dropped[SP_LANES];
            flip_rhs((const double (*)[SP_LANES])y, pp, K[0]);
            lanes_first_step_begin((const double (*)[SP_LANES])y, (const double (*)[SP_LANES])K[0], f, fresh, dropped,
                                   rtol, atol, t_end, ha, d1, sc, ytmp, w->h);
            flip_rhs((const double (*)[SP_LANES])ytmp, pp, K[1]);
            lanes_first_step_end((const double (*)[SP_LANES])K[1], (const double (*)[SP_LANES])f, fresh, t_end, ha, d1,
                                 (const double (*)[SP_LANES])sc, w->h);
        }
        int active = 0;
        for (int l = 0; l < SP_LANES; l++) active += w->cell[l] >= 0;
        if (!active) { status = SP_STATUS_SUCCESS; break; }
        if (it >= budget) { status = SP_CALL_BUDGET; break; }

        /* one trial step in every lane (idle or failing lanes: h = 0) */
        for (int l = 0; l < SP_LANES; l++) {
            H[l] = 0.0;
            tnew[l] = w->t[l];
            fail[l] = 0;
            if (w->cell[l] < 0) continue;
            double min_step = 10.0 * (nextafter(w->t[l], INFINITY) - w->t[l]);
            if (!(w->h[l] >= min_step) || w->nacc[l] + w->nrej[l] >= max_steps) { fail[l] = 1; continue; }
            tnew[l] = w->t[l] + w->h[l];
            if (tnew[l] >= t_end) tnew[l] = t_end;
            H[l] = tnew[l] - w->t[l];
        }
        memcpy(K[0], f, sizeof(f));
        for (int s = 1; s < DOP_NS; s++) {
            flip_stage_arg((const double (*)[SP_LANES])y, H, &T, s, (const double (*)[SP_FLIP_N][SP_LANES])K, ytmp);
            flip_rhs((const double (*)[SP_LANES])ytmp, pp, K[s]);
        }
        flip_stage_arg((const double (*)[SP_LANES])y, H, &T, DOP_NS, (const double (*)[SP_FLIP_N][SP_LANES])K, ynew);
        flip_rhs((const double (*)[SP_LANES])ynew, pp, K[DOP_NS]);
        flip_error_norm((const double (*)[SP_LANES])y, (const double (*)[SP_LANES])ynew,
                        (const double (*)[SP_FLIP_N][SP_LANES])K, &T, H, rtol, atol, e5, e3, err, root, bad);
        int nevent = 0;
        for (int l = 0; l < SP_LANES; l++) {
            event[l] = accept[l] = 0;
            if (w->cell[l] < 0 || fail[l]) continue;
            int nonfinite = !isfinite(bad[l]) || !isfinite(e5[l]) || !isfinite(e3[l]);
            if (nonfinite) err[l] = INFINITY;
            else if (e5[l] == 0.0 && e3[l] == 0.0) err[l] = 0.0;
            if (err[l] < 1.0) {
                const double fac = DOP_FACTOR_ACCEPTED(err[l], SP_FLIP_SAFETY / root[l], w->last_rejected[l]);
                w->h[l] = H[l] * fac;
                w->last_rejected[l] = 0;
                w->nacc[l]++;
                accept[l] = 1;
                /* did an angle reach pi in this step, or turn around close to it? */
                for (int c = 0; c < 2; c++) {
                    double q0 = fabs(y[c][l]), q1 = fabs(ynew[c][l]), v0 = y[2 + c][l], v1 = ynew[2 + c][l];
                    if (q1 >= pi) event[l] |= 1 << c;
                    else if (v0 * v1 <= 0.0 && fmax(q0, q1) + H[l] * fmax(fabs(v0), fabs(v1)) >= pi) event[l] |= 4 << c;
                }
                nevent += event[l] != 0;
            } else {
                const double fac = DOP_FACTOR_REJECTED(nonfinite, SP_FLIP_SAFETY / root[l]);
                w->h[l] = H[l] * fac;
                w->last_rejected[l] = 1;
                w->nrej[l]++;
            }
        }
        if (nevent) {
            /* the dense output's 3 extra stages (computed in every lane, used where there is an event) */
            for (int s = DOP_NS + 1; s < DOP_NSTAGES; s++) {
                flip_stage_arg((const double (*)[SP_LANES])y, H, &T, s, (const double (*)[SP_FLIP_N][SP_LANES])K, ytmp);
                flip_rhs((const double (*)[SP_LANES])ytmp, pp, K[s]);
            }
            for (int l = 0; l < SP_LANES; l++) {
                if (!event[l]) continue;
                double best = INFINITY;
                int who = -1;
                for (int c = 0; c < 2; c++) {
                    if (!(event[l] & (5 << c))) continue;
                    double F[7], h = H[l];
                    dop_dense_component(y[c][l], ynew[c][l], h, &K[0][c][l], SP_FLIP_N * SP_LANES, F, 1);
                    double x = flip_locate(y[c][l], F, h, (event[l] >> c) & 1);
                    if (x >= 0.0 && w->t[l] + x * h < best) { best = w->t[l] + x * h; who = c; }
                }
                if (who >= 0) {
                    int64_t c = w->cell[l];
                    tflip[c] = fmin(best, tnew[l]);
                    which[c] = who;
                    naccept[c] = w->nacc[l];
                    nreject[c] = w->nrej[l];
                    w->cell[l] = -1;
                }
            }
        }
        /* advance the accepted lanes; finish those at t_end, or failed */
        for (int i = 0; i < n; i++)
            SP_LANE_LOOP {
                y[i][l] = accept[l] ? ynew[i][l] : y[i][l];
                f[i][l] = accept[l] ? K[DOP_NS][i][l] : f[i][l];
            }
        for (int l = 0; l < SP_LANES; l++) {
            int64_t c = w->cell[l];
            if (c < 0) continue;
            if (accept[l]) w->t[l] = tnew[l];
            if (fail[l] || w->t[l] >= t_end) {
                tflip[c] = NAN;
                which[c] = fail[l] ? -2 : -1;
                naccept[c] = w->nacc[l];
                nreject[c] = w->nrej[l];
                w->cell[l] = -1;
            }
        }
    }
    memcpy(w->y, y, sizeof(y));
    memcpy(w->f, f, sizeof(f));
    return status;
}
#ifdef SP_CAPTURE_LANES
/* ---- regions of attraction: the closed loop of a feedback law over SP_LANES starts at once -------------
 *
 * Contract with the code generator (kernel_source.capture_c_source): cap_prepare, cap_rhs (flip_rhs's
 * trigonometry-free state, with the joint inputs u[2][SP_LANES] added to the torques) and cap_init (a
 * start (phi, psi, dphi, dpsi) as that state).
 *
 * sp_capture_lanes does what sp_capture_many does for the feedback law u = clip(u* - K dx) (angles of
 * dx wrapped to [-pi, pi)), with sp_flip's lanes: each lane carries one start with its own time, step
 * size and accept/reject decisions, DOP853 with sp_flip's error norm (over the 8 components) and
 * step-size rule, each step stopped at the law's switches (cap_switch, below); a lane whose start is
 * captured, reaches t_end or fails takes the next start.  After each accepted step the region
 * dx' P dx < rho is tested at the step's end, and where it holds the entry is located by bisection on
 * the 7th-order dense output (the 3 extra stages computed only when a lane needs them).  Element-wise IEEE arithmetic in fixed-trip lane loops: a start's result is
 * bitwise the same whichever lane, call or instruction set computes it.  Resumable like sp_flip
 * (a zeroed sp_capture_ws, at most `budget` steps per call; -1 call again, 0 all done).
 * Per start: time (NaN: not captured by t_end, or failed), steps (accepted + rejected), status
 * (SP_STATUS_*). */
typedef struct {
    int64_t started, next;
    int64_t cell[SP_LANES];
    double t[SP_LANES], h[SP_LANES];
    int64_t nacc[SP_LANES], nrej[SP_LANES], last_rejected[SP_LANES], nonfinite[SP_LANES], cut[SP_LANES];
    double y[SP_FLIP_N][SP_LANES];
    double f[SP_FLIP_N][SP_LANES];
    double pp[SP_CAP_NPP];
} sp_capture_ws;

int64_t sp_capture_ws_size(void) { return (int64_t)sizeof(sp_capture_ws); }

/* floor(q), exactly, in IEEE additions and comparisons that vectorise (GCC does not vectorise floor
 * without -ffast-math): (q + 1.5 2^52) - 1.5 2^52 is q rounded to an integer, for |q| < 2^51 (larger
 * doubles are integers already) */
static inline __attribute__((always_inline)) double cap_floor(double q)
{
    const double M = 6755399441055744.0;
    double r = (q + M) - M;
    r = r > q ? r - 1.0 : r;
    return fabs(q) < 2251799813685248.0 ? r : q;
}

#define CAP_INV_TWO_PI 0.15915494309189535 /* 1 / (2 pi): a product, not a division, in every evaluation of the law */

/* x wrapped to [-pi, pi) (up to rounding at the ends), in lane loops (not fmod: it does not vectorise) */
static inline __attribute__((always_inline)) double cap_wrap(double x)
{
    const double pi = 3.141592653589793, two_pi = 6.283185307179586;
    const double w = x + pi;
    return (w - two_pi * cap_floor(w * CAP_INV_TWO_PI)) - pi;
}

/* the feedback law's inputs u[2][SP_LANES] at the states y */
static inline __attribute__((always_inline)) void cap_law(const sp_control *restrict c, const double (*restrict y)[SP_LANES],
                                                          double (*restrict u)[SP_LANES])
{
    const double K0 = c->K[0], K1 = c->K[1], K2 = c->K[2], K3 = c->K[3];
    const double K4 = c->K[4], K5 = c->K[5], K6 = c->K[6], K7 = c->K[7];
    const double x0 = c->xs[0], x1 = c->xs[1], x2 = c->xs[2], x3 = c->xs[3];
    const double us0 = c->us[0], us1 = c->us[1], U0 = c->umax[0], U1 = c->umax[1];
    const double on0 = (c->actuated & 1) ? 1.0 : 0.0, on1 = (c->actuated & 2) ? 1.0 : 0.0;
    SP_LANE_LOOP {
        const double d0 = cap_wrap(y[0][l] - x0), d1 = cap_wrap(y[1][l] - x1), d2 = y[2][l] - x2, d3 = y[3][l] - x3;
        double a = us0, b = us1;
        a = a - K0 * d0; a = a - K1 * d1; a = a - K2 * d2; a = a - K3 * d3;
        b = b - K4 * d0; b = b - K5 * d1; b = b - K6 * d2; b = b - K7 * d3;
        a = on0 * a; b = on1 * b;  /* a joint not actuated gets 0 */
        a = a > U0 ? U0 : a; a = a < -U0 ? -U0 : a;
        b = b > U1 ? U1 : b; b = b < -U1 ? -U1 : b;
        u[0][l] = a;
        u[1][l] = b;
    }
}

/* the closed loop's y' at the states y, every lane */
static inline __attribute__((always_inline)) void cap_f(const sp_control *restrict c, const double (*restrict y)[SP_LANES],
                                                        const double *restrict pp, double (*restrict out)[SP_LANES])
{
    double u[2][SP_LANES];
    cap_law(c, y, u);
    cap_rhs(y, (const double (*)[SP_LANES])u, pp, out);
}

/* dx' P dx (angles wrapped) of one state given by its 4 first components */
static inline double cap_region1(const sp_control *c, const double *P, double q0, double q1, double v0, double v1)
{
    const double dx[4] = {cap_wrap(q0 - c->xs[0]), cap_wrap(q1 - c->xs[1]), v0 - c->xs[2], v1 - c->xs[3]};
    double v = 0.0;
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) v = v + dx[i] * P[4 * i + j] * dx[j];
    return v;
}

/* The law's switches as events (issue 28): the wrap's jumps (an angle error through +-pi, where the
 * feedback jumps) and the saturation kinks (raw_r = u*_r - K_r dx = +-umax_r).  A DOP853 step across
 * one is inaccurate (the method's order assumes a smooth right-hand side), so the error control
 * rejects it and shrinks the step blindly, several times around every switch.  Instead each step
 * stops at the switch:
 *   - before a trial, the switch functions are evaluated at both ends of the Euler step y + h f: if
 *     a saturation function changes sign, the trial is cut to the fraction theta of h where the
 *     chord crosses zero (if theta > CAP_PREDICT_MIN: a switch closer than that is at the step's
 *     start, stepped over; not for a wrap's jump: a step that starts just before a jump carries the
 *     old branch's F(y) into its stages, and at tight tolerances is then rejected down to the
 *     step-size underflow -- the jumps are left to the rejections below),
 *     but not right after a trial cut so (a trajectory that only grazes a switch surface, turning
 *     back before it, would otherwise be cut ever shorter, halfway to the touching point each time:
 *     Zeno steps down to the step-size underflow);
 *   - a rejected trial that crossed a switch is tried again up to the chord's crossing on that
 *     trial (at most CAP_SWITCH_MAX of it, so a chord that misses converges; at least
 *     CAP_SWITCH_MIN x the usual rejection factor), not counted as a rejection for the growth of
 *     the next step.
 * The step to the switch lies on one branch of the law and is accepted; the next one starts on the
 * switch, where the right-hand side is continuous (a kink) or its jump is crossed within a tiny
 * first part of the step.  The error control still decides every step, so the solution is the
 * same to the tolerance -- with fewer steps (the 128 x 128 map of bench_roa: 13 % fewer at 1e-8,
 * 9 % fewer at 1e-12) and capture times closer to a tight reference (tests/test_roa.py).  cap_switch gives theta in (0, 1)
 * per lane, or -1 where no switch function changes sign between y and ynew; where an angle error
 * jumps in the step, only the jumps count (the raw inputs are not continuous across it). */
#define CAP_PREDICT_MIN 0.001
#define CAP_SWITCH_MAX 0.9
#define CAP_SWITCH_MIN 0.1
static inline __attribute__((always_inline)) void cap_switch(const sp_control *restrict c,
                                                             const double (*restrict y)[SP_LANES],
                                                             const double (*restrict ynew)[SP_LANES],
                                                             double *restrict theta, int *restrict jumps)
{
    const double pi = 3.141592653589793, two_pi = 6.283185307179586;
    const double K0 = c->K[0], K1 = c->K[1], K2 = c->K[2], K3 = c->K[3];
    const double K4 = c->K[4], K5 = c->K[5], K6 = c->K[6], K7 = c->K[7];
    const double x0 = c->xs[0], x1 = c->xs[1], x2 = c->xs[2], x3 = c->xs[3];
    const double us0 = c->us[0], us1 = c->us[1], U0 = c->umax[0], U1 = c->umax[1];
    const double on0 = (c->actuated & 1) ? 1.0 : 0.0, on1 = (c->actuated & 2) ? 1.0 : 0.0;
    double k[4][SP_LANES], g[4][2][SP_LANES], any[SP_LANES];
    /* first, without a division, every lane: the branch k of each angle error (unwrapped) at both
     * ends, the saturation functions raw_r -+ umax_r at both ends, and whether anything changed */
    SP_LANE_LOOP {
        const double a0 = y[0][l] - x0, a1 = ynew[0][l] - x0, b0 = y[1][l] - x1, b1 = ynew[1][l] - x1;
        const double ka0 = cap_floor((a0 + pi) * CAP_INV_TWO_PI), ka1 = cap_floor((a1 + pi) * CAP_INV_TWO_PI);
        const double kb0 = cap_floor((b0 + pi) * CAP_INV_TWO_PI), kb1 = cap_floor((b1 + pi) * CAP_INV_TWO_PI);
        const double e00 = ((a0 + pi) - two_pi * ka0) - pi, e01 = ((b0 + pi) - two_pi * kb0) - pi;
        const double e10 = ((a1 + pi) - two_pi * ka1) - pi, e11 = ((b1 + pi) - two_pi * kb1) - pi;
        const double v00 = y[2][l] - x2, v01 = y[3][l] - x3, v10 = ynew[2][l] - x2, v11 = ynew[3][l] - x3;
        double r00 = us0, r01 = us1, r10 = us0, r11 = us1;
        r00 = r00 - K0 * e00; r00 = r00 - K1 * e01; r00 = r00 - K2 * v00; r00 = r00 - K3 * v01;
        r01 = r01 - K4 * e00; r01 = r01 - K5 * e01; r01 = r01 - K6 * v00; r01 = r01 - K7 * v01;
        r10 = r10 - K0 * e10; r10 = r10 - K1 * e11; r10 = r10 - K2 * v10; r10 = r10 - K3 * v11;
        r11 = r11 - K4 * e10; r11 = r11 - K5 * e11; r11 = r11 - K6 * v10; r11 = r11 - K7 * v11;
        k[0][l] = ka0; k[1][l] = ka1; k[2][l] = kb0; k[3][l] = kb1;
        g[0][0][l] = on0 * (r00 - U0); g[0][1][l] = on0 * (r10 - U0);  /* 0 * 0: an unactuated joint never switches */
        g[1][0][l] = on0 * (r00 + U0); g[1][1][l] = on0 * (r10 + U0);
        g[2][0][l] = on1 * (r01 - U1); g[2][1][l] = on1 * (r11 - U1);
        g[3][0][l] = on1 * (r01 + U1); g[3][1][l] = on1 * (r11 + U1);
        double ch = ka0 != ka1 ? 1.0 : 0.0;  /* selects, not branches: the loop vectorises */
        ch = kb0 != kb1 ? 1.0 : ch;
        ch = (g[0][0][l] > 0.0) != (g[0][1][l] > 0.0) ? 1.0 : ch;
        ch = (g[1][0][l] > 0.0) != (g[1][1][l] > 0.0) ? 1.0 : ch;
        ch = (g[2][0][l] > 0.0) != (g[2][1][l] > 0.0) ? 1.0 : ch;
        ch = (g[3][0][l] > 0.0) != (g[3][1][l] > 0.0) ? 1.0 : ch;
        any[l] = ch;
    }
    /* then, where something changed (a few steps in a hundred), the fraction of the step */
    for (int l = 0; l < SP_LANES; l++) {
        theta[l] = -1.0;
        jumps[l] = 0;
        if (any[l] == 0.0) continue;
        double th = 2.0;
        int jump = 0;
        for (int i = 0; i < 2; i++) {
            const double k0 = k[2 * i][l], k1 = k[2 * i + 1][l], d0 = y[i][l] - c->xs[i], d1 = ynew[i][l] - c->xs[i];
            if (k0 != k1 && d1 != d0) {
                const double t = (two_pi * fmax(k0, k1) - pi - d0) / (d1 - d0);
                jump = 1;
                if (t > 0.0 && t < th) th = t;
            }
        }
        if (!jump) /* the raw inputs are continuous only where no angle error jumps */
            for (int q = 0; q < 4; q++) {
                const double g0 = g[q][0][l], g1 = g[q][1][l];
                if ((g0 > 0.0) != (g1 > 0.0) && g0 != g1) {
                    const double t = g0 / (g0 - g1);
                    if (t > 0.0 && t < th) th = t;
                }
            }
        theta[l] = th < 1.0 ? th : -1.0;
        jumps[l] = jump;
    }
}

SP_MULTIVERSION
int sp_capture_lanes(sp_capture_ws *w, const sp_control *c, const double *p, const double *starts, int64_t m,
                     double t_end, double rtol, double atol, int64_t max_steps, const double *P, double rho,
                     int64_t budget, double *time, int64_t *steps, int64_t *rejected, int8_t *status)
{
    const int n = SP_FLIP_N;
    double y[SP_FLIP_N][SP_LANES], f[SP_FLIP_N][SP_LANES], ynew[SP_FLIP_N][SP_LANES], ytmp[SP_FLIP_N][SP_LANES];
    double K[DOP_NSTAGES][SP_FLIP_N][SP_LANES];
    double H[SP_LANES], tnew[SP_LANES], e5[SP_LANES], e3[SP_LANES], bad[SP_LANES], err[SP_LANES], root[SP_LANES];
    double vend[SP_LANES];
    int accept[SP_LANES], fail[SP_LANES], event[SP_LANES];
    flip_tables T;
    if (m < 0 || !(t_end > 0.0) || !(rtol > 0.0) || !(atol > 0.0) || budget < 1 || c->kind != SP_CTL_FEEDBACK)
        return SP_CALL_BAD_ARGUMENTS;
    flip_tables_init(&T);
    if (!w->started) {
        cap_prepare(p, w->pp);
        for (int l = 0; l < SP_LANES; l++) w->cell[l] = -1;
        w->next = 0;
        w->started = 1;
    }
    const double *pp = w->pp;
    memcpy(y, w->y, sizeof(y));
    memcpy(f, w->f, sizeof(f));
    int rc;
    for (int64_t it = 0;; it++) {
        /* idle lanes take the next starts (one inside the region at once is captured at t = 0) */
        int fresh[SP_LANES], nfresh = 0;
        for (int l = 0; l < SP_LANES; l++) {
            fresh[l] = 0;
            while (w->cell[l] < 0 && w->next < m) {
                int64_t k = w->next++;
                const double *x = starts + 4 * k;
                steps[k] = rejected[k] = 0;
                if (!(isfinite(x[0]) && isfinite(x[1]) && isfinite(x[2]) && isfinite(x[3]))) {
                    time[k] = NAN;
                    status[k] = SP_STATUS_NONFINITE;
                    continue;
                }
                if (cap_region1(c, P, x[0], x[1], x[2], x[3]) < rho) {
                    time[k] = 0.0;
                    status[k] = SP_STATUS_SUCCESS;
                    continue;
                }
                double y0[SP_FLIP_N];
                cap_init(x, y0);
                for (int i = 0; i < n; i++) y[i][l] = y0[i];
                w->cell[l] = k;
                w->t[l] = 0.0;
                w->h[l] = 0.0;
                w->nacc[l] = w->nrej[l] = w->last_rejected[l] = w->nonfinite[l] = w->cut[l] = 0;
                fresh[l] = 1;
                nfresh++;
            }
        }
        if (nfresh) {
            double ha[SP_LANES], d1[SP_LANES], sc[SP_FLIP_N][SP_LANES];
            int dropped[SP_LANES];
            cap_f(c, (const double (*)[SP_LANES])y, pp, K[0]);
            lanes_first_step_begin((const double (*)[SP_LANES])y, (const double (*)[SP_LANES])K[0], f, fresh, dropped,
                                   rtol, atol, t_end, ha, d1, sc, ytmp, w->h);
            SP_LANE_LOOP if (dropped[l]) w->nonfinite[l] = 1;
            cap_f(c, (const double (*)[SP_LANES])ytmp, pp, K[1]);
            lanes_first_step_end((const double (*)[SP_LANES])K[1], (const double (*)[SP_LANES])f, fresh, t_end, ha, d1,
                                 (const double (*)[SP_LANES])sc, w->h);
        }
        int active = 0;
        for (int l = 0; l < SP_LANES; l++) active += w->cell[l] >= 0;
        if (!active) { rc = SP_STATUS_SUCCESS; break; }
        if (it >= budget) { rc = SP_CALL_BUDGET; break; }

        /* one trial step in every lane (idle or failing lanes: h = 0) */
        for (int l = 0; l < SP_LANES; l++) {
            H[l] = 0.0;
            tnew[l] = w->t[l];
            fail[l] = 0;
            if (w->cell[l] < 0) continue;
            double min_step = 10.0 * (nextafter(w->t[l], INFINITY) - w->t[l]);
            if (w->nacc[l] + w->nrej[l] >= max_steps) { fail[l] = SP_STATUS_MAX_STEPS; continue; }
            if (!(w->h[l] >= min_step)) {
                fail[l] = w->nonfinite[l] ? SP_STATUS_NONFINITE : SP_STATUS_STEP_UNDERFLOW;
                continue;
            }
            H[l] = w->h[l];
        }
        {   /* a switch of the law predicted inside the step (on the Euler step): stop the step there */
            double yp[4][SP_LANES], th[SP_LANES];
            int jp[SP_LANES];
            for (int i = 0; i < 4; i++) SP_LANE_LOOP yp[i][l] = y[i][l] + H[l] * f[i][l];
            cap_switch(c, y, (const double (*)[SP_LANES])yp, th, jp);
            for (int l = 0; l < SP_LANES; l++) {
                if (!(H[l] > 0.0)) continue;
                const int cut = th[l] > CAP_PREDICT_MIN && !jp[l] && !w->cut[l];  /* kinks only, never twice in a row */
                const double hl = cut ? H[l] * th[l] : H[l];
                w->cut[l] = cut;
                tnew[l] = w->t[l] + hl;
                if (tnew[l] >= t_end) tnew[l] = t_end;
                H[l] = tnew[l] - w->t[l];
            }
        }
        memcpy(K[0], f, sizeof(f));
        for (int s = 1; s < DOP_NS; s++) {
            flip_stage_arg((const double (*)[SP_LANES])y, H, &T, s, (const double (*)[SP_FLIP_N][SP_LANES])K, ytmp);
            cap_f(c, (const double (*)[SP_LANES])ytmp, pp, K[s]);
        }
        flip_stage_arg((const double (*)[SP_LANES])y, H, &T, DOP_NS, (const double (*)[SP_FLIP_N][SP_LANES])K, ynew);
        cap_f(c, (const double (*)[SP_LANES])ynew, pp, K[DOP_NS]);
        flip_error_norm((const double (*)[SP_LANES])y, (const double (*)[SP_LANES])ynew,  /* as sp_flip */
                        (const double (*)[SP_FLIP_N][SP_LANES])K, &T, H, rtol, atol, e5, e3, err, root, bad);
        /* the region at each step's end, every lane */
        double Pr[16];
        memcpy(Pr, P, sizeof Pr);
        SP_LANE_LOOP {
            const double dx0 = cap_wrap(ynew[0][l] - c->xs[0]), dx1 = cap_wrap(ynew[1][l] - c->xs[1]);
            const double dx2 = ynew[2][l] - c->xs[2], dx3 = ynew[3][l] - c->xs[3];
            const double dx[4] = {dx0, dx1, dx2, dx3};
            double v = 0.0;
#pragma GCC unroll 4
            for (int i = 0; i < 4; i++)
#pragma GCC unroll 4
                for (int j = 0; j < 4; j++) v = v + dx[i] * Pr[4 * i + j] * dx[j];
            vend[l] = v;
        }
        double thsw[SP_LANES];
        int jsw[SP_LANES];
        cap_switch(c, y, (const double (*)[SP_LANES])ynew, thsw, jsw);
        int nevent = 0;
        for (int l = 0; l < SP_LANES; l++) {
            event[l] = accept[l] = 0;
            if (w->cell[l] < 0 || fail[l]) continue;
            int nonfinite = !isfinite(bad[l]) || !isfinite(e5[l]) || !isfinite(e3[l]);
            w->nonfinite[l] = nonfinite;
            if (nonfinite) err[l] = INFINITY;
            else if (e5[l] == 0.0 && e3[l] == 0.0) err[l] = 0.0;
            if (err[l] < 1.0) {
                const double fac = DOP_FACTOR_ACCEPTED(err[l], SP_FLIP_SAFETY / root[l], w->last_rejected[l]);
                w->h[l] = H[l] * fac;
                w->last_rejected[l] = 0;
                w->nacc[l]++;
                accept[l] = 1;
                if (vend[l] < rho) { event[l] = 1; nevent++; }
            } else {
                const double fac = DOP_FACTOR_REJECTED(nonfinite, SP_FLIP_SAFETY / root[l]);
                const double theta = nonfinite ? -1.0 : thsw[l];
                if (theta > 0.0) {
                    /* the trial crossed a switch of the law: try again up to (about) the switch */
                    w->h[l] = H[l] * fmax(fmin(theta, CAP_SWITCH_MAX), fac * CAP_SWITCH_MIN);
                    w->last_rejected[l] = 0;
                } else {
                    w->h[l] = H[l] * fac;
                    w->last_rejected[l] = 1;
                }
                w->nrej[l]++;
            }
        }
        if (nevent) {
            /* entered during this step: the dense output's 3 extra stages (every lane), then the first
             * point inside by bisection, lane by lane */
            for (int s = DOP_NS + 1; s < DOP_NSTAGES; s++) {
                flip_stage_arg((const double (*)[SP_LANES])y, H, &T, s, (const double (*)[SP_FLIP_N][SP_LANES])K, ytmp);
                cap_f(c, (const double (*)[SP_LANES])ytmp, pp, K[s]);
            }
            for (int l = 0; l < SP_LANES; l++) {
                if (!event[l]) continue;
                double F[7][4], h = H[l], lo = 0.0, hi = 1.0;
                for (int i = 0; i < 4; i++)
                    dop_dense_component(y[i][l], ynew[i][l], h, &K[0][i][l], SP_FLIP_N * SP_LANES, &F[0][i], 4);
                for (int k2 = 0; k2 < 60 && (hi - lo) * h > 1e-14 * fmax(1.0, tnew[l]); k2++) {
                    double mid = 0.5 * (lo + hi), z[4];
                    int finite = 1;
                    for (int i = 0; i < 4; i++) {
                        z[i] = dop_dense_value(y[i][l], &F[0][i], 4, mid);
                        if (!isfinite(z[i])) finite = 0;
                    }
                    if (finite && cap_region1(c, P, z[0], z[1], z[2], z[3]) < rho) hi = mid; else lo = mid;
                }
                int64_t k = w->cell[l];
                time[k] = w->t[l] + hi * h;
                steps[k] = w->nacc[l];
                rejected[k] = w->nrej[l];
                status[k] = SP_STATUS_SUCCESS;
                w->cell[l] = -1;
            }
        }
        /* advance the accepted lanes; finish those at t_end, or failed */
        for (int i = 0; i < n; i++)
            SP_LANE_LOOP {
                y[i][l] = accept[l] ? ynew[i][l] : y[i][l];
                f[i][l] = accept[l] ? K[DOP_NS][i][l] : f[i][l];
            }
        for (int l = 0; l < SP_LANES; l++) {
            int64_t k = w->cell[l];
            if (k < 0) continue;
            if (accept[l]) w->t[l] = tnew[l];
            if (fail[l] || w->t[l] >= t_end) {
                time[k] = NAN;
                steps[k] = w->nacc[l];
                rejected[k] = w->nrej[l];
                status[k] = (int8_t)(fail[l] ? fail[l] : SP_STATUS_SUCCESS);
                w->cell[l] = -1;
            }
        }
    }
    memcpy(w->y, y, sizeof(y));
    memcpy(w->f, f, sizeof(f));
    return rc;
}
#endif /* SP_CAPTURE_LANES */
#endif /* SP_FLIP_KERNEL */
