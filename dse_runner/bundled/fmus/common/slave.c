/*
 * slave.c: FMI 2.0 co-simulation entry points, written once for all our FMUs.
 *
 * The model (model.c) supplies a ModelInfo; this file owns the life cycle:
 * instantiate -> (set parameters) -> initialization mode -> steps -> terminate,
 * with fmi2Reset going back to the start values so an importer can reuse one
 * instance for many runs.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "slave.h"

enum { INSTANTIATED, INITIALIZATION, STEPPING, TERMINATED, FAILED };

static const char *const PHASE_NAMES[] = {
    "instantiated", "initialization mode", "stepping", "terminated", "error"};

void slave_log(Slave *s, fmi2Status status, const char *category, const char *fmt, ...) {
    if (!s->cb || !s->cb->logger) return;
    if (status == fmi2OK && !s->logging_on) return;
    char msg[1024], escaped[2048];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    /* The logger's message is itself a printf format: double every '%'. */
    size_t j = 0;
    for (size_t i = 0; msg[i] && j + 2 < sizeof escaped; i++) {
        if (msg[i] == '%') escaped[j++] = '%';
        escaped[j++] = msg[i];
    }
    escaped[j] = '\0';
    s->cb->logger(s->cb->componentEnvironment, s->instance_name, status, category, escaped);
}

static char *copy_string(const char *text) {
    size_t n = strlen(text ? text : "") + 1;
    char *c = malloc(n);
    if (c) memcpy(c, text ? text : "", n);
    return c;
}

static void load_defaults(Slave *s) {
    const ModelInfo *m = s->info;
    memcpy(s->r, m->real_defaults, m->n_reals * sizeof(double));
    /* A model without defaults for a type starts those variables at 0 / false. */
    for (size_t i = 0; i < m->n_integers; i++)
        s->i[i] = m->integer_defaults ? m->integer_defaults[i] : 0;
    for (size_t i = 0; i < m->n_booleans; i++)
        s->b[i] = m->boolean_defaults && m->boolean_defaults[i] ? fmi2True : fmi2False;
    for (size_t i = 0; i < m->n_strings; i++) {
        free(s->str[i]);
        s->str[i] = copy_string(m->string_defaults[i]);
    }
    if (m->release) m->release(s);
    memset(s->state, 0, m->state_size ? m->state_size : 1);
    s->time = 0.0;
    s->phase = INSTANTIATED;
}

/* Guards a call: the phase must be one of the allowed ones. */
static int allowed(Slave *s, const char *function, unsigned phases) {
    if (!s) return 0;
    if (phases & (1u << s->phase)) return 1;
    slave_log(s, fmi2Error, "logStatusError", "%s is not allowed in phase '%s'", function,
              PHASE_NAMES[s->phase]);
    s->phase = FAILED;
    return 0;
}

#define ANY_PHASE 0x1fu
#define SETTABLE ((1u << INSTANTIATED) | (1u << INITIALIZATION) | (1u << STEPPING))

static fmi2Status fail(Slave *s) {
    s->phase = FAILED;
    return fmi2Error;
}

/* ---- inquiry, logging, creation ---------------------------------------- */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[]) {
    (void)n;
    (void)cats;
    Slave *s = c;
    if (!s) return fmi2Error;
    s->logging_on = on;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                              const fmi2CallbackFunctions *cb, fmi2Boolean visible,
                              fmi2Boolean logging_on) {
    (void)resources;
    (void)visible;
    const ModelInfo *m = &MODEL;
    if (type != fmi2CoSimulation || !guid || strcmp(guid, m->guid) != 0) {
        if (cb && cb->logger)
            cb->logger(cb->componentEnvironment, name, fmi2Error, "logStatusError",
                       type != fmi2CoSimulation ? "only co-simulation is supported"
                                                : "GUID does not match this FMU's modelDescription.xml");
        return NULL;
    }
    Slave *s = calloc(1, sizeof *s);
    if (!s) return NULL;
    s->info = m;
    s->cb = cb;
    s->logging_on = logging_on;
    s->instance_name = copy_string(name);
    s->r = calloc(m->n_reals ? m->n_reals : 1, sizeof(double));
    s->str = calloc(m->n_strings ? m->n_strings : 1, sizeof(char *));
    s->i = calloc(m->n_integers ? m->n_integers : 1, sizeof(fmi2Integer));
    s->b = calloc(m->n_booleans ? m->n_booleans : 1, sizeof(fmi2Boolean));
    s->state = calloc(1, m->state_size ? m->state_size : 1);
    if (!s->instance_name || !s->r || !s->str || !s->i || !s->b || !s->state) {
        fmi2FreeInstance(s);
        return NULL;
    }
    load_defaults(s);
    return s;
}

