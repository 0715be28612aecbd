/*
 * stair2: a test FMU (FMI 2.0 co-simulation) that asks to stop early, as the
 * Reference FMUs' Stair does at t = 9.  Its output counter is 1 at the start
 * and goes up by one at every whole second; its output ramp is the time.
 * Both are Real (Stair's counter is an Integer, as stair3's is), so that the
 * native loop runs this FMU alone on its single-FMU path.  When a step would
 * pass the parameter stop_at (default 9), the FMU goes only as far as stop_at
 * and asks to stop there: fmi2DoStep returns fmi2Discard, fmi2Terminated
 * reads true and fmi2LastSuccessfulTime is stop_at (slave.c, fmi_ask_to_stop).
 */
#include <math.h>

#include "slave.h"

enum Real { STOP_AT, RAMP, COUNTER, N_REALS };

static const double REAL_DEFAULTS[N_REALS] = {9.0, 0.0, 1.0};

/* The outputs at time t. */
static int outputs(Slave *s, double t) {
    s->r[RAMP] = t;
    s->r[COUNTER] = 1.0 + floor(t + 1e-9);
    return 0;
}

static int exit_initialization(Slave *s) { return outputs(s, s->time); }

static int do_step(Slave *s, double t, double h) {
    const double stop_at = s->r[STOP_AT];
    if (t + h >= stop_at - 1e-9 * (1.0 + fabs(stop_at))) {
        fmi_ask_to_stop(&s->core, stop_at < t + h ? stop_at : t + h);
        return outputs(s, s->stop_time);
    }
    return outputs(s, t + h);
}

const ModelInfo MODEL = {
    .guid = "{5b0c7e52-0d4f-4a43-9c1e-3f6a2b8d7e01}",
    .n_reals = N_REALS,
    .real_defaults = REAL_DEFAULTS,
    .exit_initialization = exit_initialization,
    .do_step = do_step,
};
