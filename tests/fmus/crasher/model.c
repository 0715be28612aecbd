/*
 * crasher: a test FMU for the sweep's crash handling.  It moves along x at the
 * commanded speed, and dereferences a null pointer in its first step when its
 * parameter k equals crash_at, as a buggy FMU would: the process dies with
 * SIGSEGV, which no FMI status can report.
 */
#include "slave.h"

enum Real { X, Y, VELOCITY, K, CRASH_AT, N_REALS };

static const double DEFAULTS[N_REALS] = {0.0, 0.0, 0.0, 0.0, -1.0};

static int do_step(Slave *s, double t, double h) {
    (void)t;
    if (s->r[K] == s->r[CRASH_AT]) {
        volatile int *nowhere = 0;
        *nowhere = 1;
    }
    s->r[X] += s->r[VELOCITY] * h;
    return 0;
}

const ModelInfo MODEL = {
    .guid = "{5c0e2a51-93d4-4f7b-a1e8-6b2f0c9d7e14}",
    .n_reals = N_REALS,
    .real_defaults = DEFAULTS,
    .n_strings = 0,
    .string_defaults = 0,
    .state_size = 0,
    .enter_initialization = 0,
    .exit_initialization = 0,
    .do_step = do_step,
    .release = 0,
};
