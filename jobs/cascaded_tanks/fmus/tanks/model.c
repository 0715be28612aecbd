/*
 * tanks: two tanks in cascade, the plain model a user writes first, FMI 2.0 model exchange.
 *
 *   der(x1) = -k1 sqrt(x1) + k4 u      upper tank: a pump fills it, Torricelli outflow
 *   der(x2) =  k2 sqrt(x1) - k3 sqrt(x2)   lower tank: fed by the upper one
 *   y       =  x2
 *
 * No overflow, no sensor model: what is missing is for diagnosis to find. A level below zero
 * is read as an empty tank (sqrt of 0), so a solver's trial step past empty does not fail.
 * The initial levels are parameters (x1_0, x2_0), so a study can calibrate them.
 */
#include <math.h>

#include "me2.h"

enum Real { K1, K2, K3, K4, X1_0, X2_0, U, X1, X2, Y, DER_X1, DER_X2, N_REALS };

static const double DEFAULTS[N_REALS] = {
    [K1] = 0.05, [K2] = 0.05, [K3] = 0.05, [K4] = 0.05, [X1_0] = 5.0, [X2_0] = 5.0, [U] = 0.0,
    [X1] = 5.0, [X2] = 5.0, [Y] = 5.0, [DER_X1] = 0.0, [DER_X2] = 0.0,
};

static const char *const NAMES[N_REALS] = {
    "k1", "k2", "k3", "k4", "x1_0", "x2_0", "u", "x1", "x2", "y", "der(x1)", "der(x2)",
};

static const fmi2ValueReference STATES[] = {X1, X2};
static const fmi2ValueReference DERIVATIVES[] = {DER_X1, DER_X2};

static int initial(MeInstance *m) {
    double *r = m->r;
    for (int i = K1; i <= X2_0; i++)
        if (!isfinite(r[i])) {
            me_log(m, fmi2Error, "logStatusError", "parameter %s must be finite, got %g", NAMES[i], r[i]);
            return 1;
        }
    r[X1] = r[X1_0];
    r[X2] = r[X2_0];
    return 0;
}

static double root(double level) { return level > 0.0 ? sqrt(level) : 0.0; }

static int equations(MeInstance *m) {
    double *r = m->r;
    r[DER_X1] = -r[K1] * root(r[X1]) + r[K4] * r[U];
    r[DER_X2] = r[K2] * root(r[X1]) - r[K3] * root(r[X2]);
    r[Y] = r[X2];
    return 0;
}

const MeInfo ME_MODEL = {
    .guid = "{6b0f2f7e-5a43-4c1e-9d1b-2f4e8c7a9b31}",
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
