/*
 * ishigami: the Ishigami function, FMI 2.0 co-simulation, for proving sensitivity analysis.
 *
 *   y = sin(x1) + a sin(x2)^2 + b x3^4 sin(x1),   x1, x2, x3 uniform on [-pi, pi]
 *
 * Its Sobol' indices are known in closed form (Ishigami and Homma 1990; Sobol' and Levitan 1999),
 * so a sweep's estimates can be checked against the truth: with a = 7, b = 0.1, x2 acts alone,
 * x3 only through its interaction with x1, and x3's first-order index is exactly zero.
 * y is set at initialization and again at every step; one step costs nothing.
 */
#include <math.h>

#include "slave.h"

enum Real { X1, X2, X3, A, B, Y, N_REALS };

static const double DEFAULTS[N_REALS] = {[X1] = 0.0, [X2] = 0.0, [X3] = 0.0, [A] = 7.0, [B] = 0.1, [Y] = 0.0};

static int ishigami(Slave *s) {
    double *r = s->r;
    double s2 = sin(r[X2]), x3sq = r[X3] * r[X3];
    r[Y] = sin(r[X1]) + r[A] * s2 * s2 + r[B] * x3sq * x3sq * sin(r[X1]);
    return 0;
}

static int do_step(Slave *s, double t, double h) {
    (void)t;
    (void)h;
    return ishigami(s);
}

const ModelInfo MODEL = {
    .guid = "{4b0c6f1e-2d7a-4e59-b8c3-91f5a0d2e7b4}",
    .n_reals = N_REALS,
    .real_defaults = DEFAULTS,
    .n_strings = 0,
    .string_defaults = 0,
    .state_size = 0,
    .enter_initialization = 0,
    .exit_initialization = ishigami,
    .do_step = do_step,
    .release = 0,
};
