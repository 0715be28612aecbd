/*
 * native_loop.c: the master's fixed-step loop in C (dse_runner/simulation/native.py).
 *
 * Python loads, instantiates and initialises the FMUs (FMPy), resolves every
 * connection into groups of one C type and conversion, and hands this loop
 * the FMUs' own function pointers with prepared buffers.  Each step does what
 * cosim.py's Python loop does, in the same order, so the trajectories are
 * bit-identical:
 *
 *   1. external input signals of this point into the signal vector;
 *   2. per unit: its input groups gathered from the signals (converted: copy,
 *      round half to even, threshold), set; then the string outputs it feeds;
 *   3. every unit steps from t to t + h (fmi2DoStep / fmi3DoStep);
 *   4. an FMI 3.0 unit that asked to terminate stops the loop (TERMINATE); a step that failed stops it
 *      with its status (STEP_FAILED), where an FMI 2.0 unit's fmi2Discard may be its asking to stop;
 *   5. per unit: its output groups got and scattered into the signals; its
 *      string outputs got and copied into an arena;
 *   6. the recorded signals of this point are stored, and checked finite.
 *
 * It stops at the first failure and says where (Outcome); Python words the
 * message as the Python loop does.  No FMI header is needed: only the calling
 * conventions of the four FMI function shapes are used.
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

enum { F64, F32, I8, U8, I16, U16, I32, U32, I64, U64, BOOL8, CINT };  /* CINT: FMI 2's Integer and Boolean */
enum { COPY, ROUND, THRESHOLD };
enum { DONE, FEED_FAILED, STEP_FAILED, READ_FAILED, TIMEOUT, DIVERGED, UNFIT, TERMINATE,
       TEXT_READ_FAILED, TEXT_FEED_FAILED, NO_MEMORY, LIFECYCLE_FAILED, VALUE_FAILED };
enum { SETUP, ENTER, EXIT, END };  /* Lifecycle calls, as LIFECYCLE_FAILED's group */

#define FMI_WARNING 1  /* statuses above this are failures, in FMI 2 and 3 alike */

typedef int (*Access2)(void *, const uint32_t *, size_t, void *);
typedef int (*Access3)(void *, const uint32_t *, size_t, void *, size_t);
typedef int (*Step2)(void *, double, double, int);
typedef int (*Step3)(void *, double, double, bool, bool *, bool *, bool *, double *);
typedef int (*Setup2)(void *, int, double, double, int, double);
typedef int (*Enter3)(void *, bool, double, double, bool, double);
typedef int (*Call1)(void *);

typedef struct {          /* one group of values of one C type: an FMU's inputs or outputs */
    void *fn;             /* fmi2SetReal, fmi3GetInt64, ... */
    void *component;
    int32_t version;      /* 2 or 3 */
    int32_t ctype;
    int32_t conv;         /* inputs only */
    int32_t unit;
    double threshold;     /* THRESHOLD: true above this */
    double low, above;    /* ROUND: what the C type holds, [low, above) */
    int64_t n;
    const uint32_t *vrs;
    const int64_t *index; /* signals gathered (inputs) or scattered to (outputs); NULL: buffer is the signals */
    void *buffer;
} Group;

typedef struct {
    void *step;
    void *component;
    int32_t version;
    int32_t unit;
} Unit;

typedef struct {          /* a unit's set-up and end, when the loop does them (Call.lifecycle) */
    void *setup;          /* fmi2SetupExperiment; NULL in FMI 3, whose enter takes the times */
    void *enter, *exit, *terminate;
    int32_t tolerance_defined;
    double tolerance;
    int32_t stop_defined;
} Lifecycle;

typedef struct {          /* the string outputs of one unit */
    void *fn;             /* fmi2GetString or fmi3GetString */
    void *component;
    int32_t version;
    int32_t unit;
    int64_t n;
    const uint32_t *vrs;
    const char **buffer;
    int64_t first;        /* index of its first output among all string outputs */
} TextRead;

