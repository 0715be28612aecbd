/*
 * slave3.c: FMI 3.0 co-simulation entry points, written once for all our
 * FMI 3 FMUs.
 *
 * The model (model.c) supplies a ModelInfo3; this file owns the life cycle:
 * instantiate -> (set parameters) -> initialization mode -> step mode ->
 * terminate, with fmi3Reset going back to the start values so an importer can
 * reuse one instance for many runs.  It mirrors slave.c so the two layers can
 * be read side by side.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "slave3.h"

enum { INSTANTIATED, INITIALIZATION, STEPPING, TERMINATED, FAILED };

static const char *const PHASE_NAMES[] = {
    "instantiated", "initialization mode", "step mode", "terminated", "error"};

static const char *const TYPE_NAMES[V3_N_TYPES] = {
    "Float64", "Float32", "Int8",    "UInt8",  "Int16",  "UInt16", "Int32",
    "UInt32",  "Int64",   "UInt64",  "Boolean", "String", "Float64 (time)"};

void slave3_log(Slave3 *s, fmi3Status status, const char *category, const char *fmt, ...) {
    if (!s->logger) return;
    if (status == fmi3OK && !s->logging_on) return;
    /* Unlike FMI 2.0, FMI 3.0's message is plain text: no '%' escaping. */
    char msg[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    s->logger(s->environment, status, category, msg);
}

static char *copy_string(const char *text) {
    size_t n = strlen(text ? text : "") + 1;
    char *c = malloc(n);
    if (c) memcpy(c, text ? text : "", n);
    return c;
}

static int load_defaults(Slave3 *s) {
    const ModelInfo3 *m = s->info;
    for (size_t k = 0; k < m->n_variables; k++) {
        const Variable3 *v = &m->variables[k];
        size_t i = v->index;
        switch (v->type) {
        case V3_FLOAT64: s->f64[i] = v->start; break;
        case V3_FLOAT32: s->f32[i] = (fmi3Float32)v->start; break;
        case V3_INT8: s->i8[i] = (fmi3Int8)v->start; break;
        case V3_UINT8: s->u8[i] = (fmi3UInt8)v->start; break;
        case V3_INT16: s->i16[i] = (fmi3Int16)v->start; break;
        case V3_UINT16: s->u16[i] = (fmi3UInt16)v->start; break;
        case V3_INT32: s->i32[i] = (fmi3Int32)v->start; break;
        case V3_UINT32: s->u32[i] = (fmi3UInt32)v->start; break;
        case V3_INT64: s->i64[i] = (fmi3Int64)v->start; break;
        case V3_UINT64: s->u64[i] = (fmi3UInt64)v->start; break;
        case V3_BOOLEAN: s->b[i] = v->start != 0.0; break;
        case V3_STRING: {
            char *copy = copy_string(v->start_string);
            if (!copy) return 1;
            free(s->str[i]);
            s->str[i] = copy;
            break;
        }
        default: break; /* V3_TIME: nothing stored */
        }
    }
    if (m->release) m->release(s);
    memset(s->state, 0, m->state_size ? m->state_size : 1);
    s->time = 0.0;
    s->phase = INSTANTIATED;
    return 0;
}

/* Guards a call: the phase must be one of the allowed ones. */
static int allowed(Slave3 *s, const char *function, unsigned phases) {
    if (!s) return 0;
    if (phases & (1u << s->phase)) return 1;
    slave3_log(s, fmi3Error, "logStatusError", "%s is not allowed in phase '%s'", function,
               PHASE_NAMES[s->phase]);
    s->phase = FAILED;
    return 0;
}

#define ANY_PHASE 0x1fu
#define SETTABLE ((1u << INSTANTIATED) | (1u << INITIALIZATION) | (1u << STEPPING))

static fmi3Status fail(Slave3 *s) {
    s->phase = FAILED;
    return fmi3Error;
}

/* ---- the variable table ------------------------------------------------ */

static int by_vr_order(const void *a, const void *b) {
    fmi3ValueReference x = (*(const Variable3 *const *)a)->vr, y = (*(const Variable3 *const *)b)->vr;
    return x < y ? -1 : x > y;
}

