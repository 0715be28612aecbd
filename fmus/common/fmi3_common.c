/*
 * fmi3_common.c: the fmi3* functions both FMI 3.0 layers implement alike,
 * and the helpers slave3.c and me3.c build on (fmi3_common.h).
 */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3_common.h"
#include "fmi_common.h"

/* The numeric and Boolean types, each with its C type and its array in the
 * instance: allocation, release and start values go through this one list. */
#define V3_NUMERIC(X)                                                                             \
    X(V3_FLOAT64, fmi3Float64, f64) X(V3_FLOAT32, fmi3Float32, f32) X(V3_INT8, fmi3Int8, i8)      \
    X(V3_UINT8, fmi3UInt8, u8) X(V3_INT16, fmi3Int16, i16) X(V3_UINT16, fmi3UInt16, u16)          \
    X(V3_INT32, fmi3Int32, i32) X(V3_UINT32, fmi3UInt32, u32) X(V3_INT64, fmi3Int64, i64)         \
    X(V3_UINT64, fmi3UInt64, u64) X(V3_BOOLEAN, fmi3Boolean, b)

static const char *const TYPE_NAMES[V3_N_TYPES] = {
    "Float64", "Float32", "Int8",    "UInt8",  "Int16",  "UInt16", "Int32",
    "UInt32",  "Int64",   "UInt64",  "Boolean", "String", "Float64 (time)"};

/* Unlike FMI 2.0, FMI 3.0's message is plain text: no '%' escaping. */
static void emit(FmiCore *c, int status, const char *category, const char *message) {
    Fmi3Instance *s = (Fmi3Instance *)c;
    if (s->logger) s->logger(s->environment, (fmi3Status)status, category, message);
}

static int refresh(FmiCore *c) { return fmi3_refresh((Fmi3Instance *)c); }

static int enter_initialization(FmiCore *c) {
    Fmi3Instance *s = (Fmi3Instance *)c;
    return s->model.enter_initialization ? s->model.enter_initialization(s) : 0;
}

static int exit_initialization(FmiCore *c) {
    Fmi3Instance *s = (Fmi3Instance *)c;
    return s->model.exit_initialization ? s->model.exit_initialization(s) : 0;
}

static const FmiCalls CALLS = {emit, refresh, enter_initialization, exit_initialization};

_Static_assert((int)fmi3OK == FMI_OK && (int)fmi3Warning == FMI_WARNING && (int)fmi3Discard == FMI_DISCARD &&
                   (int)fmi3Error == FMI_ERROR && (int)fmi3Fatal == FMI_FATAL,
               "fmi_common.h numbers the statuses as FMI 3.0 does");

void fmi3_log(Fmi3Instance *s, fmi3Status status, const char *category, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    fmi_vlog(&s->core, status, category, fmt, ap);
    va_end(ap);
}