typedef struct {          /* a string output feeding a string input */
    void *fn;             /* the target's fmi2SetString or fmi3SetString */
    void *component;
    int32_t version;
    int32_t unit;         /* the source's unit: fed right after that unit's inputs */
    uint32_t vr;
    int32_t target;       /* the target's unit, for messages */
    int64_t source;       /* index among all string outputs */
} TextFeed;

typedef struct {          /* where the loop stopped, and the strings it recorded */
    int32_t code;
    int32_t unit;
    int32_t group;
    int32_t element;
    int64_t k;            /* the communication point reached */
    double t;
    double value;         /* UNFIT: the value that did not fit */
    char *arena;          /* every string recorded, NUL-terminated; free with dse_free */
    int64_t arena_used;
} Outcome;

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Whether the deadline has passed; without one (INFINITY), the clock is not read. */
static inline bool past(double deadline) {
    return deadline < INFINITY && now() > deadline;
}

/* Calls an FMU's getter or setter of n values at vrs (fmi2GetReal, fmi3SetString, ...) on buffer, as
 * its FMI version calls it: FMI 3 passes the number of values again, after the buffer. */
static inline int transfer(void *fn, void *component, int32_t version, const uint32_t *vrs, size_t n, void *buffer) {
    if (version == 3) return ((Access3)fn)(component, vrs, n, buffer, n);
    return ((Access2)fn)(component, vrs, n, buffer);
}

static int call(const Group *g) { return transfer(g->fn, g->component, g->version, g->vrs, (size_t)g->n, g->buffer); }

/* Steps a unit from t to t + h (fmi2DoStep or fmi3DoStep); an FMI 3 unit's terminateSimulation goes to
 * *asked, its other flags are not used. */
static inline int step_unit(const Unit *s, double t, double h, bool *asked) {
    bool event, early;
    double last_time;
    return s->version == 3 ? ((Step3)s->step)(s->component, t, h, true, &event, asked, &early, &last_time)
                           : ((Step2)s->step)(s->component, t, h, 1);
}

/* A step's status above FMI_WARNING: STEP_FAILED, the status kept as the outcome's element, for Python to
 * ask whether the unit asked to stop (fmi2Discard and fmi2Terminated) or failed. */
static int step_failed(Outcome *out, int status) {
    out->element = status;
    return STEP_FAILED;
}

/* Stores x into element i of a buffer of C type ctype, as numpy's assignment does. */
static void store(void *buffer, int ctype, int64_t i, double x) {
    switch (ctype) {
    case F64: ((double *)buffer)[i] = x; break;
    case F32: ((float *)buffer)[i] = (float)x; break;
    case I8: ((int8_t *)buffer)[i] = (int8_t)x; break;
    case U8: ((uint8_t *)buffer)[i] = (uint8_t)x; break;
    case I16: ((int16_t *)buffer)[i] = (int16_t)x; break;
    case U16: ((uint16_t *)buffer)[i] = (uint16_t)x; break;
    case I32: ((int32_t *)buffer)[i] = (int32_t)x; break;
    case U32: ((uint32_t *)buffer)[i] = (uint32_t)x; break;
    case I64: ((int64_t *)buffer)[i] = (int64_t)x; break;
    case U64: ((uint64_t *)buffer)[i] = (uint64_t)x; break;
    case BOOL8: ((bool *)buffer)[i] = x != 0.0; break;
    default: ((int *)buffer)[i] = (int)x; break;
    }
}

static double load(const void *buffer, int ctype, int64_t i) {
    switch (ctype) {
    case F64: return ((const double *)buffer)[i];
    case F32: return (double)((const float *)buffer)[i];
    case I8: return (double)((const int8_t *)buffer)[i];
    case U8: return (double)((const uint8_t *)buffer)[i];
    case I16: return (double)((const int16_t *)buffer)[i];
    case U16: return (double)((const uint16_t *)buffer)[i];
    case I32: return (double)((const int32_t *)buffer)[i];
    case U32: return (double)((const uint32_t *)buffer)[i];
    case I64: return (double)((const int64_t *)buffer)[i];
    case U64: return (double)((const uint64_t *)buffer)[i];
    case BOOL8: return ((const bool *)buffer)[i] ? 1.0 : 0.0;
    default: return (double)((const int *)buffer)[i];
    }
}

