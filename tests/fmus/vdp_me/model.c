/*
 * vdp_me: the Van der Pol oscillator as the Modelica Reference FMU VanDerPol declares it, FMI 2.0 model
 * exchange: states x0 and x1 are outputs whose start values are exact (FMI lets an importer set them before
 * initialisation), mu a parameter.
 *
 *   der(x0) = x1,   der(x1) = mu (1 - x0^2) x1 - x0
 */
#include "me2.h"

enum Real { X0, X1, MU, DER_X0, DER_X1, N_REALS };

static const double DEFAULTS[N_REALS] = {[X0] = 2.0, [X1] = 0.0, [MU] = 1.0, [DER_X0] = 0.0, [DER_X1] = 0.0};
static const char *const NAMES[N_REALS] = {"x0", "x1", "mu", "der(x0)", "der(x1)"};
static const fmi2ValueReference STATES[] = {X0, X1};
static const fmi2ValueReference DERIVATIVES[] = {DER_X0, DER_X1};

static int initial(MeInstance *m) {
    (void)m; /* the states start where their start values, or the importer, put them */
    return 0;
}

static int equations(MeInstance *m) {
    double *r = m->r;
    r[DER_X0] = r[X1];
    r[DER_X1] = r[MU] * (1.0 - r[X0] * r[X0]) * r[X1] - r[X0];
    return 0;
}

const MeInfo ME_MODEL = {
    .guid = "{8c5bb2a4-1d0e-4d57-a3e6-5b8e9f2c7d10}",
    .n_reals = N_REALS,
    .real_defaults = DEFAULTS,
    .real_names = NAMES,
    .n_states = 2,
    .states = STATES,
    .derivatives = DERIVATIVES,
    .nominals = 0,
    .n_event_indicators = 0,
    .initial = initial,
    .equations = equations,
    .event_indicators = 0,
    .event_update = 0,
};
