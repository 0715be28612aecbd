/*
 * me2.c: FMI 2.0 model-exchange entry points, written once for all our ME FMUs.
 *
 * The model (model.c) supplies an MeInfo; this file owns the life cycle
 * instantiate -> (set parameters) -> initialization mode -> event mode <->
 * continuous-time mode -> terminate, and fmi2Reset goes back to the start
 * values so an importer can reuse one instance for many runs.  The importer
 * integrates: it sets time and states, reads derivatives and event indicators.
 *
 * Inputs may be set in continuous-time mode as well as in event mode (the
 * standard allows it for continuous inputs; ours are all Real).
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "me2.h"

enum { INSTANTIATED, INITIALIZATION, EVENT, CONTINUOUS, TERMINATED, FAILED };

static const char *const PHASE_NAMES[] = {
    "instantiated", "initialization mode", "event mode", "continuous-time mode", "terminated",
    "error"};

#define BIT(phase) (1u << (phase))
#define ANY_PHASE 0x3fu
#define SETTABLE (BIT(INSTANTIATED) | BIT(INITIALIZATION) | BIT(EVENT) | BIT(CONTINUOUS))
#define RUNNING (BIT(INITIALIZATION) | BIT(EVENT) | BIT(CONTINUOUS))
#define READABLE (RUNNING | BIT(TERMINATED))

void me_log(MeInstance *m, fmi2Status status, const char *category, const char *fmt, ...) {
    if (!m->cb || !m->cb->logger) return;
    if (status == fmi2OK && !m->logging_on) return;
    char text[1024], safe[2048];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    /* The importer treats the message as a printf format: escape every '%'. */
    size_t out = 0;
    for (const char *p = text; *p && out + 2 < sizeof safe; p++) {
        if (*p == '%') safe[out++] = '%';
        safe[out++] = *p;
    }
    safe[out] = '\0';
    m->cb->logger(m->cb->componentEnvironment, m->instance_name, status, category, safe);
}

static void restart(MeInstance *m) {
    memcpy(m->r, m->info->real_defaults, m->info->n_reals * sizeof(double));
    m->time = 0.0;
    m->phase = INSTANTIATED;
    m->stale = 1;
}

/* A call outside its allowed modes is an error that ends the instance's use. */
static int allowed(MeInstance *m, const char *function, unsigned phases) {
    if (!m) return 0;
    if (phases & BIT(m->phase)) return 1;
    me_log(m, fmi2Error, "logStatusError", "%s is not allowed in %s", function,
           PHASE_NAMES[m->phase]);
    m->phase = FAILED;
    return 0;
}

static fmi2Status fail(MeInstance *m) {
    m->phase = FAILED;
    return fmi2Error;
}

static void name_of(const MeInstance *m, fmi2ValueReference vr, char *out, size_t size) {
    if (m->info->real_names)
        snprintf(out, size, "%s", m->info->real_names[vr]);
    else
        snprintf(out, size, "value reference %u", vr);
}

/* A non-finite derivative would only make the solver fail later and obscurely. */
static int derivatives_finite(MeInstance *m) {
    for (size_t i = 0; i < m->info->n_states; i++) {
        fmi2ValueReference vr = m->info->derivatives[i];
        if (isfinite(m->r[vr])) continue;
        char name[128];
        name_of(m, vr, name, sizeof name);
        me_log(m, fmi2Error, "logStatusError", "%s is %g at t=%.9g", name, m->r[vr], m->time);
        return 0;
    }
    return 1;
}

/* Brings every computed value up to date with time, states and inputs. */
static int refresh(MeInstance *m) {
    if (!m->stale || !(RUNNING & BIT(m->phase))) return 1;
    const MeInfo *info = m->info;
    if (m->phase == INITIALIZATION && info->initial && info->initial(m) != 0) return 0;
    if (info->equations && info->equations(m) != 0) return 0;
    if (!derivatives_finite(m)) return 0;
    m->stale = 0;
    return 1;
}

/* The array length an importer passes must match the model's. */
static int check_length(MeInstance *m, const char *function, size_t given, size_t expected) {
    if (given == expected) return 1;
    me_log(m, fmi2Error, "logStatusError", "%s: %zu values given, the model has %zu", function,
           given, expected);
    return 0;
}

/* ---- inquiry, logging, creation ---------------------------------------- */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[]) {
    (void)n;
    (void)cats;
    MeInstance *m = c;
    if (!m) return fmi2Error;
    m->logging_on = on;
    return fmi2OK;
}

static char *copy_text(const char *text) {
    const char *source = text ? text : "";
    char *copy = malloc(strlen(source) + 1);
    if (copy) strcpy(copy, source);
    return copy;
}

