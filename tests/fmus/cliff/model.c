/*
 * cliff: a test FMU for searches that meet failing simulations.  Its output
 * y = (a - 3)^2 + (b - 1)^2 is a bowl over its parameters a and b with its
 * minimum 0 at a = 3, b = 1; but where a > fail_above (default 7) every
 * fmi2DoStep returns fmi2Error ("a ... is over the cliff"), as a model does
 * outside the range where it is valid.  One step costs nothing.
 */
#include "slave.h"

enum Real { A, B, FAIL_ABOVE, Y, N_REALS };

static const double DEFAULTS[N_REALS] = {0.0, 0.0, 7.0, 0.0};

static int bowl(Slave *s) {
    double da = s->r[A] - 3.0, db = s->r[B] - 1.0;
    s->r[Y] = da * da + db * db;
    return 0;
}

static int do_step(Slave *s, double t, double h) {
    (void)t;
    (void)h;
    if (s->r[A] > s->r[FAIL_ABOVE]) {
        slave_log(s, fmi2Error, "logStatusError", "a = %g is over the cliff (fail_above = %g)", s->r[A],
                  s->r[FAIL_ABOVE]);
        return 1;
    }
    return bowl(s);
}

const ModelInfo MODEL = {
    .guid = "{8e2f6c1a-4b3d-4f0e-9a7c-2d5b1e8f3c60}",
    .n_reals = N_REALS,
    .real_defaults = DEFAULTS,
    .n_strings = 0,
    .string_defaults = 0,
    .state_size = 0,
    .enter_initialization = 0,
    .exit_initialization = bowl,
    .do_step = do_step,
    .release = 0,
};
