/*
 * tank: the water tank of the classic INTO-CPS single-tank example, as an
 * FMI 2.0 co-simulation FMU.  Water flows in at a constant rate; while the
 * valve at the bottom is open it flows out in proportion to the level:
 *
 *   area * d(level)/dt = inflow - valvecontrol * outflow_coefficient * level
 *
 * valvecontrol is 1 with the valve open and 0 with it closed (as INTO-CPS's
 * tank takes it; values between open it partly, outside [0, 1] are clamped).
 * The input is held over a step, so each step uses the exact solution of
 * this linear equation: no integration error, whatever the step size.
 *
 * Defaults: the tank fills at 0.2 m/s from 0.5 m and, open, drains towards
 * inflow / outflow_coefficient = 0.5 m.  With the controller's thresholds
 * 1 m and 2 m that is about 5 s filling and 2.7 s draining per cycle: a few
 * oscillations in a 30 s run.
 */
#include <math.h>

#include "slave.h"

enum Real { LEVEL, VALVECONTROL, INFLOW, OUTFLOW_COEFFICIENT, AREA, INITIAL_LEVEL, N_REALS };

static const double DEFAULTS[N_REALS] = {0.5, 0.0, 0.2, 0.4, 1.0, 0.5};

static int check_parameters(Slave *s) {
    if (!(s->r[AREA] > 0.0)) {
        slave_log(s, fmi2Error, "logStatusError", "area must be > 0 m2, got %g", s->r[AREA]);
        return 1;
    }
    if (!(s->r[INFLOW] >= 0.0) || !(s->r[OUTFLOW_COEFFICIENT] >= 0.0) || !(s->r[INITIAL_LEVEL] >= 0.0)) {
        slave_log(s, fmi2Error, "logStatusError",
                  "inflow, outflow_coefficient and initial_level must be >= 0, got %g, %g, %g",
                  s->r[INFLOW], s->r[OUTFLOW_COEFFICIENT], s->r[INITIAL_LEVEL]);
        return 1;
    }
    return 0;
}

static int exit_initialization(Slave *s) {
    if (check_parameters(s) != 0) return 1;
    s->r[LEVEL] = s->r[INITIAL_LEVEL];
    return 0;
}

static int do_step(Slave *s, double t, double h) {
    (void)t;
    double opening = fmin(fmax(s->r[VALVECONTROL], 0.0), 1.0);
    double fill = s->r[INFLOW] / s->r[AREA];                            /* [m/s] */
    double rate = opening * s->r[OUTFLOW_COEFFICIENT] / s->r[AREA];     /* [1/s] */
    if (rate > 0.0) {
        /* level relaxes exponentially towards the equilibrium fill / rate */
        double equilibrium = fill / rate;
        s->r[LEVEL] = equilibrium + (s->r[LEVEL] - equilibrium) * exp(-rate * h);
    } else {
        s->r[LEVEL] += fill * h;
    }
    return 0;
}

const ModelInfo MODEL = {
    .guid = "{4a65e64a-fa49-43ff-8c39-3554f72fe945}",
    .n_reals = N_REALS,
    .real_defaults = DEFAULTS,
    .exit_initialization = exit_initialization,
    .do_step = do_step,
};
