/*
 * me3.c: FMI 3.0 model-exchange entry points, written once for all our FMI 3
 * ME FMUs; the FMI 3 twin of me2.c.
 *
 * The model (model.c) supplies an Me3Info; this file owns the life cycle
 * instantiate -> (set parameters) -> initialization mode -> event mode <->
 * continuous-time mode -> terminate, and fmi3Reset goes back to the start
 * values so an importer can reuse one instance for many runs.  The importer
 * integrates: it sets time and states and reads derivatives.  There are no
 * event indicators and fmi3UpdateDiscreteStates never reports an event.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "me3.h"

enum { INSTANTIATED, INITIALIZATION, EVENT, CONTINUOUS, TERMINATED, FAILED };

static const char *const PHASE_NAMES[] = {
    "instantiated", "initialization mode", "event mode", "continuous-time mode", "terminated",
    "error"};

#define BIT(phase) (1u << (phase))
#define ANY_PHASE 0x3fu
#define SETTABLE (BIT(INSTANTIATED) | BIT(INITIALIZATION) | BIT(EVENT) | BIT(CONTINUOUS))
#define RUNNING (BIT(INITIALIZATION) | BIT(EVENT) | BIT(CONTINUOUS))
#define READABLE (RUNNING | BIT(TERMINATED))

void me3_log(Me3Instance *m, fmi3Status status, const char *category, const char *fmt, ...) {
    if (!m->logger) return;
    if (status == fmi3OK && !m->logging_on) return;
    /* FMI 3.0's message is plain text: no '%' escaping. */
    char msg[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    m->logger(m->environment, status, category, msg);
}

static void restart(Me3Instance *m) {
    memcpy(m->r, m->info->real_defaults, m->info->n_reals * sizeof(double));
    m->time = 0.0;
    m->phase = INSTANTIATED;
    m->stale = 1;
}

/* A call outside its allowed modes is an error that ends the instance's use. */
static int allowed(Me3Instance *m, const char *function, unsigned phases) {
    if (!m) return 0;
    if (phases & BIT(m->phase)) return 1;
    me3_log(m, fmi3Error, "logStatusError", "%s is not allowed in %s", function,
            PHASE_NAMES[m->phase]);
    m->phase = FAILED;
    return 0;
}

static fmi3Status fail(Me3Instance *m) {
    m->phase = FAILED;
    return fmi3Error;
}

static void name_of(const Me3Instance *m, fmi3ValueReference vr, char *out, size_t size) {
    if (m->info->real_names)
        snprintf(out, size, "%s", m->info->real_names[vr]);
    else
        snprintf(out, size, "value reference %u", vr);
}

/* A non-finite derivative would only make the solver fail later and obscurely. */
static int derivatives_finite(Me3Instance *m) {
    for (size_t i = 0; i < m->info->n_states; i++) {
        fmi3ValueReference vr = m->info->derivatives[i];
        if (isfinite(m->r[vr])) continue;
        char name[128];
        name_of(m, vr, name, sizeof name);
        me3_log(m, fmi3Error, "logStatusError", "%s is %g at t=%.9g", name, m->r[vr], m->time);
        return 0;
    }
    return 1;
}

/* Brings every computed value up to date with time, states and inputs. */
static int refresh(Me3Instance *m) {
    if (!m->stale || !(RUNNING & BIT(m->phase))) return 1;
    const Me3Info *info = m->info;
    m->r[info->time_vr] = m->time;
    if (m->phase == INITIALIZATION && info->initial && info->initial(m) != 0) return 0;
    if (info->equations && info->equations(m) != 0) return 0;
    if (!derivatives_finite(m)) return 0;
    m->stale = 0;
    return 1;
}

static int check_length(Me3Instance *m, const char *function, size_t given, size_t expected) {
    if (given == expected) return 1;
    me3_log(m, fmi3Error, "logStatusError", "%s: %zu values given, the model has %zu", function,
            given, expected);
    return 0;
}

/* ---- inquiry, logging, creation ---------------------------------------- */

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance c, fmi3Boolean on, size_t n, const fmi3String cats[]) {
    (void)n;
    (void)cats;
    Me3Instance *m = c;
    if (!m) return fmi3Error;
    m->logging_on = on;
    return fmi3OK;
}

static char *copy_text(const char *text) {
    const char *source = text ? text : "";
    char *copy = malloc(strlen(source) + 1);
    if (copy) strcpy(copy, source);
    return copy;
}

