/*
 * fmi2_common.c: the fmi2* functions both FMI 2.0 layers implement alike,
 * and the helpers slave.c and me2.c build on (fmi2_common.h).
 */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2_common.h"
#include "fmi_common.h"

/* FMI 2.0's logger takes its message as a printf format: every '%' is doubled. */
static void emit(FmiCore *c, int status, const char *category, const char *message) {
    Fmi2Instance *s = (Fmi2Instance *)c;
    if (!s->cb || !s->cb->logger) return;
    char escaped[2048];
    size_t j = 0;
    for (size_t i = 0; message[i] && j + 2 < sizeof escaped; i++) {
        if (message[i] == '%') escaped[j++] = '%';
        escaped[j++] = message[i];
    }
    escaped[j] = '\0';
    s->cb->logger(s->cb->componentEnvironment, s->instance_name, (fmi2Status)status, category, escaped);
}

static int refresh(FmiCore *c) { return fmi2_refresh((Fmi2Instance *)c); }

static int enter_initialization(FmiCore *c) {
    Fmi2Instance *s = (Fmi2Instance *)c;
    return s->model.enter_initialization ? s->model.enter_initialization(s) : 0;
}

static int exit_initialization(FmiCore *c) {
    Fmi2Instance *s = (Fmi2Instance *)c;
    return s->model.exit_initialization ? s->model.exit_initialization(s) : 0;
}

static const FmiCalls CALLS = {emit, refresh, enter_initialization, exit_initialization};

_Static_assert((int)fmi2OK == FMI_OK && (int)fmi2Warning == FMI_WARNING && (int)fmi2Discard == FMI_DISCARD &&
                   (int)fmi2Error == FMI_ERROR && (int)fmi2Fatal == FMI_FATAL,
               "fmi_common.h numbers the statuses as FMI 2.0 does");

void fmi2_log(Fmi2Instance *s, fmi2Status status, const char *category, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    fmi_vlog(&s->core, status, category, fmt, ap);
    va_end(ap);
}

/* Back to the start values, as after instantiation. */
static void restart(Fmi2Instance *s) {
    const Fmi2Model *m = &s->model;
    memcpy(s->r, m->real_defaults, m->n_reals * sizeof(double));
    for (size_t i = 0; i < m->n_integers; i++) s->i[i] = m->integer_defaults ? m->integer_defaults[i] : 0;
    for (size_t i = 0; i < m->n_booleans; i++)
        s->b[i] = m->boolean_defaults && m->boolean_defaults[i] ? fmi2True : fmi2False;
    for (size_t i = 0; i < m->n_strings; i++) {
        free(s->str[i]);
        s->str[i] = fmi_copy_text(m->string_defaults[i]);
    }
    if (m->release) m->release(s);
    memset(s->state, 0, m->state_size ? m->state_size : 1);
    s->time = 0.0;
    s->phase = INSTANTIATED;
    s->stale = 1;
}

/* ---- inquiry, logging, creation ---------------------------------------- */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[]) {
    (void)n;
    (void)cats;
    return (fmi2Status)fmi_set_debug_logging(fmi2_core(c), on);
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                              const fmi2CallbackFunctions *cb, fmi2Boolean visible,
                              fmi2Boolean logging_on) {
    (void)resources;
    (void)visible;
    return fmi2_create(name, type, guid, cb, logging_on);
}

Fmi2Instance *fmi2_instantiate(fmi2String name, fmi2Type type, fmi2String guid,
                               const fmi2CallbackFunctions *cb, fmi2Boolean logging_on,
                               const char *model_guid, const Fmi2Model *model) {
    const char *refusal = NULL;
    if (type != (model->co_simulation ? fmi2CoSimulation : fmi2ModelExchange))
        refusal = model->co_simulation ? "only co-simulation is supported" : "only model exchange is supported";
    else if (!guid || strcmp(guid, model_guid) != 0)
        refusal = "GUID does not match this FMU's modelDescription.xml";
    if (refusal) {
        if (cb && cb->logger) cb->logger(cb->componentEnvironment, name, fmi2Error, "logStatusError", refusal);
        return NULL;
    }
    Fmi2Instance *s = calloc(1, sizeof *s);
    if (!s) return NULL;
    s->model = *model;
    s->calls = &CALLS;
    s->co_simulation = model->co_simulation;
    s->cb = cb;
    s->logging_on = logging_on;
    s->instance_name = fmi_copy_text(name);
    s->r = fmi_zeroed(model->n_reals, sizeof *s->r);
    s->str = fmi_zeroed(model->n_strings, sizeof *s->str);
    s->i = fmi_zeroed(model->n_integers, sizeof *s->i);
    s->b = fmi_zeroed(model->n_booleans, sizeof *s->b);
    s->state = fmi_zeroed(1, model->state_size ? model->state_size : 1);
    if (!s->instance_name || !s->r || !s->str || !s->i || !s->b || !s->state) {
        fmi2FreeInstance(s);
        return NULL;
    }
    restart(s);
    return s;
}