void fmi2FreeInstance(fmi2Component c) {
    Slave *s = c;
    if (!s) return;
    if (s->info->release && s->state) s->info->release(s);
    if (s->str)
        for (size_t i = 0; i < s->info->n_strings; i++) free(s->str[i]);
    free(s->str);
    free(s->r);
    free(s->i);
    free(s->b);
    free(s->state);
    free(s->instance_name);
    free(s);
}

/* ---- life cycle ------------------------------------------------------- */

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tol_defined, fmi2Real tol,
                               fmi2Real start, fmi2Boolean stop_defined, fmi2Real stop) {
    (void)tol_defined;
    (void)tol;
    (void)stop_defined;
    (void)stop;
    Slave *s = c;
    if (!allowed(s, "fmi2SetupExperiment", 1u << INSTANTIATED)) return fmi2Error;
    s->time = start;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    Slave *s = c;
    if (!allowed(s, "fmi2EnterInitializationMode", 1u << INSTANTIATED)) return fmi2Error;
    s->phase = INITIALIZATION;
    if (s->info->enter_initialization && s->info->enter_initialization(s) != 0) return fail(s);
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Slave *s = c;
    if (!allowed(s, "fmi2ExitInitializationMode", 1u << INITIALIZATION)) return fmi2Error;
    if (s->info->exit_initialization && s->info->exit_initialization(s) != 0) return fail(s);
    s->phase = STEPPING;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    Slave *s = c;
    if (!allowed(s, "fmi2Terminate", 1u << STEPPING)) return fmi2Error;
    s->phase = TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    Slave *s = c;
    if (!allowed(s, "fmi2Reset", ANY_PHASE)) return fmi2Error;
    load_defaults(s);
    return fmi2OK;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean no_set_prior) {
    (void)no_set_prior;
    Slave *s = c;
    if (!allowed(s, "fmi2DoStep", 1u << STEPPING)) return fmi2Error;
    if (!(h > 0.0)) {
        slave_log(s, fmi2Error, "logStatusError", "communication step size must be > 0, got %g", h);
        return fail(s);
    }
    if (fabs(t - s->time) > 1e-9 * (1.0 + fabs(t))) {
        slave_log(s, fmi2Error, "logStatusError",
                  "fmi2DoStep at t=%.9g but the FMU is at t=%.9g (no rollback)", t, s->time);
        return fail(s);
    }
    if (s->info->do_step(s, t, h) != 0) return fail(s);
    s->time = t + h;
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    Slave *s = c;
    if (s) slave_log(s, fmi2Error, "logStatusError", "fmi2CancelStep: steps are synchronous");
    return fmi2Error;
}

/* ---- variable access -------------------------------------------------- */

