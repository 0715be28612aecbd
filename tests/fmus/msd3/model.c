/*
 * msd3: the mass-spring-damper of jobs/msd/fmus/msd, as FMI 3.0 model exchange.
 *
 *   m x'' = F - k x - c x'      states x [m], v = x' [m/s]
 */
#include <math.h>

#include "me3.h"

enum Real { TIME, M, K, C, X0, V0, F, X, V, DER_X, DER_V, N_REALS };

static const double DEFAULTS[N_REALS] = {
    [TIME] = 0.0, [M] = 1.0, [K] = 10.0, [C] = 0.5, [X0] = 0.1, [V0] = 0.0, [F] = 0.0,
    [X] = 0.1, [V] = 0.0, [DER_X] = 0.0, [DER_V] = 0.0,
};

static const char *const NAMES[N_REALS] = {
    "time", "m", "k", "c", "x0", "v0", "F", "x", "v", "der(x)", "der(v)",
};

static const fmi3ValueReference STATES[] = {X, V};
static const fmi3ValueReference DERIVATIVES[] = {DER_X, DER_V};

static int initial(Me3Instance *m) {
    double *r = m->r;
    if (!(r[M] > 0.0) || !isfinite(r[M])) {
        me3_log(m, fmi3Error, "logStatusError", "mass m must be finite and > 0, got %g", r[M]);
        return 1;
    }
    for (int i = K; i <= V0; i++)
        if (!isfinite(r[i])) {
            me3_log(m, fmi3Error, "logStatusError", "parameter %s must be finite, got %g", NAMES[i], r[i]);
            return 1;
        }
    r[X] = r[X0];
    r[V] = r[V0];
    return 0;
}

static int equations(Me3Instance *m) {
    double *r = m->r;
    r[DER_X] = r[V];
    r[DER_V] = (r[F] - r[K] * r[X] - r[C] * r[V]) / r[M];
    return 0;
}

const Me3Info ME3_MODEL = {
    .instantiation_token = "{5b0f1c2e-3d4a-4e8b-9f6c-7a1d2e3f4b5c}",
    .n_reals = N_REALS,
    .real_defaults = DEFAULTS,
    .real_names = NAMES,
    .time_vr = TIME,
    .n_states = 2,
    .states = STATES,
    .derivatives = DERIVATIVES,
    .nominals = 0,
    .initial = initial,
    .equations = equations,
};