/* Back to the start values, as after instantiation; 1 if out of memory. */
static int restart(Fmi3Instance *s) {
    const Fmi3Model *m = &s->model;
    for (size_t k = 0; k < m->n_variables; k++) {
        const Variable3 *v = &m->variables[k];
        size_t i = v->index;
        switch (v->type) {
#define START(TYPE, ctype, array) \
    case TYPE: s->array[i] = (ctype)v->start; break;
            V3_NUMERIC(START)
        case V3_STRING: {
            char *copy = fmi_copy_text(v->start_string);
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
    s->stale = 1;
    return 0;
}

/* ---- the variable table ------------------------------------------------ */

static int by_vr_order(const void *a, const void *b) {
    fmi3ValueReference x = (*(const Variable3 *const *)a)->vr, y = (*(const Variable3 *const *)b)->vr;
    return x < y ? -1 : x > y;
}

/* Checks the model's table once per instance, so a mistake in model.c is a
 * clear message at instantiation instead of a stray write later: types in
 * range, value references unique, each type's indices exactly 0..n-1. */
static int index_table(Fmi3Instance *s) {
    const Fmi3Model *m = &s->model;
    for (size_t k = 0; k < m->n_variables; k++) {
        const Variable3 *v = &m->variables[k];
        if ((unsigned)v->type >= V3_N_TYPES) {
            fmi3_log(s, fmi3Error, "logStatusError", "variable table entry %zu: unknown type %d", k,
                     (int)v->type);
            return 1;
        }
        if (v->type < V3_N_STORED) s->count[v->type]++;
    }
    for (size_t k = 0; k < m->n_variables; k++) {
        const Variable3 *v = &m->variables[k];
        if (v->type == V3_TIME) continue;
        if (v->index >= s->count[v->type]) {
            fmi3_log(s, fmi3Error, "logStatusError",
                     "variable table: value reference %u has %s index %zu, but there are only %zu %s "
                     "variables",
                     v->vr, TYPE_NAMES[v->type], v->index, s->count[v->type], TYPE_NAMES[v->type]);
            return 1;
        }
        for (size_t j = 0; j < k; j++)
            if (m->variables[j].type == v->type && m->variables[j].index == v->index) {
                fmi3_log(s, fmi3Error, "logStatusError",
                         "variable table: value references %u and %u share %s index %zu",
                         m->variables[j].vr, v->vr, TYPE_NAMES[v->type], v->index);
                return 1;
            }
    }
    s->by_vr = fmi_zeroed(m->n_variables, sizeof *s->by_vr);
    if (!s->by_vr) return 1;
    for (size_t k = 0; k < m->n_variables; k++) s->by_vr[k] = &m->variables[k];
    qsort(s->by_vr, m->n_variables, sizeof *s->by_vr, by_vr_order);
    for (size_t k = 1; k < m->n_variables; k++)
        if (s->by_vr[k]->vr == s->by_vr[k - 1]->vr) {
            fmi3_log(s, fmi3Error, "logStatusError", "variable table: value reference %u appears twice",
                     s->by_vr[k]->vr);
            return 1;
        }
    return 0;
}

/* The variable with reference vr, which must be of the type the caller
 * accesses; NULL after logging otherwise. */
static const Variable3 *lookup(Fmi3Instance *s, const char *function, fmi3ValueReference vr,
                               VarType3 type) {
    size_t lo = 0, hi = s->model.n_variables;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (s->by_vr[mid]->vr < vr)
            lo = mid + 1;
        else
            hi = mid;
    }
    if (lo == s->model.n_variables || s->by_vr[lo]->vr != vr) {
        fmi3_log(s, fmi3Error, "logStatusError", "%s: unknown value reference %u", function, vr);
        return NULL;
    }
    const Variable3 *v = s->by_vr[lo];
    int same = v->type == type || (type == V3_FLOAT64 && v->type == V3_TIME);
    if (!same) {
        fmi3_log(s, fmi3Error, "logStatusError", "%s: value reference %u is a %s variable", function,
                 vr, TYPE_NAMES[v->type]);
        return NULL;
    }
    return v;
}

/* ---- inquiry, logging, creation ---------------------------------------- */

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance c, fmi3Boolean on, size_t n, const fmi3String cats[]) {
    (void)n;
    (void)cats;
    return (fmi3Status)fmi_set_debug_logging(fmi3_core(c), on);
}

void fmi3FreeInstance(fmi3Instance c) {
    Fmi3Instance *s = c;
    if (!s) return;
    if (s->model.release && s->state) s->model.release(s);
    if (s->str)
        for (size_t i = 0; i < s->count[V3_STRING]; i++) free(s->str[i]);
#define RELEASE(TYPE, ctype, array) free(s->array);
    V3_NUMERIC(RELEASE)
    free(s->str);
    free(s->by_vr);
    free(s->own_variables);
    free(s->state);
    free(s->instance_name);
    free(s);
}

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
    return fmi3_create(1, name, token, event_mode_used, logging_on, environment, logger);
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String name, fmi3String token, fmi3String resources,
                                          fmi3Boolean visible, fmi3Boolean logging_on,
                                          fmi3InstanceEnvironment environment,
                                          fmi3LogMessageCallback logger) {
    (void)resources;
    (void)visible;
    return fmi3_create(0, name, token, fmi3False, logging_on, environment, logger);
}

