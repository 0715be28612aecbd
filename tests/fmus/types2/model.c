/*
 * types2: a test FMU (FMI 2.0 co-simulation) with a variable of every FMI 2
 * type, so tests can check that values of each type get in and out exactly.
 *
 * Each input has a parameter beside it and an output that is a deterministic
 * function of them.  At every communication point t, with n the number of
 * steps taken so far (the outputs are computed when initialization ends,
 * n = 0 at the start time, and at the end of every step):
 *
 *   real_out   = real_gain * real_in + t         real_gain: default 2, min 0, max 10
 *   int_out    = int_in + int_offset + n         int_offset: default 0, min -100, max 100
 *   steps      = n
 *   bool_out   = bool_in XOR invert              invert: default true, so bool_out = !bool_in
 *   string_out = string_in followed by suffix    suffix: default "!"
 *   enum_out   = (enum_in - 1 + n) mod 3 + 1     Colour: red = 1, green = 2, blue = 3;
 *                                                enum_in: default red, min 1, max 3
 *
 * The inputs are read at the start of a step; the outputs change only in a
 * step, so no output depends directly on an input.
 */
#include <stdlib.h>
#include <string.h>

#include "slave.h"

enum Real { REAL_IN, REAL_GAIN, REAL_OUT, N_REALS };
enum Integer { INT_IN, INT_OFFSET, INT_OUT, STEPS, ENUM_IN, ENUM_OUT, N_INTEGERS };
enum Boolean { BOOL_IN, INVERT, BOOL_OUT, N_BOOLEANS };
enum String { STRING_IN, SUFFIX, STRING_OUT, N_STRINGS };

enum { N_COLOURS = 3 };

static const double REAL_DEFAULTS[N_REALS] = {0.0, 2.0, 0.0};
static const int INTEGER_DEFAULTS[N_INTEGERS] = {0, 0, 0, 0, 1, 1};
static const int BOOLEAN_DEFAULTS[N_BOOLEANS] = {0, 1, 1};
static const char *const STRING_DEFAULTS[N_STRINGS] = {"", "!", "!"};

/* Computes every output for time t after n steps. */
static int update_outputs(Slave *s, double t, int n) {
    s->r[REAL_OUT] = s->r[REAL_GAIN] * s->r[REAL_IN] + t;
    s->i[INT_OUT] = s->i[INT_IN] + s->i[INT_OFFSET] + n;
    s->i[STEPS] = n;
    s->b[BOOL_OUT] = s->b[BOOL_IN] != s->b[INVERT];
    /* The enumeration's own min/max are not enforced by the layer: reject out-of-range values. */
    if (s->i[ENUM_IN] < 1 || s->i[ENUM_IN] > N_COLOURS) {
        slave_log(s, fmi2Error, "logStatusError", "enum_in must be 1, 2 or 3, got %d", s->i[ENUM_IN]);
        return 1;
    }
    s->i[ENUM_OUT] = (s->i[ENUM_IN] - 1 + n) % N_COLOURS + 1;
    size_t a = strlen(s->str[STRING_IN]), b = strlen(s->str[SUFFIX]);
    char *joined = malloc(a + b + 1);
    if (!joined) {
        slave_log(s, fmi2Error, "logStatusError", "out of memory for string_out");
        return 1;
    }
    memcpy(joined, s->str[STRING_IN], a);
    memcpy(joined + a, s->str[SUFFIX], b + 1);
    free(s->str[STRING_OUT]);
    s->str[STRING_OUT] = joined;
    return 0;
}

static int exit_initialization(Slave *s) { return update_outputs(s, s->time, 0); }

static int do_step(Slave *s, double t, double h) { return update_outputs(s, t + h, s->i[STEPS] + 1); }

const ModelInfo MODEL = {
    .guid = "{b58b5cc7-46e5-49c8-bce8-592db66c6935}",
    .n_reals = N_REALS,
    .real_defaults = REAL_DEFAULTS,
    .n_strings = N_STRINGS,
    .string_defaults = STRING_DEFAULTS,
    .n_integers = N_INTEGERS,
    .integer_defaults = INTEGER_DEFAULTS,
    .n_booleans = N_BOOLEANS,
    .boolean_defaults = BOOLEAN_DEFAULTS,
    .exit_initialization = exit_initialization,
    .do_step = do_step,
};