/* Gathers a group's inputs from the signals into its buffer; -1 or the element that does not fit. */
static int64_t fill(const Group *g, const double *signals, double *bad) {
    if (g->conv == COPY && g->ctype == F64) {
        double *b = g->buffer;
        for (int64_t i = 0; i < g->n; i++) b[i] = signals[g->index[i]];
        return -1;
    }
    for (int64_t i = 0; i < g->n; i++) {
        double x = signals[g->index[i]];
        if (g->conv == THRESHOLD) {
            store(g->buffer, g->ctype, i, x > g->threshold ? 1.0 : 0.0);
        } else if (g->conv == ROUND) {
            double r = nearbyint(x);  /* half to even, as numpy's rint */
            if (!(r >= g->low && r < g->above)) {
                *bad = x;
                return i;
            }
            store(g->buffer, g->ctype, i, r);
        } else {
            store(g->buffer, g->ctype, i, x);
        }
    }
    return -1;
}

/* Gathers an input group from the signals and sets it: DONE, FEED_FAILED, or UNFIT with the element
 * that does not fit and its value in out. */
static int feed(const Group *g, const double *signals, Outcome *out) {
    double bad = 0.0;
    int64_t unfit = fill(g, signals, &bad);
    if (unfit >= 0) {
        out->element = (int32_t)unfit;
        out->value = bad;
        return UNFIT;
    }
    return call(g) > FMI_WARNING ? FEED_FAILED : DONE;
}

static void scatter(const Group *g, double *signals) {
    if (g->index == NULL) return;  /* float64 outputs read straight into the signals */
    for (int64_t i = 0; i < g->n; i++) signals[g->index[i]] = load(g->buffer, g->ctype, i);
}

typedef struct {
    char *data;
    int64_t used, size;
} Arena;

/* Appends a string and its NUL; its offset, or -1 without memory. */
static int64_t keep(Arena *a, const char *text) {
    size_t length = strlen(text ? text : "") + 1;
    if (a->used + (int64_t)length > a->size) {
        int64_t size = a->size ? a->size : 4096;
        while (size < a->used + (int64_t)length) size *= 2;
        char *data = realloc(a->data, (size_t)size);
        if (!data) return -1;
        a->data = data;
        a->size = size;
    }
    memcpy(a->data + a->used, text ? text : "", length);
    a->used += (int64_t)length;
    return a->used - (int64_t)length;
}

static int stop(Outcome *out, Arena *arena, int code, int64_t k, double t, int unit, int group) {
    out->code = code;
    out->k = k;
    out->t = t;
    out->unit = unit;
    out->group = group;
    out->arena = arena->data;
    out->arena_used = arena->used;
    return code;
}

/* Copies the signals of point k into its row of the record; false if one is not finite. */
static bool keep_row(double *row, const double *signals, int64_t n) {
    bool finite = true;
    for (int64_t j = 0; j < n; j++) {
        row[j] = signals[j];
        finite &= isfinite(signals[j]) != 0;
    }
    return finite;
}

static bool finite_row(const double *row, int64_t n) {
    bool finite = true;
    for (int64_t j = 0; j < n; j++) finite &= isfinite(row[j]) != 0;
    return finite;
}

/*
 * The loop of a plan with only numeric connections and no input signals (most studies): the
 * same steps as dse_loop below, without the per-unit interleaving that strings and input signals
 * need (for numbers it changes nothing: every input is set before any unit steps).
 */