void fmi2FreeInstance(fmi2Component c) {
    Fmi2Instance *s = c;
    if (!s) return;
    if (s->model.release && s->state) s->model.release(s);
    if (s->str)
        for (size_t i = 0; i < s->model.n_strings; i++) free(s->str[i]);
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
    Fmi2Instance *s = c;
    if (!fmi2_allowed(s, "fmi2SetupExperiment", BIT(INSTANTIATED))) return fmi2Error;
    s->time = start;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    FmiCore *core = fmi2_core(c);
    return (fmi2Status)fmi_enter_initialization(core, "fmi2EnterInitializationMode", core ? core->time : 0.0);
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    return (fmi2Status)fmi_exit_initialization(fmi2_core(c), "fmi2ExitInitializationMode");
}

fmi2Status fmi2Terminate(fmi2Component c) { return (fmi2Status)fmi_terminate(fmi2_core(c), "fmi2Terminate"); }

fmi2Status fmi2Reset(fmi2Component c) {
    Fmi2Instance *s = c;
    if (!fmi2_allowed(s, "fmi2Reset", ANY_PHASE)) return fmi2Error;
    restart(s);
    return fmi2OK;
}

/* ---- variable access -------------------------------------------------- */

/* Checks a call's value references against the count of their type; a read
 * then brings computed values up to date, a write marks them stale. */
static int accessible(Fmi2Instance *s, const char *function, const fmi2ValueReference vr[], size_t n,
                      size_t limit, int reading) {
    for (size_t k = 0; k < n; k++)
        if (vr[k] >= limit) {
            fmi2_log(s, fmi2Error, "logStatusError", "%s: unknown value reference %u", function, vr[k]);
            return 0;
        }
    if (reading) return fmi2_refresh(s);
    s->stale = 1;
    return 1;
}

/* A String is stored as an owned copy; 0 if out of memory. */
static int store_string(Fmi2Instance *s, fmi2ValueReference vr, fmi2String value) {
    char *copy = fmi_copy_text(value);
    if (!copy) return 0;
    free(s->str[vr]);
    s->str[vr] = copy;
    return 1;
}

/* fmi2Boolean is an int: any non-zero value is stored as fmi2True, so a model
 * can compare against fmi2True and an importer reads back 0 or 1. */
#define AS_BOOLEAN(x) ((x) ? fmi2True : fmi2False)
#define PLAIN_STORE(array, value) (s->array[vr[k]] = (value), 1)

/* Get and Set of one type, which differ in names and in STORE (writes v[k]
 * to reference vr[k], 0 if it cannot): a read is allowed in any phase, a
 * write until terminated. */
#define ACCESSORS(Name, ctype, array, count, STORE)                                                \
    fmi2Status fmi2Get##Name(fmi2Component c, const fmi2ValueReference vr[], size_t n, ctype v[]) { \
        Fmi2Instance *s = c;                                                                       \
        if (!fmi2_allowed(s, "fmi2Get" #Name, ANY_PHASE)) return fmi2Error;                        \
        if (!accessible(s, "fmi2Get" #Name, vr, n, s->model.count, 1)) return fmi2_fail(s);        \
        for (size_t k = 0; k < n; k++) v[k] = s->array[vr[k]];                                     \
        return fmi2OK;                                                                             \
    }                                                                                              \
    fmi2Status fmi2Set##Name(fmi2Component c, const fmi2ValueReference vr[], size_t n,             \
                             const ctype v[]) {                                                    \
        Fmi2Instance *s = c;                                                                       \
        if (!fmi2_allowed(s, "fmi2Set" #Name, SETTABLE)) return fmi2Error;                         \
        if (!accessible(s, "fmi2Set" #Name, vr, n, s->model.count, 0)) return fmi2_fail(s);        \
        for (size_t k = 0; k < n; k++)                                                             \
            if (!(STORE)) return fmi2_fail(s);                                                     \
        return fmi2OK;                                                                             \
    }

ACCESSORS(Real, fmi2Real, r, n_reals, PLAIN_STORE(r, v[k]))
ACCESSORS(Integer, fmi2Integer, i, n_integers, PLAIN_STORE(i, v[k]))
ACCESSORS(Boolean, fmi2Boolean, b, n_booleans, PLAIN_STORE(b, AS_BOOLEAN(v[k])))
ACCESSORS(String, fmi2String, str, n_strings, store_string(s, vr[k], v[k]))

/* ---- optional capabilities neither layer has -------------------------- */

FMI2_UNSUPPORTED(fmi2GetFMUstate, fmi2FMUstate *st)
FMI2_UNSUPPORTED(fmi2SetFMUstate, fmi2FMUstate st)
FMI2_UNSUPPORTED(fmi2FreeFMUstate, fmi2FMUstate *st)
FMI2_UNSUPPORTED(fmi2SerializedFMUstateSize, fmi2FMUstate st, size_t *size)
FMI2_UNSUPPORTED(fmi2SerializeFMUstate, fmi2FMUstate st, fmi2Byte b[], size_t size)
FMI2_UNSUPPORTED(fmi2DeSerializeFMUstate, const fmi2Byte b[], size_t size, fmi2FMUstate *st)
FMI2_UNSUPPORTED(fmi2GetDirectionalDerivative, const fmi2ValueReference u[], size_t nu,
                 const fmi2ValueReference z[], size_t nz, const fmi2Real du[], fmi2Real dz[])
