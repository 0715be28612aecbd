/*
 * pendulum: a damped pendulum driven by a torque, FMI 2.0 model exchange.
 *
 *   m l^2 w' = tau - m g l sin(theta) - b w      states theta [rad], w = theta' [rad/s]
 *
 * A point mass m on a massless rod of length l, viscous damping b at the pivot. The initial angle and
 * rate are parameters (theta0, w0), so a design-space exploration can fit them with l and b.
 */
#include <math.h>

#include "me2.h"

enum Real { M, L, B, G, THETA0, W0, TAU, THETA, W, DER_THETA, DER_W, N_REALS };

static const double DEFAULTS[N_REALS] = {
    [M] = 1.0, [L] = 1.0, [B] = 0.1, [G] = 9.81, [THETA0] = 0.0, [W0] = 0.0, [TAU] = 0.0,
    [THETA] = 0.0, [W] = 0.0, [DER_THETA] = 0.0, [DER_W] = 0.0,
};

static const char *const NAMES[N_REALS] = {
    "m", "l", "b", "g", "theta0", "w0", "tau", "theta", "w", "der(theta)", "der(w)",
};

static const fmi2ValueReference STATES[] = {THETA, W};
static const fmi2ValueReference DERIVATIVES[] = {DER_THETA, DER_W};

/* The parameters are checked once, where a bad value can still be blamed on them. */
static int initial(MeInstance *m) {
    double *r = m->r;
    if (!(r[M] > 0.0) || !isfinite(r[M]) || !(r[L] > 0.0) || !isfinite(r[L])) {
        me_log(m, fmi2Error, "logStatusError", "mass m and length l must be finite and > 0, got m=%g, l=%g",
               r[M], r[L]);
        return 1;
    }
    for (int i = B; i <= W0; i++)
        if (!isfinite(r[i])) {
            me_log(m, fmi2Error, "logStatusError", "parameter %s must be finite, got %g", NAMES[i], r[i]);
            return 1;
        }
    r[THETA] = r[THETA0];
    r[W] = r[W0];
    return 0;
}

static int equations(MeInstance *m) {
    double *r = m->r;
    double inertia = r[M] * r[L] * r[L];
    r[DER_THETA] = r[W];
    r[DER_W] = (r[TAU] - r[M] * r[G] * r[L] * sin(r[THETA]) - r[B] * r[W]) / inertia;
    return 0;
}

const MeInfo ME_MODEL = {
    .guid = "{6f1e2b0c-3d4a-4c55-9a7e-2b8d1f0c9e31}",
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