__attribute__((noinline)) static int plain_loop(const Unit *units, int32_t n_units, const Group *feeds, int32_t n_feeds,
                      const Group *reads, int32_t n_reads, bool fmi3, const double *times, const double *steps,
                      int64_t n_times, double *signals, int64_t n_recorded, double *record, double seconds, bool *asked,
                      Arena *arena, Outcome *out) {
    const double deadline = seconds > 0 ? now() + seconds : INFINITY;
    for (int64_t k = 1; k < n_times; k++) {
        const double t = times[k - 1], t_next = times[k], h = steps[k];
        if (!(k & 63) && past(deadline)) return stop(out, arena, TIMEOUT, k, t, -1, -1);
        for (int32_t f = 0; f < n_feeds; f++) {
            int code = feed(&feeds[f], signals, out);
            if (code != DONE) return stop(out, arena, code, k, t, feeds[f].unit, f);
        }
        for (int32_t u = 0; u < n_units; u++) {
            int status = step_unit(&units[u], t, h, &asked[u]);
            if (status > FMI_WARNING) return stop(out, arena, step_failed(out, status), k, t, u, -1);
        }
        if (fmi3)
            for (int32_t u = 0; u < n_units; u++)
                if (asked[u]) return stop(out, arena, TERMINATE, k, t_next, u, -1);
        for (int32_t r = 0; r < n_reads; r++) {
            if (call(&reads[r]) > FMI_WARNING) return stop(out, arena, READ_FAILED, k, t_next, reads[r].unit, r);
            scatter(&reads[r], signals);
        }
        if (!keep_row(record + k * n_recorded, signals, n_recorded))
            return stop(out, arena, DIVERGED, k, t_next, -1, -1);
    }
    return stop(out, arena, DONE, n_times - 1, times[n_times - 1], -1, -1);
}

/* Whether all n values are finite, tested on their bits: a non-finite double has every exponent bit
 * set, and adding one to that exponent carries into bit 63.  Integer and, add and or only, so the
 * compiler vectorises it (isfinite row by row, with an early exit, cost the cheap case 3 µs a run). */
static bool finite_block(const double *x, int64_t n) {
    const uint64_t exponent = 0x7ff0000000000000ull;
    uint64_t carried = 0;
    for (int64_t i = 0; i < n; i++) {
        uint64_t bits;
        memcpy(&bits, &x[i], sizeof bits);
        carried |= (bits & exponent) + (1ull << 52);
    }
    return !(carried >> 63);
}

/* The first row in [from, to) of the record with a non-finite value, or -1: the block at once, then
 * row by row only where it holds one. */
static int64_t first_nonfinite(const double *record, int64_t from, int64_t to, int64_t n) {
    if (to <= from || finite_block(record + from * n, (to - from) * n)) return -1;
    for (int64_t k = from; k < to; k++)
        if (!finite_row(record + k * n, n)) return k;
    return -1;
}

/* At point k of the loops that check rows in blocks, every 64 points (other points pass at once): the
 * rows since ``*checked`` are finite and the deadline has not passed. DONE to go on, else the code the
 * run stopped with. */
static inline int checkpoint(Outcome *out, Arena *arena, const double *record, const double *times,
                             int64_t n_recorded, int64_t *checked, int64_t k, double deadline) {
    if (k & 63) return DONE;
    int64_t bad = first_nonfinite(record, *checked, k, n_recorded);
    if (bad >= 0) return stop(out, arena, DIVERGED, bad, times[bad], -1, -1);
    *checked = k;
    if (past(deadline)) return stop(out, arena, TIMEOUT, k, times[k - 1], -1, -1);
    return DONE;
}

/* The end of those loops: the last rows checked, then done. */
static int finish(Outcome *out, Arena *arena, const double *record, const double *times, int64_t n_recorded,
                  int64_t checked, int64_t n_times) {
    int64_t bad = first_nonfinite(record, checked, n_times, n_recorded);
    if (bad >= 0) return stop(out, arena, DIVERGED, bad, times[bad], -1, -1);
    return stop(out, arena, DONE, n_times - 1, times[n_times - 1], -1, -1);
}

/* Stops with ``code`` at point k, unless a row written before it (from ``checked`` on) is non-finite:
 * then the divergence, where it began, is what stopped the run. */
static int halt(Outcome *out, Arena *arena, const double *record, const double *times, int64_t n_recorded,
                int64_t checked, int code, int64_t k, double t, int unit, int group) {
    int64_t bad = first_nonfinite(record, checked, k, n_recorded);
    if (bad >= 0) return stop(out, arena, DIVERGED, bad, times[bad], -1, -1);
    return stop(out, arena, code, k, t, unit, group);
}