static const char *refusal(fmi2Type type, fmi2String guid, const MeInfo *info) {
    if (type != fmi2ModelExchange) return "only model exchange is supported";
    if (!guid || strcmp(guid, info->guid) != 0)
        return "GUID does not match this FMU's modelDescription.xml";
    return NULL;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                              const fmi2CallbackFunctions *cb, fmi2Boolean visible,
                              fmi2Boolean logging_on) {
    (void)resources;
    (void)visible;
    const MeInfo *info = &ME_MODEL;
    const char *why = refusal(type, guid, info);
    if (why) {
        if (cb && cb->logger) cb->logger(cb->componentEnvironment, name, fmi2Error, "logStatusError", why);
        return NULL;
    }
    MeInstance *m = calloc(1, sizeof *m);
    if (!m) return NULL;
    m->info = info;
    m->cb = cb;
    m->logging_on = logging_on;
    m->instance_name = copy_text(name);
    m->r = calloc(info->n_reals ? info->n_reals : 1, sizeof(double));
    if (!m->instance_name || !m->r) {
        fmi2FreeInstance(m);
        return NULL;
    }
    restart(m);
    return m;
}

void fmi2FreeInstance(fmi2Component c) {
    MeInstance *m = c;
    if (!m) return;
    free(m->r);
    free(m->instance_name);
    free(m);
}

/* ---- life cycle ------------------------------------------------------- */

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tol_defined, fmi2Real tol,
                               fmi2Real start, fmi2Boolean stop_defined, fmi2Real stop) {
    (void)tol_defined;
    (void)tol;
    (void)stop_defined;
    (void)stop;
    MeInstance *m = c;
    if (!allowed(m, "fmi2SetupExperiment", BIT(INSTANTIATED))) return fmi2Error;
    m->time = start;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    MeInstance *m = c;
    if (!allowed(m, "fmi2EnterInitializationMode", BIT(INSTANTIATED))) return fmi2Error;
    m->phase = INITIALIZATION;
    m->stale = 1;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    MeInstance *m = c;
    if (!allowed(m, "fmi2ExitInitializationMode", BIT(INITIALIZATION))) return fmi2Error;
    m->stale = 1; /* the initial states are final now: compute them one last time */
    if (!refresh(m)) return fail(m);
    m->phase = EVENT;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    MeInstance *m = c;
    if (!allowed(m, "fmi2Terminate", BIT(EVENT) | BIT(CONTINUOUS))) return fmi2Error;
    if (!refresh(m)) return fail(m);
    m->phase = TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    MeInstance *m = c;
    if (!allowed(m, "fmi2Reset", ANY_PHASE)) return fmi2Error;
    restart(m);
    return fmi2OK;
}

/* ---- event mode and continuous-time mode ------------------------------- */

fmi2Status fmi2EnterEventMode(fmi2Component c) {
    MeInstance *m = c;
    if (!allowed(m, "fmi2EnterEventMode", BIT(EVENT) | BIT(CONTINUOUS))) return fmi2Error;
    m->phase = EVENT;
    return fmi2OK;
}

fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *info) {
    MeInstance *m = c;
    if (!allowed(m, "fmi2NewDiscreteStates", BIT(EVENT))) return fmi2Error;
    MeEvent event = {0};
    if (!refresh(m)) return fail(m);
    if (m->info->event_update) {
        if (m->info->event_update(m, &event) != 0) return fail(m);
        m->stale = 1;
    }
    info->newDiscreteStatesNeeded = fmi2False;
    info->terminateSimulation = event.terminate ? fmi2True : fmi2False;
    info->nominalsOfContinuousStatesChanged = fmi2False;
    info->valuesOfContinuousStatesChanged = event.states_changed ? fmi2True : fmi2False;
    info->nextEventTimeDefined = event.next_time_defined ? fmi2True : fmi2False;
    info->nextEventTime = event.next_time_defined ? event.next_time : 0.0;
    return fmi2OK;
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) {
    MeInstance *m = c;
    if (!allowed(m, "fmi2EnterContinuousTimeMode", BIT(EVENT))) return fmi2Error;
    m->phase = CONTINUOUS;
    return fmi2OK;
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean no_set_prior,
                                       fmi2Boolean *enter_event_mode, fmi2Boolean *terminate) {
    (void)no_set_prior;
    MeInstance *m = c;
    if (!allowed(m, "fmi2CompletedIntegratorStep", BIT(CONTINUOUS))) return fmi2Error;
    *enter_event_mode = fmi2False; /* our models have no step events */
    *terminate = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time) {
    MeInstance *m = c;
    if (!allowed(m, "fmi2SetTime", BIT(EVENT) | BIT(CONTINUOUS))) return fmi2Error;
    m->time = time;
    m->stale = 1;
    return fmi2OK;
}

fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
    MeInstance *m = c;
    if (!allowed(m, "fmi2SetContinuousStates", BIT(CONTINUOUS))) return fmi2Error;
    if (!check_length(m, "fmi2SetContinuousStates", nx, m->info->n_states)) return fail(m);
    for (size_t i = 0; i < nx; i++) m->r[m->info->states[i]] = x[i];
    m->stale = 1;
    return fmi2OK;
}

fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    MeInstance *m = c;
    if (!allowed(m, "fmi2GetContinuousStates", READABLE)) return fmi2Error;
    if (!check_length(m, "fmi2GetContinuousStates", nx, m->info->n_states)) return fail(m);
    if (!refresh(m)) return fail(m);
    for (size_t i = 0; i < nx; i++) x[i] = m->r[m->info->states[i]];
    return fmi2OK;
}

fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real dx[], size_t nx) {
    MeInstance *m = c;
    if (!allowed(m, "fmi2GetDerivatives", READABLE)) return fmi2Error;
    if (!check_length(m, "fmi2GetDerivatives", nx, m->info->n_states)) return fail(m);
    if (!refresh(m)) return fail(m);
    for (size_t i = 0; i < nx; i++) dx[i] = m->r[m->info->derivatives[i]];
    return fmi2OK;
}

fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real z[], size_t nz) {
    MeInstance *m = c;
    if (!allowed(m, "fmi2GetEventIndicators", READABLE)) return fmi2Error;
    if (!check_length(m, "fmi2GetEventIndicators", nz, m->info->n_event_indicators)) return fail(m);
    if (nz == 0) return fmi2OK;
    if (!refresh(m) || m->info->event_indicators(m, z) != 0) return fail(m);
    return fmi2OK;
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real nominals[], size_t nx) {
    MeInstance *m = c;
    if (!allowed(m, "fmi2GetNominalsOfContinuousStates", BIT(INSTANTIATED) | READABLE))
        return fmi2Error;
    if (!check_length(m, "fmi2GetNominalsOfContinuousStates", nx, m->info->n_states))
        return fail(m);
    for (size_t i = 0; i < nx; i++) nominals[i] = m->info->nominals ? m->info->nominals[i] : 1.0;
    return fmi2OK;
}

/* ---- variable access -------------------------------------------------- */

static int known(MeInstance *m, const char *function, const fmi2ValueReference vr[], size_t n) {
    for (size_t i = 0; i < n; i++)
        if (vr[i] >= m->info->n_reals) {
            me_log(m, fmi2Error, "logStatusError", "%s: unknown value reference %u", function, vr[i]);
            return 0;
        }
    return 1;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    MeInstance *m = c;
    if (!allowed(m, "fmi2GetReal", ANY_PHASE)) return fmi2Error;
    if (!known(m, "fmi2GetReal", vr, n) || !refresh(m)) return fail(m);
    for (size_t i = 0; i < n; i++) v[i] = m->r[vr[i]];
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                       const fmi2Real v[]) {
    MeInstance *m = c;
    if (!allowed(m, "fmi2SetReal", SETTABLE)) return fmi2Error;
    if (!known(m, "fmi2SetReal", vr, n)) return fail(m);
    for (size_t i = 0; i < n; i++) m->r[vr[i]] = v[i];
    m->stale = 1;
    return fmi2OK;
}

/* Our ME FMUs have only Real variables: any other reference is unknown. */
static fmi2Status no_such_variable(fmi2Component c, const char *function, size_t n) {
    MeInstance *m = c;
    if (!m) return fmi2Error;
    if (n == 0) return fmi2OK;
    me_log(m, fmi2Error, "logStatusError", "%s: this FMU has no such variables", function);
    return fail(m);
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]) {
    (void)vr;
    (void)v;
    return no_such_variable(c, "fmi2GetInteger", n);
}
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          const fmi2Integer v[]) {
    (void)vr;
    (void)v;
    return no_such_variable(c, "fmi2SetInteger", n);
}
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]) {
    (void)vr;
    (void)v;
    return no_such_variable(c, "fmi2GetBoolean", n);
}
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          const fmi2Boolean v[]) {
    (void)vr;
    (void)v;
    return no_such_variable(c, "fmi2SetBoolean", n);
}
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[]) {
    (void)vr;
    (void)v;
    return no_such_variable(c, "fmi2GetString", n);
}
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                         const fmi2String v[]) {
    (void)vr;
    (void)v;
    return no_such_variable(c, "fmi2SetString", n);
}

/* ---- optional capabilities the description declares absent ------------- */

static fmi2Status unsupported(fmi2Component c, const char *function) {
    MeInstance *m = c;
    if (m) me_log(m, fmi2Error, "logStatusError", "%s is not supported by this FMU", function);
    return fmi2Error;
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *st) {
    (void)st;
    return unsupported(c, "fmi2GetFMUstate");
}
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate st) {
    (void)st;
    return unsupported(c, "fmi2SetFMUstate");
}
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *st) {
    (void)st;
    return unsupported(c, "fmi2FreeFMUstate");
}
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate st, size_t *size) {
    (void)st;
    (void)size;
    return unsupported(c, "fmi2SerializedFMUstateSize");
}
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate st, fmi2Byte b[], size_t size) {
    (void)st;
    (void)b;
    (void)size;
    return unsupported(c, "fmi2SerializeFMUstate");
}
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t size,
                                   fmi2FMUstate *st) {
    (void)b;
    (void)size;
    (void)st;
    return unsupported(c, "fmi2DeSerializeFMUstate");
}
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference z[], size_t nz,
                                        const fmi2Real du[], fmi2Real dz[]) {
    (void)u;
    (void)nu;
    (void)z;
    (void)nz;
    (void)du;
    (void)dz;
    return unsupported(c, "fmi2GetDirectionalDerivative");
}
