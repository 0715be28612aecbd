/* A bouncing ball (model exchange, me2.c): a bounce is a state event, a kick a time event. */
#include "me2.h"

enum Real { H, V, DER_H, DER_V, G, E, KICK_TIME, KICK, KICKED, N_REALS };
static const double DEFAULTS[N_REALS] = {1.0, 0.0, 0.0, 0.0, 9.81, 0.7, 0.9, 6.0, 0.0};
static const fmi2ValueReference STATES[] = {H, V}, DERIVATIVES[] = {DER_H, DER_V};

static int equations(MeInstance *m) {
    m->r[DER_H] = m->r[V];
    m->r[DER_V] = -m->r[G];
    return 0;
}

static int indicators(MeInstance *m, double z[]) {
    z[0] = m->r[H];
    return 0;
}

/* A bounce is a state event; the upward kick at KICK_TIME is a time event. */
static int update(MeInstance *m, MeEvent *e) {
    double *r = m->r;
    if (r[H] <= 0.0 && r[V] < 0.0) {
        r[H] = 0.0;
        r[V] = -r[E] * r[V];
        e->states_changed = 1;
    }
    if (!r[KICKED] && m->time >= r[KICK_TIME] - 1e-12) {
        r[V] += r[KICK];
        r[KICKED] = 1.0;
        e->states_changed = 1;
    }
    e->next_time_defined = !r[KICKED];
    e->next_time = r[KICK_TIME];
    return 0;
}

const MeInfo ME_MODEL = {
    .guid = "{5c1f2a9e-0d7b-4e63-9a48-3b2e6f1d7c05}", .n_reals = N_REALS, .real_defaults = DEFAULTS,
    .n_states = 2, .states = STATES, .derivatives = DERIVATIVES, .n_event_indicators = 1,
    .equations = equations, .event_indicators = indicators, .event_update = update,
};
