/*
 * stair_me: stair2 in FMI 2.0 model exchange (me2.c).  Its state ramp grows at
 * rate 1 (it is the time), and its output counter is 1 at the start, up by one
 * at every whole second.  A time event at the parameter stop_at (default 9)
 * asks to stop: the event update's terminateSimulation.
 */
#include <math.h>

#include "me2.h"

enum Real { RAMP, DER_RAMP, STOP_AT, COUNTER, N_REALS };
static const double DEFAULTS[N_REALS] = {0.0, 1.0, 9.0, 1.0};
static const fmi2ValueReference STATES[] = {RAMP}, DERIVATIVES[] = {DER_RAMP};

static int equations(MeInstance *m) {
    m->r[DER_RAMP] = 1.0;
    m->r[COUNTER] = 1.0 + floor(m->time + 1e-9);
    return 0;
}

/* The first event update (initialization) schedules the time event; at it, the FMU asks to stop. */
static int update(MeInstance *m, MeEvent *e) {
    const double stop_at = m->r[STOP_AT];
    e->terminate = m->time >= stop_at - 1e-9 * (1.0 + fabs(stop_at));
    e->next_time_defined = !e->terminate;
    e->next_time = stop_at;
    return 0;
}

const MeInfo ME_MODEL = {
    .guid = "{0e7c3b5a-9d21-4f68-b4a3-6c8e1f2d9a07}", .n_reals = N_REALS, .real_defaults = DEFAULTS,
    .n_states = 1, .states = STATES, .derivatives = DERIVATIVES, .n_event_indicators = 0,
    .equations = equations, .event_update = update,
};