/*
 * The loop of a plan whose units feed nothing to each other and whose outputs are all float64 read
 * straight into the signals (one FMU, as in most studies of one model): each output group's getter
 * writes into the record's row itself, the place its signals would be copied to, and the rows are
 * checked finite 64 at a time, off the steps' path. Those two save a few ns a step, as much as a
 * cheap FMU's own step costs. A run still stops at the first non-finite point, as reported; the
 * FMUs may have stepped up to 63 points beyond it (the Python loop checks only at the end).
 */
__attribute__((noinline)) static int direct_loop(const Unit *units, int32_t n_units, const Group *reads, int32_t n_reads, bool fmi3,
                       const double *times, const double *steps, int64_t n_times, const double *signals,
                       int64_t n_recorded, double *record, double seconds, bool *asked, Arena *arena, Outcome *out) {
    const double deadline = seconds > 0 ? now() + seconds : INFINITY;
    int64_t checked = 1;  /* rows before this are finite */
    for (int64_t k = 1; k < n_times; k++) {
        const double t = times[k - 1], t_next = times[k], h = steps[k];
        int code = checkpoint(out, arena, record, times, n_recorded, &checked, k, deadline);
        if (code != DONE) return code;
        for (int32_t u = 0; u < n_units; u++) {
            int status = step_unit(&units[u], t, h, &asked[u]);
            if (status > FMI_WARNING)
                return halt(out, arena, record, times, n_recorded, checked, step_failed(out, status), k, t, u, -1);
        }
        if (fmi3)
            for (int32_t u = 0; u < n_units; u++)
                if (asked[u]) return halt(out, arena, record, times, n_recorded, checked, TERMINATE, k, t_next, u, -1);
        double *row = record + k * n_recorded;
        for (int32_t r = 0; r < n_reads; r++) {
            const Group *g = &reads[r];
            double *into = row + ((const double *)g->buffer - signals);
            if (transfer(g->fn, g->component, g->version, g->vrs, (size_t)g->n, into) > FMI_WARNING)
                return halt(out, arena, record, times, n_recorded, checked, READ_FAILED, k, t_next, g->unit, r);
        }
    }
    return finish(out, arena, record, times, n_recorded, checked, n_times);
}

/*
 * direct_loop for one unit with one output group (a single FMU, the commonest study), with its
 * functions and arguments held in locals: the general loops reload them from their structures after
 * every call into an FMU (which could have changed them, as far as the compiler knows), and that
 * costs a cheap FMU about half again its own step.
 */
static inline __attribute__((always_inline)) int single_steps(
    const bool fmi3, const Unit *unit, const Group *read, const double *times, const double *steps, int64_t n_times,
    const double *signals, int64_t n_recorded, double *record, double seconds, Arena *arena, Outcome *out) {
    const double deadline = seconds > 0 ? now() + seconds : INFINITY;
    void *const component = unit->component, *const reader = read->component;
    const Step2 step2 = (Step2)unit->step;
    const Step3 step3 = (Step3)unit->step;
    const Access2 get2 = (Access2)read->fn;
    const Access3 get3 = (Access3)read->fn;
    const uint32_t *const vrs = read->vrs;
    const size_t n = (size_t)read->n;
    const int64_t offset = (const double *)read->buffer - signals;
    bool event, asked = false, early;
    double last_time;
    int64_t checked = 1;  /* rows before this are finite */
    for (int64_t k = 1; k < n_times; k++) {
        const double t = times[k - 1], t_next = times[k], h = steps[k];
        int code = checkpoint(out, arena, record, times, n_recorded, &checked, k, deadline);
        if (code != DONE) return code;
        int status = fmi3 ? step3(component, t, h, true, &event, &asked, &early, &last_time) : step2(component, t, h, 1);
        if (status > FMI_WARNING)
            return halt(out, arena, record, times, n_recorded, checked, step_failed(out, status), k, t, 0, -1);
        if (asked) return halt(out, arena, record, times, n_recorded, checked, TERMINATE, k, t_next, 0, -1);
        double *into = record + k * n_recorded + offset;
        status = fmi3 ? get3(reader, vrs, n, into, n) : get2(reader, vrs, n, into);
        if (status > FMI_WARNING) return halt(out, arena, record, times, n_recorded, checked, READ_FAILED, k, t_next, 0, 0);
    }
    return finish(out, arena, record, times, n_recorded, checked, n_times);
}