static int check_vrs(Slave *s, const char *function, const fmi2ValueReference vr[], size_t n,
                     size_t limit) {
    for (size_t i = 0; i < n; i++)
        if (vr[i] >= limit) {
            slave_log(s, fmi2Error, "logStatusError", "%s: unknown value reference %u", function,
                      vr[i]);
            return 0;
        }
    return 1;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    Slave *s = c;
    if (!allowed(s, "fmi2GetReal", ANY_PHASE)) return fmi2Error;
    if (!check_vrs(s, "fmi2GetReal", vr, n, s->info->n_reals)) return fail(s);
    for (size_t i = 0; i < n; i++) v[i] = s->r[vr[i]];
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                       const fmi2Real v[]) {
    Slave *s = c;
    if (!allowed(s, "fmi2SetReal", SETTABLE)) return fmi2Error;
    if (!check_vrs(s, "fmi2SetReal", vr, n, s->info->n_reals)) return fail(s);
    for (size_t i = 0; i < n; i++) s->r[vr[i]] = v[i];
    return fmi2OK;
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                         fmi2String v[]) {
    Slave *s = c;
    if (!allowed(s, "fmi2GetString", ANY_PHASE)) return fmi2Error;
    if (!check_vrs(s, "fmi2GetString", vr, n, s->info->n_strings)) return fail(s);
    for (size_t i = 0; i < n; i++) v[i] = s->str[vr[i]];
    return fmi2OK;
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                         const fmi2String v[]) {
    Slave *s = c;
    if (!allowed(s, "fmi2SetString", SETTABLE)) return fmi2Error;
    if (!check_vrs(s, "fmi2SetString", vr, n, s->info->n_strings)) return fail(s);
    for (size_t i = 0; i < n; i++) {
        char *copy = copy_string(v[i]);
        if (!copy) return fail(s);
        free(s->str[vr[i]]);
        s->str[vr[i]] = copy;
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]) {
    Slave *s = c;
    if (!allowed(s, "fmi2GetInteger", ANY_PHASE)) return fmi2Error;
    if (!check_vrs(s, "fmi2GetInteger", vr, n, s->info->n_integers)) return fail(s);
    for (size_t i = 0; i < n; i++) v[i] = s->i[vr[i]];
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          const fmi2Integer v[]) {
    Slave *s = c;
    if (!allowed(s, "fmi2SetInteger", SETTABLE)) return fmi2Error;
    if (!check_vrs(s, "fmi2SetInteger", vr, n, s->info->n_integers)) return fail(s);
    for (size_t i = 0; i < n; i++) s->i[vr[i]] = v[i];
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]) {
    Slave *s = c;
    if (!allowed(s, "fmi2GetBoolean", ANY_PHASE)) return fmi2Error;
    if (!check_vrs(s, "fmi2GetBoolean", vr, n, s->info->n_booleans)) return fail(s);
    for (size_t i = 0; i < n; i++) v[i] = s->b[vr[i]];
    return fmi2OK;
}

/* fmi2Boolean is an int: any non-zero value is stored as fmi2True, so a model
 * can compare against fmi2True and an importer reads back 0 or 1. */
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          const fmi2Boolean v[]) {
    Slave *s = c;
    if (!allowed(s, "fmi2SetBoolean", SETTABLE)) return fmi2Error;
    if (!check_vrs(s, "fmi2SetBoolean", vr, n, s->info->n_booleans)) return fail(s);
    for (size_t i = 0; i < n; i++) s->b[vr[i]] = v[i] ? fmi2True : fmi2False;
    return fmi2OK;
}

/* ---- optional capabilities this FMU declares it does not have ---------- */

static fmi2Status unsupported(fmi2Component c, const char *function) {
    Slave *s = c;
    if (s) slave_log(s, fmi2Error, "logStatusError", "%s is not supported by this FMU", function);
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
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer order[], const fmi2Real v[]) {
    (void)vr;
    (void)n;
    (void)order;
    (void)v;
    return unsupported(c, "fmi2SetRealInputDerivatives");
}
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer order[], fmi2Real v[]) {
    (void)vr;
    (void)n;
    (void)order;
    (void)v;
    return unsupported(c, "fmi2GetRealOutputDerivatives");
}

/* ---- status ----------------------------------------------------------- */

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind k, fmi2Status *v) {
    (void)k;
    if (!c) return fmi2Error;
    *v = fmi2OK;
    return fmi2OK;
}
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind k, fmi2Real *v) {
    Slave *s = c;
    if (!s) return fmi2Error;
    if (k != fmi2LastSuccessfulTime) return unsupported(c, "fmi2GetRealStatus for this kind");
    *v = s->time;
    return fmi2OK;
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind k, fmi2Integer *v) {
    (void)k;
    (void)v;
    return unsupported(c, "fmi2GetIntegerStatus");
}
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind k, fmi2Boolean *v) {
    (void)k;
    (void)v;
    return unsupported(c, "fmi2GetBooleanStatus");
}
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind k, fmi2String *v) {
    (void)k;
    (void)v;
    return unsupported(c, "fmi2GetStringStatus");
}
