/*
 * controller: the on/off level controller of the classic INTO-CPS water-tank
 * example, as an FMI 2.0 co-simulation FMU.  It opens the tank's valve when
 * the level reaches maxlevel and closes it when the level falls to minlevel;
 * in between it keeps the valve as it is (hysteresis), so the tank
 * oscillates between the two thresholds.  The valve starts closed.
 *
 * valve is a Boolean; a master wiring it to the tank's Real valvecontrol
 * passes it as 1 (open) / 0 (closed).  The level read at the start of a step
 * decides the valve from the end of that step: one step of delay, as a
 * sampled controller has.
 */
#include "slave.h"

enum Real { LEVEL, MINLEVEL, MAXLEVEL, N_REALS };
enum Boolean { VALVE, N_BOOLEANS };

static const double REAL_DEFAULTS[N_REALS] = {0.0, 1.0, 2.0};
static const int BOOLEAN_DEFAULTS[N_BOOLEANS] = {0};

static int exit_initialization(Slave *s) {
    if (!(s->r[MINLEVEL] < s->r[MAXLEVEL])) {
        slave_log(s, fmi2Error, "logStatusError", "minlevel (%g m) must be below maxlevel (%g m)",
                  s->r[MINLEVEL], s->r[MAXLEVEL]);
        return 1;
    }
    return 0;
}

static int do_step(Slave *s, double t, double h) {
    (void)t;
    (void)h;
    if (s->r[LEVEL] >= s->r[MAXLEVEL])
        s->b[VALVE] = fmi2True;
    else if (s->r[LEVEL] <= s->r[MINLEVEL])
        s->b[VALVE] = fmi2False;
    return 0;
}

const ModelInfo MODEL = {
    .guid = "{fd829735-7d78-4a03-a02c-00e60681fdf4}",
    .n_reals = N_REALS,
    .real_defaults = REAL_DEFAULTS,
    .n_booleans = N_BOOLEANS,
    .boolean_defaults = BOOLEAN_DEFAULTS,
    .exit_initialization = exit_initialization,
    .do_step = do_step,
};