void fmi3FreeInstance(fmi3Instance c) {
    Me3Instance *m = c;
    if (!m) return;
    free(m->r);
    free(m->instance_name);
    free(m);
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String name, fmi3String token, fmi3String resources,
                                          fmi3Boolean visible, fmi3Boolean logging_on,
                                          fmi3InstanceEnvironment environment,
                                          fmi3LogMessageCallback logger) {
    (void)resources;
    (void)visible;
    const Me3Info *info = &ME3_MODEL;
    if (!token || strcmp(token, info->instantiation_token) != 0) {
        if (logger)
            logger(environment, fmi3Error, "logStatusError",
                   "instantiationToken does not match this FMU's modelDescription.xml");
        return NULL;
    }
    Me3Instance *m = calloc(1, sizeof *m);
    if (!m) return NULL;
    m->info = info;
    m->environment = environment;
    m->logger = logger;
    m->logging_on = logging_on;
    m->instance_name = copy_text(name);
    m->r = calloc(info->n_reals ? info->n_reals : 1, sizeof(double));
    if (!m->instance_name || !m->r) {
        fmi3FreeInstance(m);
        return NULL;
    }
    restart(m);
    return m;
}

/* ---- life cycle ------------------------------------------------------- */

fmi3Status fmi3EnterInitializationMode(fmi3Instance c, fmi3Boolean tol_defined, fmi3Float64 tol,
                                       fmi3Float64 start, fmi3Boolean stop_defined,
                                       fmi3Float64 stop) {
    (void)tol_defined;
    (void)tol;
    (void)stop_defined;
    (void)stop;
    Me3Instance *m = c;
    if (!allowed(m, "fmi3EnterInitializationMode", BIT(INSTANTIATED))) return fmi3Error;
    m->time = start;
    m->phase = INITIALIZATION;
    m->stale = 1;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance c) {
    Me3Instance *m = c;
    if (!allowed(m, "fmi3ExitInitializationMode", BIT(INITIALIZATION))) return fmi3Error;
    m->stale = 1; /* the initial states are final now: compute them one last time */
    if (!refresh(m)) return fail(m);
    m->phase = EVENT;
    return fmi3OK;
}

fmi3Status fmi3Terminate(fmi3Instance c) {
    Me3Instance *m = c;
    if (!allowed(m, "fmi3Terminate", BIT(EVENT) | BIT(CONTINUOUS))) return fmi3Error;
    if (!refresh(m)) return fail(m);
    m->phase = TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance c) {
    Me3Instance *m = c;
    if (!allowed(m, "fmi3Reset", ANY_PHASE)) return fmi3Error;
    restart(m);
    return fmi3OK;
}

/* ---- event mode and continuous-time mode ------------------------------- */

fmi3Status fmi3EnterEventMode(fmi3Instance c) {
    Me3Instance *m = c;
    if (!allowed(m, "fmi3EnterEventMode", BIT(EVENT) | BIT(CONTINUOUS))) return fmi3Error;
    m->phase = EVENT;
    return fmi3OK;
}

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance c, fmi3Boolean *update, fmi3Boolean *terminate,
                                    fmi3Boolean *nominals, fmi3Boolean *values,
                                    fmi3Boolean *next_defined, fmi3Float64 *next) {
    Me3Instance *m = c;
    if (!allowed(m, "fmi3UpdateDiscreteStates", BIT(EVENT))) return fmi3Error;
    if (!refresh(m)) return fail(m);
    if (update) *update = fmi3False;
    if (terminate) *terminate = fmi3False;
    if (nominals) *nominals = fmi3False;
    if (values) *values = fmi3False;
    if (next_defined) *next_defined = fmi3False;
    if (next) *next = 0.0;
    return fmi3OK;
}

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance c) {
    Me3Instance *m = c;
    if (!allowed(m, "fmi3EnterContinuousTimeMode", BIT(EVENT))) return fmi3Error;
    m->phase = CONTINUOUS;
    return fmi3OK;
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance c, fmi3Boolean no_set_prior,
                                       fmi3Boolean *enter_event_mode,
                                       fmi3Boolean *terminate_simulation) {
    (void)no_set_prior;
    Me3Instance *m = c;
    if (!allowed(m, "fmi3CompletedIntegratorStep", BIT(CONTINUOUS))) return fmi3Error;
    *enter_event_mode = fmi3False; /* no step events */
    *terminate_simulation = fmi3False;
    return fmi3OK;
}