/* single_steps made twice, for FMI 2 and for FMI 3, so that neither tests the version at each step. */
__attribute__((noinline)) static int single_loop(const Unit *unit, const Group *read, const double *times,
                                                 const double *steps, int64_t n_times, const double *signals, int64_t n_recorded,
                                                 double *record, double seconds, Arena *arena, Outcome *out) {
    return unit->version == 3
        ? single_steps(true, unit, read, times, steps, n_times, signals, n_recorded, record, seconds, arena, out)
        : single_steps(false, unit, read, times, steps, n_times, signals, n_recorded, record, seconds, arena, out);
}

/*
 * Checks point 0 (row 0 of record, filled by Python) and runs points 1 .. n_times - 1.  signals holds n_recorded recorded values, then n_external
 * external inputs; record is n_times x n_recorded, row 0 already filled; external is
 * n_times x n_external.  text_offsets is n_times x n_texts (row 0 unused): each recorded
 * string's offset in the arena; initial_texts the string outputs at point 0.
 */
int dse_loop(const Unit *units, int32_t n_units, const Group *feeds, int32_t n_feeds,
             const Group *reads, int32_t n_reads, const TextRead *text_reads, int32_t n_text_reads,
             const TextFeed *text_feeds, int32_t n_text_feeds, const char **initial_texts, int64_t n_texts,
             const double *times, const double *steps, int64_t n_times, double *signals, int64_t n_recorded,
             const double *external, int64_t n_external, double *record, int64_t *text_offsets,
             double seconds, Outcome *out) {
    Arena arena = {0};
    if (!finite_row(record, n_recorded)) return stop(out, &arena, DIVERGED, 0, times[0], -1, -1);
    int64_t *latest = n_texts ? malloc((size_t)n_texts * sizeof *latest) : NULL;
    if (n_texts && !latest) return stop(out, &arena, NO_MEMORY, 0, times[0], -1, -1);
    for (int64_t j = 0; j < n_texts; j++) {
        if ((latest[j] = keep(&arena, initial_texts[j])) < 0) {
            free(latest);
            return stop(out, &arena, NO_MEMORY, 0, times[0], -1, -1);
        }
    }
    int code = DONE;
    bool *asked = n_units ? calloc((size_t)n_units, sizeof *asked) : NULL;  /* terminateSimulation, per unit */
    if (n_units && !asked) { free(latest); return stop(out, &arena, NO_MEMORY, 0, times[0], -1, -1); }
    if (n_texts == 0 && n_external == 0) {
        bool fmi3 = false;
        for (int32_t u = 0; u < n_units; u++) fmi3 |= units[u].version == 3;
        bool direct = n_feeds == 0;
        for (int32_t r = 0; r < n_reads; r++) direct &= reads[r].index == NULL;  /* float64, into the signals */
        code = direct && n_units == 1 && n_reads == 1 && units[0].version == reads[0].version  /* not an ME unit's */
            ? single_loop(units, reads, times, steps, n_times, signals, n_recorded, record, seconds, &arena, out)
            : direct
            ? direct_loop(units, n_units, reads, n_reads, fmi3, times, steps, n_times, signals, n_recorded, record, seconds,
                          asked, &arena, out)
            : plain_loop(units, n_units, feeds, n_feeds, reads, n_reads, fmi3, times, steps, n_times, signals,
                         n_recorded, record, seconds, asked, &arena, out);
        goto done;
    }
    double deadline = seconds > 0 ? now() + seconds : INFINITY;
    int64_t k;
    for (k = 1; k < n_times; k++) {
        double t = times[k - 1], t_next = times[k], h = steps[k];
        if (!(k & 63) && past(deadline)) { code = stop(out, &arena, TIMEOUT, k, t, -1, -1); goto done; }
        for (int64_t j = 0; j < n_external; j++) signals[n_recorded + j] = external[(k - 1) * n_external + j];
        int32_t f = 0, tf = 0;
        for (int32_t u = 0; u < n_units; u++) {
            for (; f < n_feeds && feeds[f].unit == u; f++) {
                code = feed(&feeds[f], signals, out);
                if (code != DONE) { code = stop(out, &arena, code, k, t, u, f); goto done; }
            }
            for (; tf < n_text_feeds && text_feeds[tf].unit == u; tf++) {
                const TextFeed *x = &text_feeds[tf];
                const char *value = arena.data + latest[x->source];
                if (transfer(x->fn, x->component, x->version, &x->vr, 1, (void *)&value) > FMI_WARNING) {
                    code = stop(out, &arena, TEXT_FEED_FAILED, k, t, x->target, tf);
                    goto done;
                }
            }
        }
        for (int32_t u = 0; u < n_units; u++) {
            int status = step_unit(&units[u], t, h, &asked[u]);
            if (status > FMI_WARNING) {
                code = stop(out, &arena, step_failed(out, status), k, t, u, -1);
                goto done;
            }
        }
        for (int32_t u = 0; u < n_units; u++)  /* after every unit has stepped, as the Python loop checks */
            if (asked[u]) { code = stop(out, &arena, TERMINATE, k, t_next, u, -1); goto done; }
        int32_t r = 0, tr = 0;
        for (int32_t u = 0; u < n_units; u++) {
            for (; r < n_reads && reads[r].unit == u; r++) {
                if (call(&reads[r]) > FMI_WARNING) { code = stop(out, &arena, READ_FAILED, k, t_next, u, r); goto done; }
                scatter(&reads[r], signals);
            }
            for (; tr < n_text_reads && text_reads[tr].unit == u; tr++) {
                const TextRead *x = &text_reads[tr];
                if (transfer(x->fn, x->component, x->version, x->vrs, (size_t)x->n, (void *)x->buffer) > FMI_WARNING) {
                    code = stop(out, &arena, TEXT_READ_FAILED, k, t_next, u, tr);
                    goto done;
                }
                for (int64_t j = 0; j < x->n; j++) {
                    int64_t at = keep(&arena, x->buffer[j]);
                    if (at < 0) { code = stop(out, &arena, NO_MEMORY, k, t_next, u, tr); goto done; }
                    latest[x->first + j] = text_offsets[k * n_texts + x->first + j] = at;
                }
            }
        }
        if (!keep_row(record + k * n_recorded, signals, n_recorded)) {
            code = stop(out, &arena, DIVERGED, k, t_next, -1, -1);
            goto done;
        }
    }
    code = stop(out, &arena, DONE, n_times - 1, times[n_times - 1], -1, -1);
done:
    free(latest);
    free(asked);
    return code;
}

