/*
 * wild_dual_cs: the co-simulation half of a test FMU offering both FMI 2.0
 * interfaces (see wild_dual_me/model.c).  Each step uses the exact solution
 * of x' = -a x, so it differs from the model-exchange half by the solver's
 * error only.
 *
 *   x = x0 exp(-a t),  der(x) = -a x
 *   me = 0                         (wild_dual_me sets it to 1)
 */
#include <math.h>

#include "slave.h"

enum Real { A, X0, X, DER_X, ME, N_REALS };

static const double DEFAULTS[N_REALS] = {1.0, 1.0, 1.0, 0.0, 0.0};

static int exit_initialization(Slave *s) {
    s->r[X] = s->r[X0];
    s->r[DER_X] = -s->r[A] * s->r[X];
    s->r[ME] = 0.0;
    return 0;
}

static int do_step(Slave *s, double t, double h) {
    (void)t;
    s->r[X] *= exp(-s->r[A] * h);
    s->r[DER_X] = -s->r[A] * s->r[X];
    return 0;
}

const ModelInfo MODEL = {
    .guid = "{6f0c1f7e-2a4b-4d8e-9a55-0d7c3b9e1a21}",
    .n_reals = N_REALS,
    .real_defaults = DEFAULTS,
    .exit_initialization = exit_initialization,
    .do_step = do_step,
};