Fmi3Instance *fmi3_instantiate(fmi3String name, fmi3String token, const char *model_token,
                               const char *refusal, fmi3Boolean logging_on,
                               fmi3InstanceEnvironment environment, fmi3LogMessageCallback logger,
                               const Fmi3Model *model) {
    if (!refusal && (!token || strcmp(token, model_token) != 0))
        refusal = "instantiationToken does not match this FMU's modelDescription.xml";
    if (refusal) {
        if (logger) logger(environment, fmi3Error, "logStatusError", refusal);
        return NULL;
    }
    Fmi3Instance *s = calloc(1, sizeof *s);
    if (!s) return NULL;
    s->model = *model;
    s->calls = &CALLS;
    s->co_simulation = model->co_simulation;
    s->environment = environment;
    s->logger = logger;
    s->logging_on = logging_on;
    s->instance_name = fmi_copy_text(name);
    if (!s->instance_name || index_table(s) != 0) {
        fmi3FreeInstance(s);
        return NULL;
    }
    int allocated = 1;
#define ALLOCATE(TYPE, ctype, array)                             \
    s->array = fmi_zeroed(s->count[TYPE], sizeof *s->array); \
    allocated = allocated && s->array;
    V3_NUMERIC(ALLOCATE)
    s->str = fmi_zeroed(s->count[V3_STRING], sizeof *s->str);
    s->state = fmi_zeroed(1, model->state_size ? model->state_size : 1);
    if (!allocated || !s->str || !s->state || restart(s) != 0) {
        fmi3FreeInstance(s);
        return NULL;
    }
    return s;
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance c, fmi3Boolean tol_defined, fmi3Float64 tol,
                                       fmi3Float64 start, fmi3Boolean stop_defined, fmi3Float64 stop) {
    (void)tol_defined;
    (void)tol;
    (void)stop_defined;
    (void)stop;
    return (fmi3Status)fmi_enter_initialization(fmi3_core(c), "fmi3EnterInitializationMode", start);
}

/* Co-simulation without event mode goes straight to step mode; model exchange starts in event mode. */
fmi3Status fmi3ExitInitializationMode(fmi3Instance c) {
    return (fmi3Status)fmi_exit_initialization(fmi3_core(c), "fmi3ExitInitializationMode");
}

fmi3Status fmi3Terminate(fmi3Instance c) { return (fmi3Status)fmi_terminate(fmi3_core(c), "fmi3Terminate"); }

fmi3Status fmi3Reset(fmi3Instance c) {
    Fmi3Instance *s = c;
    if (!fmi3_allowed(s, "fmi3Reset", ANY_PHASE)) return fmi3Error;
    if (restart(s) != 0) return fmi3_fail(s);
    return fmi3OK;
}

/* ---- variable access -------------------------------------------------- */

/* Arrays are not supported: one value per value reference.  A read then
 * brings computed values up to date, a write marks them stale. */
static int accessible(Fmi3Instance *s, const char *function, size_t n_vrs, size_t n_values, int reading) {
    if (n_vrs != n_values) {
        fmi3_log(s, fmi3Error, "logStatusError",
                 "%s: %zu values for %zu value references (this FMU has no array variables)", function,
                 n_values, n_vrs);
        return 0;
    }
    if (reading) return fmi3_refresh(s);
    s->stale = 1;
    return 1;
}

/* How a value is written: most types plainly; Float64 minding the independent
 * variable (V3_TIME), which reads the clock and cannot be set; String as an
 * owned copy.  Each returns 0 after logging if it cannot. */
static int store_float64(Fmi3Instance *s, const Variable3 *var, fmi3Float64 value) {
    if (var->type == V3_TIME) {
        fmi3_log(s, fmi3Error, "logStatusError",
                 "fmi3SetFloat64: value reference %u is the independent variable (time)", var->vr);
        return 0;
    }
    s->f64[var->index] = value;
    return 1;
}

static int store_string(Fmi3Instance *s, const Variable3 *var, fmi3String value) {
    char *copy = fmi_copy_text(value);
    if (!copy) return 0;
    free(s->str[var->index]);
    s->str[var->index] = copy;
    return 1;
}

#define PLAIN_STORE(array) (s->array[var->index] = v[i], 1)