/*
 * dse_loop's arguments in one block: Python fills the fixed ones once per set of FMU instances
 * (native.Program) and only the run's own before each call, so a call converts one pointer, not 22.
 */
typedef struct {
    const Unit *units;
    const Lifecycle *lifecycle;  /* NULL: Python sets the units up and terminates them */
    const Group *feeds, *reads;
    const Group *values;         /* the run's values, set after each unit's set-up; NULL: Python set both */
    const TextRead *text_reads;
    const TextFeed *text_feeds;
    const char **initial_texts;
    const double *times, *steps, *external;  /* steps[k]: the communication step that reaches times[k] */
    double *signals, *record;
    int64_t *text_offsets;
    Outcome *out;
    double seconds;
    int64_t n_texts, n_times, n_recorded, n_external;
    int32_t n_units, n_feeds, n_reads, n_text_reads, n_text_feeds, n_values;
} Call;

/* Every output group read into the signals at point k (time t). */
static int read_all(const Call *c, int64_t k, double t) {
    for (int32_t r = 0; r < c->n_reads; r++) {
        if (call(&c->reads[r]) > FMI_WARNING) return stop(c->out, &(Arena){0}, READ_FAILED, k, t, c->reads[r].unit, r);
        scatter(&c->reads[r], c->signals);
    }
    return DONE;
}