/* Checks the model's table once per instance, so a mistake in model.c is a
 * clear message at instantiation instead of a stray write later: types in
 * range, value references unique, each type's indices exactly 0..n-1. */
static int index_table(Slave3 *s) {
    const ModelInfo3 *m = s->info;
    for (size_t k = 0; k < m->n_variables; k++) {
        const Variable3 *v = &m->variables[k];
        if ((unsigned)v->type >= V3_N_TYPES) {
            slave3_log(s, fmi3Error, "logStatusError", "variable table entry %zu: unknown type %d", k,
                       (int)v->type);
            return 1;
        }
        if (v->type < V3_N_STORED) s->count[v->type]++;
    }
    for (size_t k = 0; k < m->n_variables; k++) {
        const Variable3 *v = &m->variables[k];
        if (v->type == V3_TIME) continue;
        if (v->index >= s->count[v->type]) {
            slave3_log(s, fmi3Error, "logStatusError",
                       "variable table: value reference %u has %s index %zu, but there are only %zu %s "
                       "variables",
                       v->vr, TYPE_NAMES[v->type], v->index, s->count[v->type], TYPE_NAMES[v->type]);
            return 1;
        }
        for (size_t j = 0; j < k; j++)
            if (m->variables[j].type == v->type && m->variables[j].index == v->index) {
                slave3_log(s, fmi3Error, "logStatusError",
                           "variable table: value references %u and %u share %s index %zu",
                           m->variables[j].vr, v->vr, TYPE_NAMES[v->type], v->index);
                return 1;
            }
    }
    s->by_vr = malloc((m->n_variables ? m->n_variables : 1) * sizeof *s->by_vr);
    if (!s->by_vr) return 1;
    for (size_t k = 0; k < m->n_variables; k++) s->by_vr[k] = &m->variables[k];
    qsort(s->by_vr, m->n_variables, sizeof *s->by_vr, by_vr_order);
    for (size_t k = 1; k < m->n_variables; k++)
        if (s->by_vr[k]->vr == s->by_vr[k - 1]->vr) {
            slave3_log(s, fmi3Error, "logStatusError", "variable table: value reference %u appears twice",
                       s->by_vr[k]->vr);
            return 1;
        }
    return 0;
}

/* The variable with reference vr, which must be of the type the caller
 * accesses; NULL after logging otherwise. */
static const Variable3 *lookup(Slave3 *s, const char *function, fmi3ValueReference vr,
                               VarType3 type) {
    size_t lo = 0, hi = s->info->n_variables;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (s->by_vr[mid]->vr < vr)
            lo = mid + 1;
        else
            hi = mid;
    }
    if (lo == s->info->n_variables || s->by_vr[lo]->vr != vr) {
        slave3_log(s, fmi3Error, "logStatusError", "%s: unknown value reference %u", function, vr);
        return NULL;
    }
    const Variable3 *v = s->by_vr[lo];
    int same = v->type == type || (type == V3_FLOAT64 && v->type == V3_TIME);
    if (!same) {
        slave3_log(s, fmi3Error, "logStatusError", "%s: value reference %u is a %s variable", function,
                   vr, TYPE_NAMES[v->type]);
        return NULL;
    }
    return v;
}

/* Arrays are not supported: one value per value reference. */
static int scalars(Slave3 *s, const char *function, size_t n_vrs, size_t n_values) {
    if (n_vrs == n_values) return 1;
    slave3_log(s, fmi3Error, "logStatusError",
               "%s: %zu values for %zu value references (this FMU has no array variables)", function,
               n_values, n_vrs);
    return 0;
}

/* ---- inquiry, logging, creation ---------------------------------------- */

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance c, fmi3Boolean on, size_t n, const fmi3String cats[]) {
    (void)n;
    (void)cats;
    Slave3 *s = c;
    if (!s) return fmi3Error;
    s->logging_on = on;
    return fmi3OK;
}

