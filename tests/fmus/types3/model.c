/*
 * types3: a test FMU (FMI 3.0 co-simulation) with variables of the FMI 3
 * types our importers meet, so tests can check that values of each type get
 * in and out exactly.  FMI 3 value references are unique across types; the
 * table below maps each to its type and its index in the typed array.
 *
 * At every communication point t, with n the number of steps taken so far
 * (the outputs are computed when initialization ends, n = 0 at the start
 * time, and at the end of every step):
 *
 *   float64_out = float64_gain * float64_in + t    float64_gain: default 2, min 0, max 10
 *   float32_out = float32_in / 2                   (exact in binary)
 *   int32_out   = int32_in + int32_offset + n      int32_offset: default 0, min -100, max 100
 *   int64_out   = 2 * int64_in + n                 (64-bit: try int64_in = 2^40; no overflow check)
 *   uint16_out  = (uint16_in + n) mod 65536        (wraps: uint16_in = 65535 gives 0 after one step)
 *   steps       = n                                (Int32)
 *   bool_out    = bool_in XOR invert               invert: default true, so bool_out = !bool_in
 *   string_out  = string_in followed by suffix     suffix: default "!"
 *   enum_out    = (enum_in - 1 + n) mod 3 + 1      Colour: red = 1, green = 2, blue = 3;
 *                                                  enum_in: default red, min 1, max 3
 *
 * The inputs are read at the start of a step; the outputs change only in a
 * step, so no output depends directly on an input.
 */
#include <stdlib.h>
#include <string.h>

#include "slave3.h"

enum Float64 { FLOAT64_IN, FLOAT64_GAIN, FLOAT64_OUT, N_FLOAT64 };
enum Float32 { FLOAT32_IN, FLOAT32_OUT, N_FLOAT32 };
enum Int32 { INT32_IN, INT32_OFFSET, INT32_OUT, STEPS, N_INT32 };
enum Int64 { INT64_IN, INT64_OUT, ENUM_IN, ENUM_OUT, N_INT64 }; /* enumerations are Int64 */
enum UInt16 { UINT16_IN, UINT16_OUT, N_UINT16 };
enum Boolean { BOOL_IN, INVERT, BOOL_OUT, N_BOOLEAN };
enum String { STRING_IN, SUFFIX, STRING_OUT, N_STRING };

enum { N_COLOURS = 3 };

/* Value references as in modelDescription.xml, in its order. */
static const Variable3 VARIABLES[] = {
    {.vr = 0, .type = V3_TIME},
    {.vr = 1, .type = V3_FLOAT64, .index = FLOAT64_IN},
    {.vr = 2, .type = V3_FLOAT64, .index = FLOAT64_GAIN, .start = 2.0},
    {.vr = 3, .type = V3_FLOAT64, .index = FLOAT64_OUT},
    {.vr = 4, .type = V3_FLOAT32, .index = FLOAT32_IN},
    {.vr = 5, .type = V3_FLOAT32, .index = FLOAT32_OUT},
    {.vr = 6, .type = V3_INT32, .index = INT32_IN},
    {.vr = 7, .type = V3_INT32, .index = INT32_OFFSET},
    {.vr = 8, .type = V3_INT32, .index = INT32_OUT},
    {.vr = 9, .type = V3_INT32, .index = STEPS},
    {.vr = 10, .type = V3_INT64, .index = INT64_IN},
    {.vr = 11, .type = V3_INT64, .index = INT64_OUT},
    {.vr = 12, .type = V3_UINT16, .index = UINT16_IN},
    {.vr = 13, .type = V3_UINT16, .index = UINT16_OUT},
    {.vr = 14, .type = V3_BOOLEAN, .index = BOOL_IN},
    {.vr = 15, .type = V3_BOOLEAN, .index = INVERT, .start = 1},
    {.vr = 16, .type = V3_BOOLEAN, .index = BOOL_OUT, .start = 1},
    {.vr = 17, .type = V3_STRING, .index = STRING_IN, .start_string = ""},
    {.vr = 18, .type = V3_STRING, .index = SUFFIX, .start_string = "!"},
    {.vr = 19, .type = V3_STRING, .index = STRING_OUT, .start_string = "!"},
    {.vr = 20, .type = V3_INT64, .index = ENUM_IN, .start = 1},
    {.vr = 21, .type = V3_INT64, .index = ENUM_OUT, .start = 1},
};

/* Computes every output for time t after n steps. */
static int update_outputs(Slave3 *s, double t, int n) {
    s->f64[FLOAT64_OUT] = s->f64[FLOAT64_GAIN] * s->f64[FLOAT64_IN] + t;
    s->f32[FLOAT32_OUT] = s->f32[FLOAT32_IN] / 2.0f;
    s->i32[INT32_OUT] = s->i32[INT32_IN] + s->i32[INT32_OFFSET] + n;
    s->i32[STEPS] = n;
    s->i64[INT64_OUT] = 2 * s->i64[INT64_IN] + n;
    s->u16[UINT16_OUT] = (fmi3UInt16)(s->u16[UINT16_IN] + n);
    s->b[BOOL_OUT] = s->b[BOOL_IN] != s->b[INVERT];
    /* The enumeration's own min/max are not enforced by the layer: reject out-of-range values. */
    if (s->i64[ENUM_IN] < 1 || s->i64[ENUM_IN] > N_COLOURS) {
        slave3_log(s, fmi3Error, "logStatusError", "enum_in must be 1, 2 or 3, got %lld",
                   (long long)s->i64[ENUM_IN]);
        return 1;
    }
    s->i64[ENUM_OUT] = (s->i64[ENUM_IN] - 1 + n) % N_COLOURS + 1;
    size_t a = strlen(s->str[STRING_IN]), b = strlen(s->str[SUFFIX]);
    char *joined = malloc(a + b + 1);
    if (!joined) {
        slave3_log(s, fmi3Error, "logStatusError", "out of memory for string_out");
        return 1;
    }
    memcpy(joined, s->str[STRING_IN], a);
    memcpy(joined + a, s->str[SUFFIX], b + 1);
    free(s->str[STRING_OUT]);
    s->str[STRING_OUT] = joined;
    return 0;
}

static int exit_initialization(Slave3 *s) { return update_outputs(s, s->time, 0); }

static int do_step(Slave3 *s, double t, double h) { return update_outputs(s, t + h, s->i32[STEPS] + 1); }

const ModelInfo3 MODEL = {
    .instantiation_token = "{04e45aa8-4b82-431e-93f5-4d1d46cb3eff}",
    .variables = VARIABLES,
    .n_variables = sizeof VARIABLES / sizeof VARIABLES[0],
    .exit_initialization = exit_initialization,
    .do_step = do_step,
};