fmi3Status fmi3SetTime(fmi3Instance c, fmi3Float64 time) {
    Me3Instance *m = c;
    if (!allowed(m, "fmi3SetTime", BIT(EVENT) | BIT(CONTINUOUS))) return fmi3Error;
    m->time = time;
    m->stale = 1;
    return fmi3OK;
}

fmi3Status fmi3SetContinuousStates(fmi3Instance c, const fmi3Float64 x[], size_t n) {
    Me3Instance *m = c;
    if (!allowed(m, "fmi3SetContinuousStates", BIT(CONTINUOUS))) return fmi3Error;
    if (!check_length(m, "fmi3SetContinuousStates", n, m->info->n_states)) return fail(m);
    for (size_t i = 0; i < n; i++) m->r[m->info->states[i]] = x[i];
    m->stale = 1;
    return fmi3OK;
}

fmi3Status fmi3GetContinuousStates(fmi3Instance c, fmi3Float64 x[], size_t n) {
    Me3Instance *m = c;
    if (!allowed(m, "fmi3GetContinuousStates", READABLE)) return fmi3Error;
    if (!check_length(m, "fmi3GetContinuousStates", n, m->info->n_states)) return fail(m);
    if (!refresh(m)) return fail(m);
    for (size_t i = 0; i < n; i++) x[i] = m->r[m->info->states[i]];
    return fmi3OK;
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance c, fmi3Float64 dx[], size_t n) {
    Me3Instance *m = c;
    if (!allowed(m, "fmi3GetContinuousStateDerivatives", READABLE)) return fmi3Error;
    if (!check_length(m, "fmi3GetContinuousStateDerivatives", n, m->info->n_states)) return fail(m);
    if (!refresh(m)) return fail(m);
    for (size_t i = 0; i < n; i++) dx[i] = m->r[m->info->derivatives[i]];
    return fmi3OK;
}

fmi3Status fmi3GetEventIndicators(fmi3Instance c, fmi3Float64 z[], size_t n) {
    (void)z;
    Me3Instance *m = c;
    if (!allowed(m, "fmi3GetEventIndicators", READABLE)) return fmi3Error;
    if (!check_length(m, "fmi3GetEventIndicators", n, 0)) return fail(m);
    return fmi3OK;
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance c, fmi3Float64 nominals[], size_t n) {
    Me3Instance *m = c;
    if (!allowed(m, "fmi3GetNominalsOfContinuousStates", BIT(INSTANTIATED) | READABLE))
        return fmi3Error;
    if (!check_length(m, "fmi3GetNominalsOfContinuousStates", n, m->info->n_states)) return fail(m);
    for (size_t i = 0; i < n; i++) nominals[i] = m->info->nominals ? m->info->nominals[i] : 1.0;
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance c, size_t *n) {
    Me3Instance *m = c;
    if (!allowed(m, "fmi3GetNumberOfEventIndicators", ANY_PHASE)) return fmi3Error;
    *n = 0;
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance c, size_t *n) {
    Me3Instance *m = c;
    if (!allowed(m, "fmi3GetNumberOfContinuousStates", ANY_PHASE)) return fmi3Error;
    *n = m->info->n_states;
    return fmi3OK;
}

/* ---- variable access: Float64 only ------------------------------------- */

static int known(Me3Instance *m, const char *function, const fmi3ValueReference vr[], size_t n,
                 size_t n_values) {
    if (n != n_values) {
        me3_log(m, fmi3Error, "logStatusError",
                "%s: %zu values for %zu value references (this FMU has no array variables)",
                function, n_values, n);
        return 0;
    }
    for (size_t i = 0; i < n; i++)
        if (vr[i] >= m->info->n_reals) {
            me3_log(m, fmi3Error, "logStatusError", "%s: unknown value reference %u", function, vr[i]);
            return 0;
        }
    return 1;
}