void fmi3FreeInstance(fmi3Instance c) {
    Slave3 *s = c;
    if (!s) return;
    if (s->info->release && s->state) s->info->release(s);
    if (s->str)
        for (size_t i = 0; i < s->count[V3_STRING]; i++) free(s->str[i]);
    free(s->f64);
    free(s->f32);
    free(s->i8);
    free(s->u8);
    free(s->i16);
    free(s->u16);
    free(s->i32);
    free(s->u32);
    free(s->i64);
    free(s->u64);
    free(s->b);
    free(s->str);
    free(s->by_vr);
    free(s->state);
    free(s->instance_name);
    free(s);
}

/* calloc that never asks for 0 bytes, so NULL always means out of memory. */
static void *zeroed(size_t n, size_t size) { return calloc(n ? n : 1, size); }

fmi3Instance fmi3InstantiateCoSimulation(
    fmi3String name, fmi3String token, fmi3String resources, fmi3Boolean visible,
    fmi3Boolean logging_on, fmi3Boolean event_mode_used, fmi3Boolean early_return_allowed,
    const fmi3ValueReference required_intermediate[], size_t n_required_intermediate,
    fmi3InstanceEnvironment environment, fmi3LogMessageCallback logger,
    fmi3IntermediateUpdateCallback intermediate_update) {
    /* We never return early and never call back mid-step, so these need no state. */
    (void)resources;
    (void)visible;
    (void)early_return_allowed;
    (void)required_intermediate;
    (void)n_required_intermediate;
    (void)intermediate_update;
    const ModelInfo3 *m = &MODEL;
    const char *refusal = NULL;
    if (!token || strcmp(token, m->instantiation_token) != 0)
        refusal = "instantiationToken does not match this FMU's modelDescription.xml";
    else if (event_mode_used)
        refusal = "event mode is not supported (the FMU declares hasEventMode=\"false\")";
    if (refusal) {
        if (logger) logger(environment, fmi3Error, "logStatusError", refusal);
        return NULL;
    }
    Slave3 *s = calloc(1, sizeof *s);
    if (!s) return NULL;
    s->info = m;
    s->environment = environment;
    s->logger = logger;
    s->logging_on = logging_on;
    s->instance_name = copy_string(name);
    if (!s->instance_name || index_table(s) != 0) {
        fmi3FreeInstance(s);
        return NULL;
    }
    s->f64 = zeroed(s->count[V3_FLOAT64], sizeof *s->f64);
    s->f32 = zeroed(s->count[V3_FLOAT32], sizeof *s->f32);
    s->i8 = zeroed(s->count[V3_INT8], sizeof *s->i8);
    s->u8 = zeroed(s->count[V3_UINT8], sizeof *s->u8);
    s->i16 = zeroed(s->count[V3_INT16], sizeof *s->i16);
    s->u16 = zeroed(s->count[V3_UINT16], sizeof *s->u16);
    s->i32 = zeroed(s->count[V3_INT32], sizeof *s->i32);
    s->u32 = zeroed(s->count[V3_UINT32], sizeof *s->u32);
    s->i64 = zeroed(s->count[V3_INT64], sizeof *s->i64);
    s->u64 = zeroed(s->count[V3_UINT64], sizeof *s->u64);
    s->b = zeroed(s->count[V3_BOOLEAN], sizeof *s->b);
    s->str = zeroed(s->count[V3_STRING], sizeof *s->str);
    s->state = zeroed(1, m->state_size ? m->state_size : 1);
    if (!s->f64 || !s->f32 || !s->i8 || !s->u8 || !s->i16 || !s->u16 || !s->i32 || !s->u32 ||
        !s->i64 || !s->u64 || !s->b || !s->str || !s->state || load_defaults(s) != 0) {
        fmi3FreeInstance(s);
        return NULL;
    }
    return s;
}

/* ---- life cycle ------------------------------------------------------- */

