/*
 * blowup: a test FMU whose output overflows to infinity mid-run while every
 * FMI call returns fmi2OK, as a model without checks of its own does when it
 * diverges: the master alone must notice.
 *
 *   y = exp(rate * t)       rate: default 1000 1/s, so y is infinite from t = 0.71 s on
 *
 * Why it exists: the native loop's divergence checks (tests/simulation/test_native_loop.py)
 * for one FMU alone and for FMUs that feed nothing to each other.
 */
#include <math.h>

#include "slave.h"

enum Real { RATE, Y, N_REALS };

static const double DEFAULTS[N_REALS] = {1000.0, 1.0};

static int exit_initialization(Slave *s) {
    s->r[Y] = 1.0;
    return 0;
}

static int do_step(Slave *s, double t, double h) {
    s->r[Y] = exp(s->r[RATE] * (t + h));
    return 0;
}

const ModelInfo MODEL = {
    .guid = "{3e8f5b2a-7c1d-4f6e-9b0a-5d2c8e4f1a73}",
    .n_reals = N_REALS,
    .real_defaults = DEFAULTS,
    .exit_initialization = exit_initialization,
    .do_step = do_step,
};