fmi3Status fmi3GetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
                          fmi3Float64 v[], size_t n_values) {
    Me3Instance *m = c;
    if (!allowed(m, "fmi3GetFloat64", ANY_PHASE)) return fmi3Error;
    if (!known(m, "fmi3GetFloat64", vr, n, n_values) || !refresh(m)) return fail(m);
    for (size_t i = 0; i < n; i++) v[i] = vr[i] == m->info->time_vr ? m->time : m->r[vr[i]];
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
                          const fmi3Float64 v[], size_t n_values) {
    Me3Instance *m = c;
    if (!allowed(m, "fmi3SetFloat64", SETTABLE)) return fmi3Error;
    if (!known(m, "fmi3SetFloat64", vr, n, n_values)) return fail(m);
    for (size_t i = 0; i < n; i++)
        if (vr[i] == m->info->time_vr) {
            me3_log(m, fmi3Error, "logStatusError",
                    "fmi3SetFloat64: the independent variable cannot be set (use fmi3SetTime)");
            return fail(m);
        }
    for (size_t i = 0; i < n; i++) m->r[vr[i]] = v[i];
    m->stale = 1;
    return fmi3OK;
}

/* Only Float64 variables: any other type's reference is unknown. */
static fmi3Status no_such_variable(fmi3Instance c, const char *function, size_t n) {
    Me3Instance *m = c;
    if (!m) return fmi3Error;
    if (n == 0) return fmi3OK;
    me3_log(m, fmi3Error, "logStatusError", "%s: this FMU has no such variables", function);
    return fail(m);
}

#define NO_ACCESS(Name, ctype)                                                                     \
    fmi3Status fmi3Get##Name(fmi3Instance c, const fmi3ValueReference vr[], size_t n_vrs,          \
                             ctype v[], size_t n_values) {                                         \
        (void)vr;                                                                                  \
        (void)v;                                                                                   \
        (void)n_values;                                                                            \
        return no_such_variable(c, "fmi3Get" #Name, n_vrs);                                        \
    }                                                                                              \
    fmi3Status fmi3Set##Name(fmi3Instance c, const fmi3ValueReference vr[], size_t n_vrs,          \
                             const ctype v[], size_t n_values) {                                   \
        (void)vr;                                                                                  \
        (void)v;                                                                                   \
        (void)n_values;                                                                            \
        return no_such_variable(c, "fmi3Set" #Name, n_vrs);                                        \
    }

NO_ACCESS(Float32, fmi3Float32)
NO_ACCESS(Int8, fmi3Int8)
NO_ACCESS(UInt8, fmi3UInt8)
NO_ACCESS(Int16, fmi3Int16)
NO_ACCESS(UInt16, fmi3UInt16)
NO_ACCESS(Int32, fmi3Int32)
NO_ACCESS(UInt32, fmi3UInt32)
NO_ACCESS(Int64, fmi3Int64)
NO_ACCESS(UInt64, fmi3UInt64)
NO_ACCESS(Boolean, fmi3Boolean)
NO_ACCESS(String, fmi3String)

/* ---- everything this layer declares it does not have ------------------- */

static fmi3Status unsupported(fmi3Instance c, const char *function) {
    Me3Instance *m = c;
    if (m) me3_log(m, fmi3Error, "logStatusError", "%s is not supported by this FMU", function);
    return fmi3Error;
}

/* Other interface types: there is no instance yet to log through, so use the callback directly. */
fmi3Instance fmi3InstantiateCoSimulation(
    fmi3String name, fmi3String token, fmi3String resources, fmi3Boolean visible,
    fmi3Boolean logging_on, fmi3Boolean event_mode_used, fmi3Boolean early_return_allowed,
    const fmi3ValueReference required_intermediate[], size_t n_required_intermediate,
    fmi3InstanceEnvironment environment, fmi3LogMessageCallback logger,
    fmi3IntermediateUpdateCallback intermediate_update) {
    (void)name;
    (void)token;
    (void)resources;
    (void)visible;
    (void)logging_on;
    (void)event_mode_used;
    (void)early_return_allowed;
    (void)required_intermediate;
    (void)n_required_intermediate;
    (void)intermediate_update;
    if (logger)
        logger(environment, fmi3Error, "logStatusError",
               "fmi3InstantiateCoSimulation is not supported: this FMU is model exchange only");
    return NULL;
}

fmi3Status fmi3DoStep(fmi3Instance c, fmi3Float64 t, fmi3Float64 h, fmi3Boolean no_set_prior,
                      fmi3Boolean *event_handling_needed, fmi3Boolean *terminate_simulation,
                      fmi3Boolean *early_return, fmi3Float64 *last_successful_time) {
    (void)t;
    (void)h;
    (void)no_set_prior;
    (void)event_handling_needed;
    (void)terminate_simulation;
    (void)early_return;
    (void)last_successful_time;
    return unsupported(c, "fmi3DoStep");
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
               "fmi3InstantiateScheduledExecution is not supported: this FMU is model exchange only");
    return NULL;
}

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