fmi3Status fmi3EnterInitializationMode(fmi3Instance c, fmi3Boolean tol_defined, fmi3Float64 tol,
                                       fmi3Float64 start, fmi3Boolean stop_defined,
                                       fmi3Float64 stop) {
    (void)tol_defined;
    (void)tol;
    (void)stop_defined;
    (void)stop;
    Slave3 *s = c;
    if (!allowed(s, "fmi3EnterInitializationMode", 1u << INSTANTIATED)) return fmi3Error;
    s->time = start;
    s->phase = INITIALIZATION;
    if (s->info->enter_initialization && s->info->enter_initialization(s) != 0) return fail(s);
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance c) {
    Slave3 *s = c;
    if (!allowed(s, "fmi3ExitInitializationMode", 1u << INITIALIZATION)) return fmi3Error;
    if (s->info->exit_initialization && s->info->exit_initialization(s) != 0) return fail(s);
    /* Without event mode, co-simulation goes straight to step mode. */
    s->phase = STEPPING;
    return fmi3OK;
}

fmi3Status fmi3Terminate(fmi3Instance c) {
    Slave3 *s = c;
    if (!allowed(s, "fmi3Terminate", 1u << STEPPING)) return fmi3Error;
    s->phase = TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance c) {
    Slave3 *s = c;
    if (!allowed(s, "fmi3Reset", ANY_PHASE)) return fmi3Error;
    if (load_defaults(s) != 0) return fail(s);
    return fmi3OK;
}

fmi3Status fmi3DoStep(fmi3Instance c, fmi3Float64 t, fmi3Float64 h, fmi3Boolean no_set_prior,
                      fmi3Boolean *event_handling_needed, fmi3Boolean *terminate_simulation,
                      fmi3Boolean *early_return, fmi3Float64 *last_successful_time) {
    (void)no_set_prior;
    Slave3 *s = c;
    if (!allowed(s, "fmi3DoStep", 1u << STEPPING)) return fmi3Error;
    /* Set the flags first: whatever happens, the importer reads defined values. */
    if (event_handling_needed) *event_handling_needed = fmi3False;
    if (terminate_simulation) *terminate_simulation = fmi3False;
    if (early_return) *early_return = fmi3False;
    if (last_successful_time) *last_successful_time = s->time;
    if (!(h > 0.0)) {
        slave3_log(s, fmi3Error, "logStatusError", "communication step size must be > 0, got %g", h);
        return fail(s);
    }
    if (fabs(t - s->time) > 1e-9 * (1.0 + fabs(t))) {
        slave3_log(s, fmi3Error, "logStatusError",
                   "fmi3DoStep at t=%.9g but the FMU is at t=%.9g (no rollback)", t, s->time);
        return fail(s);
    }
    if (s->info->do_step(s, t, h) != 0) return fail(s);
    s->time = t + h;
    if (last_successful_time) *last_successful_time = s->time;
    return fmi3OK;
}

/* ---- variable access -------------------------------------------------- */

/* Float64 by hand: the independent variable (V3_TIME) reads the clock and
 * cannot be set. */
fmi3Status fmi3GetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t n_vrs,
                          fmi3Float64 v[], size_t n_values) {
    Slave3 *s = c;
    if (!allowed(s, "fmi3GetFloat64", ANY_PHASE)) return fmi3Error;
    if (!scalars(s, "fmi3GetFloat64", n_vrs, n_values)) return fail(s);
    for (size_t i = 0; i < n_vrs; i++) {
        const Variable3 *var = lookup(s, "fmi3GetFloat64", vr[i], V3_FLOAT64);
        if (!var) return fail(s);
        v[i] = var->type == V3_TIME ? s->time : s->f64[var->index];
    }
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t n_vrs,
                          const fmi3Float64 v[], size_t n_values) {
    Slave3 *s = c;
    if (!allowed(s, "fmi3SetFloat64", SETTABLE)) return fmi3Error;
    if (!scalars(s, "fmi3SetFloat64", n_vrs, n_values)) return fail(s);
    for (size_t i = 0; i < n_vrs; i++) {
        const Variable3 *var = lookup(s, "fmi3SetFloat64", vr[i], V3_FLOAT64);
        if (!var) return fail(s);
        if (var->type == V3_TIME) {
            slave3_log(s, fmi3Error, "logStatusError",
                       "fmi3SetFloat64: value reference %u is the independent variable (time)", vr[i]);
            return fail(s);
        }
        s->f64[var->index] = v[i];
    }
    return fmi3OK;
}