/* Get and Set of one type, which differ in names and in LOAD (the value of
 * var in s) and STORE (writes v[i] to var in s, 0 if it cannot). */
#define ACCESSORS(Name, ctype, TYPE, LOAD, STORE)                                                  \
    fmi3Status fmi3Get##Name(fmi3Instance c, const fmi3ValueReference vr[], size_t n_vrs,          \
                             ctype v[], size_t n_values) {                                         \
        Fmi3Instance *s = c;                                                                       \
        if (!fmi3_allowed(s, "fmi3Get" #Name, ANY_PHASE)) return fmi3Error;                        \
        if (!accessible(s, "fmi3Get" #Name, n_vrs, n_values, 1)) return fmi3_fail(s);              \
        for (size_t i = 0; i < n_vrs; i++) {                                                       \
            const Variable3 *var = lookup(s, "fmi3Get" #Name, vr[i], TYPE);                        \
            if (!var) return fmi3_fail(s);                                                         \
            v[i] = LOAD;                                                                           \
        }                                                                                          \
        return fmi3OK;                                                                             \
    }                                                                                              \
    fmi3Status fmi3Set##Name(fmi3Instance c, const fmi3ValueReference vr[], size_t n_vrs,          \
                             const ctype v[], size_t n_values) {                                   \
        Fmi3Instance *s = c;                                                                       \
        if (!fmi3_allowed(s, "fmi3Set" #Name, SETTABLE)) return fmi3Error;                         \
        if (!accessible(s, "fmi3Set" #Name, n_vrs, n_values, 0)) return fmi3_fail(s);             \
        for (size_t i = 0; i < n_vrs; i++) {                                                       \
            const Variable3 *var = lookup(s, "fmi3Set" #Name, vr[i], TYPE);                        \
            if (!var || !(STORE)) return fmi3_fail(s);                                             \
        }                                                                                          \
        return fmi3OK;                                                                             \
    }
#define PLAIN_ACCESSORS(Name, ctype, TYPE, array) \
    ACCESSORS(Name, ctype, TYPE, s->array[var->index], PLAIN_STORE(array))

ACCESSORS(Float64, fmi3Float64, V3_FLOAT64, var->type == V3_TIME ? s->time : s->f64[var->index],
          store_float64(s, var, v[i]))
PLAIN_ACCESSORS(Float32, fmi3Float32, V3_FLOAT32, f32)
PLAIN_ACCESSORS(Int8, fmi3Int8, V3_INT8, i8)
PLAIN_ACCESSORS(UInt8, fmi3UInt8, V3_UINT8, u8)
PLAIN_ACCESSORS(Int16, fmi3Int16, V3_INT16, i16)
PLAIN_ACCESSORS(UInt16, fmi3UInt16, V3_UINT16, u16)
PLAIN_ACCESSORS(Int32, fmi3Int32, V3_INT32, i32)
PLAIN_ACCESSORS(UInt32, fmi3UInt32, V3_UINT32, u32)
PLAIN_ACCESSORS(Int64, fmi3Int64, V3_INT64, i64)
PLAIN_ACCESSORS(UInt64, fmi3UInt64, V3_UINT64, u64)
PLAIN_ACCESSORS(Boolean, fmi3Boolean, V3_BOOLEAN, b)
ACCESSORS(String, fmi3String, V3_STRING, s->str[var->index], store_string(s, var, v[i]))

/* ---- everything neither layer has -------------------------------------- */

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
               "fmi3InstantiateScheduledExecution is not supported: this FMU has no scheduled execution");
    return NULL;
}

FMI3_UNSUPPORTED_CALL(fmi3EnterConfigurationMode)
FMI3_UNSUPPORTED_CALL(fmi3ExitConfigurationMode)
FMI3_UNSUPPORTED_CALL(fmi3EvaluateDiscreteStates)

FMI3_UNSUPPORTED(fmi3GetBinary, const fmi3ValueReference vr[], size_t n_vrs, size_t sizes[],
                 fmi3Binary v[], size_t n_values)
FMI3_UNSUPPORTED(fmi3SetBinary, const fmi3ValueReference vr[], size_t n_vrs, const size_t sizes[],
                 const fmi3Binary v[], size_t n_values)
FMI3_UNSUPPORTED(fmi3GetClock, const fmi3ValueReference vr[], size_t n_vrs, fmi3Clock v[])
FMI3_UNSUPPORTED(fmi3SetClock, const fmi3ValueReference vr[], size_t n_vrs, const fmi3Clock v[])
FMI3_UNSUPPORTED(fmi3GetNumberOfVariableDependencies, fmi3ValueReference vr, size_t *n)
FMI3_UNSUPPORTED(fmi3GetVariableDependencies, fmi3ValueReference dependent,
                 size_t element_indices_of_dependent[], fmi3ValueReference independents[],
                 size_t element_indices_of_independents[], fmi3DependencyKind kinds[], size_t n)

FMI3_UNSUPPORTED(fmi3GetFMUState, fmi3FMUState *st)
FMI3_UNSUPPORTED(fmi3SetFMUState, fmi3FMUState st)
FMI3_UNSUPPORTED(fmi3FreeFMUState, fmi3FMUState *st)
FMI3_UNSUPPORTED(fmi3SerializedFMUStateSize, fmi3FMUState st, size_t *size)
FMI3_UNSUPPORTED(fmi3SerializeFMUState, fmi3FMUState st, fmi3Byte b[], size_t size)
FMI3_UNSUPPORTED(fmi3DeserializeFMUState, const fmi3Byte b[], size_t size, fmi3FMUState *st)

FMI3_UNSUPPORTED(fmi3GetDirectionalDerivative, const fmi3ValueReference unknowns[], size_t n_unknowns,
                 const fmi3ValueReference knowns[], size_t n_knowns, const fmi3Float64 seed[],
                 size_t n_seed, fmi3Float64 sensitivity[], size_t n_sensitivity)
FMI3_UNSUPPORTED(fmi3GetAdjointDerivative, const fmi3ValueReference unknowns[], size_t n_unknowns,
                 const fmi3ValueReference knowns[], size_t n_knowns, const fmi3Float64 seed[],
                 size_t n_seed, fmi3Float64 sensitivity[], size_t n_sensitivity)
FMI3_UNSUPPORTED(fmi3GetOutputDerivatives, const fmi3ValueReference vr[], size_t n_vrs,
                 const fmi3Int32 orders[], fmi3Float64 v[], size_t n_values)

/* Clocks (scheduled execution). */
FMI3_UNSUPPORTED(fmi3GetIntervalDecimal, const fmi3ValueReference vr[], size_t n_vrs,
                 fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[])
FMI3_UNSUPPORTED(fmi3GetIntervalFraction, const fmi3ValueReference vr[], size_t n_vrs,
                 fmi3UInt64 counters[], fmi3UInt64 resolutions[], fmi3IntervalQualifier qualifiers[])
FMI3_UNSUPPORTED(fmi3GetShiftDecimal, const fmi3ValueReference vr[], size_t n_vrs, fmi3Float64 shifts[])
FMI3_UNSUPPORTED(fmi3GetShiftFraction, const fmi3ValueReference vr[], size_t n_vrs,
                 fmi3UInt64 counters[], fmi3UInt64 resolutions[])
FMI3_UNSUPPORTED(fmi3SetIntervalDecimal, const fmi3ValueReference vr[], size_t n_vrs,
                 const fmi3Float64 intervals[])
FMI3_UNSUPPORTED(fmi3SetIntervalFraction, const fmi3ValueReference vr[], size_t n_vrs,
                 const fmi3UInt64 counters[], const fmi3UInt64 resolutions[])
FMI3_UNSUPPORTED(fmi3SetShiftDecimal, const fmi3ValueReference vr[], size_t n_vrs,
                 const fmi3Float64 shifts[])
FMI3_UNSUPPORTED(fmi3SetShiftFraction, const fmi3ValueReference vr[], size_t n_vrs,
                 const fmi3UInt64 counters[], const fmi3UInt64 resolutions[])
FMI3_UNSUPPORTED(fmi3ActivateModelPartition, fmi3ValueReference clock, fmi3Float64 activation_time)
