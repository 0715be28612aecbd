/*
 * stair3: stair2 in FMI 3.0 co-simulation.  Its Int32 output counter is 1 at
 * the start and goes up by one at every whole second; its Float64 output ramp
 * is the time.  The step that reaches the parameter stop_at (default 9) sets
 * fmi3DoStep's terminateSimulation (slave3.c, fmi_ask_to_stop).
 */
#include <math.h>

#include "slave3.h"

enum Float64 { STOP_AT, RAMP, N_FLOAT64 };
enum Int32 { COUNTER, N_INT32 };

/* Value references as in modelDescription.xml, in its order. */
static const Variable3 VARIABLES[] = {
    {.vr = 0, .type = V3_TIME},
    {.vr = 1, .type = V3_FLOAT64, .index = STOP_AT, .start = 9.0},
    {.vr = 2, .type = V3_FLOAT64, .index = RAMP},
    {.vr = 3, .type = V3_INT32, .index = COUNTER, .start = 1},
};

/* The outputs at time t. */
static int outputs(Slave3 *s, double t) {
    s->f64[RAMP] = t;
    s->i32[COUNTER] = 1 + (int)floor(t + 1e-9);
    return 0;
}

static int exit_initialization(Slave3 *s) { return outputs(s, s->time); }

static int do_step(Slave3 *s, double t, double h) {
    const double stop_at = s->f64[STOP_AT];
    if (t + h >= stop_at - 1e-9 * (1.0 + fabs(stop_at))) {
        fmi_ask_to_stop(&s->core, stop_at < t + h ? stop_at : t + h);
        return outputs(s, s->stop_time);
    }
    return outputs(s, t + h);
}

const ModelInfo3 MODEL = {
    .instantiation_token = "{a3d9e4f0-6c2b-4e1a-8f57-0b9c3d2e6a14}",
    .variables = VARIABLES,
    .n_variables = sizeof VARIABLES / sizeof VARIABLES[0],
    .exit_initialization = exit_initialization,
    .do_step = do_step,
};