/* The input signals of point 0 into the signals, then every input group set from them. */
static int feed_all(const Call *c, double t) {
    for (int64_t j = 0; j < c->n_external; j++) c->signals[c->n_recorded + j] = c->external[j];
    for (int32_t f = 0; f < c->n_feeds; f++) {
        int code = feed(&c->feeds[f], c->signals, c->out);
        if (code != DONE) return stop(c->out, &(Arena){0}, code, 0, t, c->feeds[f].unit, f);
    }
    return DONE;
}

/* A lifecycle call's status: LIFECYCLE_FAILED names the unit, the call (group) and the status (element). */
static int lifecycle_status(const Call *c, int status, int32_t unit, int which, double t) {
    if (status <= FMI_WARNING) return DONE;
    c->out->element = status;
    return stop(c->out, &(Arena){0}, LIFECYCLE_FAILED, 0, t, unit, which);
}

/*
 * What cosim.py's Python does around the loop, when Call.lifecycle is given: every unit set up (FMI 2:
 * fmi2SetupExperiment with the stop time), its values set (Call.values, grouped by unit; where
 * Call.values is NULL, Python did both), in initialization mode; outputs read and inputs fed once,
 * initialization left, outputs read again into row 0 of the record. The order is FMPy's.
 */
static int initialise(const Call *c) {
    const double start = c->times[0], stop_time = c->times[c->n_times - 1];
    for (int32_t u = 0; u < c->n_units; u++) {
        const Unit *unit = &c->units[u];
        const Lifecycle *l = &c->lifecycle[u];
        int code = DONE;
        if (c->values && unit->version == 2)
            code = lifecycle_status(c, ((Setup2)l->setup)(unit->component, l->tolerance_defined, l->tolerance, start,
                                                          l->stop_defined, stop_time), u, SETUP, start);
        for (int32_t g = 0; c->values && code == DONE && g < c->n_values; g++)
            if (c->values[g].unit == u && call(&c->values[g]) > FMI_WARNING)
                code = stop(c->out, &(Arena){0}, VALUE_FAILED, 0, start, u, g);
        if (code != DONE) return code;
        if (unit->version == 3)
            code = lifecycle_status(c, ((Enter3)l->enter)(unit->component, l->tolerance_defined != 0, l->tolerance,
                                                          start, l->stop_defined != 0, stop_time), u, ENTER, start);
        else
            code = lifecycle_status(c, ((Call1)l->enter)(unit->component), u, ENTER, start);
        if (code != DONE) return code;
    }
    int code = read_all(c, 0, start);
    if (code == DONE) code = feed_all(c, start);
    for (int32_t u = 0; u < c->n_units && code == DONE; u++)
        code = lifecycle_status(c, ((Call1)c->lifecycle[u].exit)(c->units[u].component), u, EXIT, start);
    if (code == DONE) code = read_all(c, 0, start);
    if (code == DONE) memcpy(c->record, c->signals, (size_t)c->n_recorded * sizeof *c->record);
    return code;
}

int dse_run(const Call *c) {
    if (c->lifecycle) {
        int code = initialise(c);
        if (code != DONE) return code;
    }
    int code = dse_loop(c->units, c->n_units, c->feeds, c->n_feeds, c->reads, c->n_reads, c->text_reads,
                        c->n_text_reads, c->text_feeds, c->n_text_feeds, c->initial_texts, c->n_texts, c->times,
                        c->steps, c->n_times, c->signals, c->n_recorded, c->external, c->n_external, c->record,
                        c->text_offsets, c->seconds, c->out);
    for (int32_t u = 0; c->lifecycle && code == DONE && u < c->n_units; u++) {
        double end = c->times[c->n_times - 1];
        code = lifecycle_status(c, ((Call1)c->lifecycle[u].terminate)(c->units[u].component), u, END, end);
        if (code != DONE) c->out->k = c->n_times - 1;
    }
    return code;
}

void dse_free(char *arena) { free(arena); }