/* The other numeric types and Boolean differ only in names: one definition. */
#define ACCESSORS(Name, ctype, TYPE, array)                                                        \
    fmi3Status fmi3Get##Name(fmi3Instance c, const fmi3ValueReference vr[], size_t n_vrs,          \
                             ctype v[], size_t n_values) {                                         \
        Slave3 *s = c;                                                                             \
        if (!allowed(s, "fmi3Get" #Name, ANY_PHASE)) return fmi3Error;                             \
        if (!scalars(s, "fmi3Get" #Name, n_vrs, n_values)) return fail(s);                         \
        for (size_t i = 0; i < n_vrs; i++) {                                                       \
            const Variable3 *var = lookup(s, "fmi3Get" #Name, vr[i], TYPE);                        \
            if (!var) return fail(s);                                                              \
            v[i] = s->array[var->index];                                                           \
        }                                                                                          \
        return fmi3OK;                                                                             \
    }                                                                                              \
    fmi3Status fmi3Set##Name(fmi3Instance c, const fmi3ValueReference vr[], size_t n_vrs,          \
                             const ctype v[], size_t n_values) {                                   \
        Slave3 *s = c;                                                                             \
        if (!allowed(s, "fmi3Set" #Name, SETTABLE)) return fmi3Error;                              \
        if (!scalars(s, "fmi3Set" #Name, n_vrs, n_values)) return fail(s);                         \
        for (size_t i = 0; i < n_vrs; i++) {                                                       \
            const Variable3 *var = lookup(s, "fmi3Set" #Name, vr[i], TYPE);                        \
            if (!var) return fail(s);                                                              \
            s->array[var->index] = v[i];                                                           \
        }                                                                                          \
        return fmi3OK;                                                                             \
    }

ACCESSORS(Float32, fmi3Float32, V3_FLOAT32, f32)
ACCESSORS(Int8, fmi3Int8, V3_INT8, i8)
ACCESSORS(UInt8, fmi3UInt8, V3_UINT8, u8)
ACCESSORS(Int16, fmi3Int16, V3_INT16, i16)
ACCESSORS(UInt16, fmi3UInt16, V3_UINT16, u16)
ACCESSORS(Int32, fmi3Int32, V3_INT32, i32)
ACCESSORS(UInt32, fmi3UInt32, V3_UINT32, u32)
ACCESSORS(Int64, fmi3Int64, V3_INT64, i64)
ACCESSORS(UInt64, fmi3UInt64, V3_UINT64, u64)
ACCESSORS(Boolean, fmi3Boolean, V3_BOOLEAN, b)

fmi3Status fmi3GetString(fmi3Instance c, const fmi3ValueReference vr[], size_t n_vrs,
                         fmi3String v[], size_t n_values) {
    Slave3 *s = c;
    if (!allowed(s, "fmi3GetString", ANY_PHASE)) return fmi3Error;
    if (!scalars(s, "fmi3GetString", n_vrs, n_values)) return fail(s);
    for (size_t i = 0; i < n_vrs; i++) {
        const Variable3 *var = lookup(s, "fmi3GetString", vr[i], V3_STRING);
        if (!var) return fail(s);
        v[i] = s->str[var->index];
    }
    return fmi3OK;
}

fmi3Status fmi3SetString(fmi3Instance c, const fmi3ValueReference vr[], size_t n_vrs,
                         const fmi3String v[], size_t n_values) {
    Slave3 *s = c;
    if (!allowed(s, "fmi3SetString", SETTABLE)) return fmi3Error;
    if (!scalars(s, "fmi3SetString", n_vrs, n_values)) return fail(s);
    for (size_t i = 0; i < n_vrs; i++) {
        const Variable3 *var = lookup(s, "fmi3SetString", vr[i], V3_STRING);
        if (!var) return fail(s);
        char *copy = copy_string(v[i]);
        if (!copy) return fail(s);
        free(s->str[var->index]);
        s->str[var->index] = copy;
    }
    return fmi3OK;
}

/* ---- everything this layer declares it does not have ------------------- */

static fmi3Status unsupported(fmi3Instance c, const char *function) {
    Slave3 *s = c;
    if (s) slave3_log(s, fmi3Error, "logStatusError", "%s is not supported by this FMU", function);
    return fmi3Error;
}

/* Other interface types: there is no instance yet to log through, so use the callback directly. */
fmi3Instance fmi3InstantiateModelExchange(fmi3String name, fmi3String token, fmi3String resources,
                                          fmi3Boolean visible, fmi3Boolean logging_on,
                                          fmi3InstanceEnvironment environment,
                                          fmi3LogMessageCallback logger) {
    (void)name;
    (void)token;
    (void)resources;
    (void)visible;
    (void)logging_on;
    if (logger)
        logger(environment, fmi3Error, "logStatusError",
               "fmi3InstantiateModelExchange is not supported: this FMU is co-simulation only");
    return NULL;
}

fmi3Instance fmi3InstantiateScheduledExecution(
    fmi3String name, fmi3String token, fmi3String resources, fmi3Boolean visible,
    fmi3Boolean logging_on, fmi3InstanceEnvironment environment, fmi3LogMessageCallback logger,
    fmi3ClockUpdateCallback clock_update, fmi3LockPreemptionCallback lock,
    fmi3UnlockPreemptionCallback unlock) {
    (void)name;
    (void)token;
    (void)resources;
    (void)visible;
    (void)logging_on;
    (void)clock_update;
    (void)lock;
    (void)unlock;
    if (logger)
        logger(environment, fmi3Error, "logStatusError",
               "fmi3InstantiateScheduledExecution is not supported: this FMU is co-simulation only");
    return NULL;
}

fmi3Status fmi3EnterEventMode(fmi3Instance c) { return unsupported(c, "fmi3EnterEventMode"); }
fmi3Status fmi3EnterStepMode(fmi3Instance c) { return unsupported(c, "fmi3EnterStepMode"); }
fmi3Status fmi3EnterConfigurationMode(fmi3Instance c) {
    return unsupported(c, "fmi3EnterConfigurationMode");
}
fmi3Status fmi3ExitConfigurationMode(fmi3Instance c) {
    return unsupported(c, "fmi3ExitConfigurationMode");
}
fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance c) {
    return unsupported(c, "fmi3EvaluateDiscreteStates");
}
fmi3Status fmi3UpdateDiscreteStates(fmi3Instance c, fmi3Boolean *update, fmi3Boolean *terminate,
                                    fmi3Boolean *nominals, fmi3Boolean *values,
                                    fmi3Boolean *next_defined, fmi3Float64 *next) {
    (void)update;
    (void)terminate;
    (void)nominals;
    (void)values;
    (void)next_defined;
    (void)next;
    return unsupported(c, "fmi3UpdateDiscreteStates");
}

fmi3Status fmi3GetBinary(fmi3Instance c, const fmi3ValueReference vr[], size_t n_vrs,
                         size_t sizes[], fmi3Binary v[], size_t n_values) {
    (void)vr;
    (void)n_vrs;
    (void)sizes;
    (void)v;
    (void)n_values;
    return unsupported(c, "fmi3GetBinary");
}
fmi3Status fmi3SetBinary(fmi3Instance c, const fmi3ValueReference vr[], size_t n_vrs,
                         const size_t sizes[], const fmi3Binary v[], size_t n_values) {
    (void)vr;
    (void)n_vrs;
    (void)sizes;
    (void)v;
    (void)n_values;
    return unsupported(c, "fmi3SetBinary");
}
fmi3Status fmi3GetClock(fmi3Instance c, const fmi3ValueReference vr[], size_t n_vrs,
                        fmi3Clock v[]) {
    (void)vr;
    (void)n_vrs;
    (void)v;
    return unsupported(c, "fmi3GetClock");
}
fmi3Status fmi3SetClock(fmi3Instance c, const fmi3ValueReference vr[], size_t n_vrs,
                        const fmi3Clock v[]) {
    (void)vr;
    (void)n_vrs;
    (void)v;
    return unsupported(c, "fmi3SetClock");
}

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance c, fmi3ValueReference vr, size_t *n) {
    (void)vr;
    (void)n;
    return unsupported(c, "fmi3GetNumberOfVariableDependencies");
}
fmi3Status fmi3GetVariableDependencies(fmi3Instance c, fmi3ValueReference dependent,
                                       size_t element_indices_of_dependent[],
                                       fmi3ValueReference independents[],
                                       size_t element_indices_of_independents[],
                                       fmi3DependencyKind kinds[], size_t n) {
    (void)dependent;
    (void)element_indices_of_dependent;
    (void)independents;
    (void)element_indices_of_independents;
    (void)kinds;
    (void)n;
    return unsupported(c, "fmi3GetVariableDependencies");
}

fmi3Status fmi3GetFMUState(fmi3Instance c, fmi3FMUState *st) {
    (void)st;
    return unsupported(c, "fmi3GetFMUState");
}
fmi3Status fmi3SetFMUState(fmi3Instance c, fmi3FMUState st) {
    (void)st;
    return unsupported(c, "fmi3SetFMUState");
}
fmi3Status fmi3FreeFMUState(fmi3Instance c, fmi3FMUState *st) {
    (void)st;
    return unsupported(c, "fmi3FreeFMUState");
}
fmi3Status fmi3SerializedFMUStateSize(fmi3Instance c, fmi3FMUState st, size_t *size) {
    (void)st;
    (void)size;
    return unsupported(c, "fmi3SerializedFMUStateSize");
}
fmi3Status fmi3SerializeFMUState(fmi3Instance c, fmi3FMUState st, fmi3Byte b[], size_t size) {
    (void)st;
    (void)b;
    (void)size;
    return unsupported(c, "fmi3SerializeFMUState");
}
fmi3Status fmi3DeserializeFMUState(fmi3Instance c, const fmi3Byte b[], size_t size,
                                   fmi3FMUState *st) {
    (void)b;
    (void)size;
    (void)st;
    return unsupported(c, "fmi3DeserializeFMUState");
}

fmi3Status fmi3GetDirectionalDerivative(fmi3Instance c, const fmi3ValueReference unknowns[],
                                        size_t n_unknowns, const fmi3ValueReference knowns[],
                                        size_t n_knowns, const fmi3Float64 seed[], size_t n_seed,
                                        fmi3Float64 sensitivity[], size_t n_sensitivity) {
    (void)unknowns;
    (void)n_unknowns;
    (void)knowns;
    (void)n_knowns;
    (void)seed;
    (void)n_seed;
    (void)sensitivity;
    (void)n_sensitivity;
    return unsupported(c, "fmi3GetDirectionalDerivative");
}
fmi3Status fmi3GetAdjointDerivative(fmi3Instance c, const fmi3ValueReference unknowns[],
                                    size_t n_unknowns, const fmi3ValueReference knowns[],
                                    size_t n_knowns, const fmi3Float64 seed[], size_t n_seed,
                                    fmi3Float64 sensitivity[], size_t n_sensitivity) {
    (void)unknowns;
    (void)n_unknowns;
    (void)knowns;
    (void)n_knowns;
    (void)seed;
    (void)n_seed;
    (void)sensitivity;
    (void)n_sensitivity;
    return unsupported(c, "fmi3GetAdjointDerivative");
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance c, const fmi3ValueReference vr[], size_t n_vrs,
                                    const fmi3Int32 orders[], fmi3Float64 v[], size_t n_values) {
    (void)vr;
    (void)n_vrs;
    (void)orders;
    (void)v;
    (void)n_values;
    return unsupported(c, "fmi3GetOutputDerivatives");
}

/* Clocks (scheduled execution). */
fmi3Status fmi3GetIntervalDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t n_vrs,
                                  fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[]) {
    (void)vr;
    (void)n_vrs;
    (void)intervals;
    (void)qualifiers;
    return unsupported(c, "fmi3GetIntervalDecimal");
}
fmi3Status fmi3GetIntervalFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t n_vrs,
                                   fmi3UInt64 counters[], fmi3UInt64 resolutions[],
                                   fmi3IntervalQualifier qualifiers[]) {
    (void)vr;
    (void)n_vrs;
    (void)counters;
    (void)resolutions;
    (void)qualifiers;
    return unsupported(c, "fmi3GetIntervalFraction");
}
fmi3Status fmi3GetShiftDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t n_vrs,
                               fmi3Float64 shifts[]) {
    (void)vr;
    (void)n_vrs;
    (void)shifts;
    return unsupported(c, "fmi3GetShiftDecimal");
}
fmi3Status fmi3GetShiftFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t n_vrs,
                                fmi3UInt64 counters[], fmi3UInt64 resolutions[]) {
    (void)vr;
    (void)n_vrs;
    (void)counters;
    (void)resolutions;
    return unsupported(c, "fmi3GetShiftFraction");
}
fmi3Status fmi3SetIntervalDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t n_vrs,
                                  const fmi3Float64 intervals[]) {
    (void)vr;
    (void)n_vrs;
    (void)intervals;
    return unsupported(c, "fmi3SetIntervalDecimal");
}
fmi3Status fmi3SetIntervalFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t n_vrs,
                                   const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)vr;
    (void)n_vrs;
    (void)counters;
    (void)resolutions;
    return unsupported(c, "fmi3SetIntervalFraction");
}
fmi3Status fmi3SetShiftDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t n_vrs,
                               const fmi3Float64 shifts[]) {
    (void)vr;
    (void)n_vrs;
    (void)shifts;
    return unsupported(c, "fmi3SetShiftDecimal");
}
fmi3Status fmi3SetShiftFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t n_vrs,
                                const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)vr;
    (void)n_vrs;
    (void)counters;
    (void)resolutions;
    return unsupported(c, "fmi3SetShiftFraction");
}
fmi3Status fmi3ActivateModelPartition(fmi3Instance c, fmi3ValueReference clock,
                                      fmi3Float64 activation_time) {
    (void)clock;
    (void)activation_time;
    return unsupported(c, "fmi3ActivateModelPartition");
}

