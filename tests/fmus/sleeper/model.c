/*
 * sleeper: a test FMU for timeouts and declared bounds.  It moves along x at
 * the commanded speed and sleeps `pause` seconds of wall time in every step,
 * so a run can be made to last far longer than any timeout, however busy the
 * machine.  `pause` declares min 0 and max 10 in modelDescription.xml.
 */
#define _POSIX_C_SOURCE 199309L
#include <time.h>

#include "slave.h"

enum Real { X, Y, VELOCITY, PAUSE, N_REALS };

static const double DEFAULTS[N_REALS] = {0.0, 0.0, 0.0, 0.0};

static int do_step(Slave *s, double t, double h) {
    (void)t;
    double pause = s->r[PAUSE];
    if (pause > 0) {
        struct timespec wait = {(time_t)pause, (long)((pause - (double)(time_t)pause) * 1e9)};
        while (nanosleep(&wait, &wait) != 0) {
        }
    }
    s->r[X] += s->r[VELOCITY] * h;
    return 0;
}

const ModelInfo MODEL = {
    .guid = "{0b7d8f3e-2a41-4c9e-9d15-7e3a6c1f8b20}",
    .n_reals = N_REALS,
    .real_defaults = DEFAULTS,
    .n_strings = 0,
    .string_defaults = 0,
    .state_size = 0,
    .enter_initialization = 0,
    .exit_initialization = 0,
    .do_step = do_step,
    .release = 0,
};
