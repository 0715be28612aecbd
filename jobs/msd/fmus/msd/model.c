/*
 * msd: a mass-spring-damper, FMI 2.0 model exchange.
 *
 *   m x'' = F - k x - c x'      states x [m], v = x' [m/s]
 *
 * The initial position and velocity are parameters (x0, v0), so a design-space
 * exploration can fit them together with m, k and c against a recording.
 */
#include <math.h>

#include "me2.h"

enum Real { M, K, C, X0, V0, F, X, V, DER_X, DER_V, N_REALS };

static const double DEFAULTS[N_REALS] = {
    [M] = 1.0, [K] = 10.0, [C] = 0.5, [X0] = 0.1, [V0] = 0.0, [F] = 0.0,
    [X] = 0.1, [V] = 0.0, [DER_X] = 0.0, [DER_V] = 0.0,
};

static const char *const NAMES[N_REALS] = {
    "m", "k", "c", "x0", "v0", "F", "x", "v", "der(x)", "der(v)",
};

static const fmi2ValueReference STATES[] = {X, V};
static const fmi2ValueReference DERIVATIVES[] = {DER_X, DER_V};

/* The parameters are checked once, where a bad value can still be blamed on them. */
static int initial(MeInstance *m) {
    double *r = m->r;
    if (!(r[M] > 0.0) || !isfinite(r[M])) {
        me_log(m, fmi2Error, "logStatusError", "mass m must be finite and > 0, got %g", r[M]);
        return 1;
    }
    for (int i = K; i <= V0; i++)
        if (!isfinite(r[i])) {
            me_log(m, fmi2Error, "logStatusError", "parameter %s must be finite, got %g", NAMES[i], r[i]);
            return 1;
        }
    r[X] = r[X0];
    r[V] = r[V0];
    return 0;
}

static int equations(MeInstance *m) {
    double *r = m->r;
    r[DER_X] = r[V];
    r[DER_V] = (r[F] - r[K] * r[X] - r[C] * r[V]) / r[M];
    return 0;
}

const MeInfo ME_MODEL = {
    .guid = "{d3c48163-7618-432a-a9a1-da52d53577e5}",
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