/* Model exchange. */
fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance c) {
    return unsupported(c, "fmi3EnterContinuousTimeMode");
}
fmi3Status fmi3CompletedIntegratorStep(fmi3Instance c, fmi3Boolean no_set_prior,
                                       fmi3Boolean *enter_event_mode,
                                       fmi3Boolean *terminate_simulation) {
    (void)no_set_prior;
    (void)enter_event_mode;
    (void)terminate_simulation;
    return unsupported(c, "fmi3CompletedIntegratorStep");
}
fmi3Status fmi3SetTime(fmi3Instance c, fmi3Float64 time) {
    (void)time;
    return unsupported(c, "fmi3SetTime");
}
fmi3Status fmi3SetContinuousStates(fmi3Instance c, const fmi3Float64 x[], size_t n) {
    (void)x;
    (void)n;
    return unsupported(c, "fmi3SetContinuousStates");
}
fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance c, fmi3Float64 dx[], size_t n) {
    (void)dx;
    (void)n;
    return unsupported(c, "fmi3GetContinuousStateDerivatives");
}
fmi3Status fmi3GetEventIndicators(fmi3Instance c, fmi3Float64 z[], size_t n) {
    (void)z;
    (void)n;
    return unsupported(c, "fmi3GetEventIndicators");
}
fmi3Status fmi3GetContinuousStates(fmi3Instance c, fmi3Float64 x[], size_t n) {
    (void)x;
    (void)n;
    return unsupported(c, "fmi3GetContinuousStates");
}
fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance c, fmi3Float64 nominals[], size_t n) {
    (void)nominals;
    (void)n;
    return unsupported(c, "fmi3GetNominalsOfContinuousStates");
}
fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance c, size_t *n) {
    (void)n;
    return unsupported(c, "fmi3GetNumberOfEventIndicators");
}
fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance c, size_t *n) {
    (void)n;
    return unsupported(c, "fmi3GetNumberOfContinuousStates");
}
