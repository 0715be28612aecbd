/*
 * me2.c: the FMI 2.0 model-exchange entry points, written once for all our ME
 * FMUs; fmi2_common.c has the ones co-simulation shares.
 *
 * The model (model.c) supplies an MeInfo; this file owns its part of the life
 * cycle, instantiation, event mode and continuous-time mode; fmi2_common.c
 * the rest (instantiated -> initialization mode -> event mode <->
 * continuous-time mode -> terminated, and fmi2Reset back to the start values
 * so an importer can reuse one instance for many runs).  The importer integrates: it sets time and states, reads derivatives
 * and event indicators.
 *
 * Inputs may be set in continuous-time mode as well as in event mode (the
 * standard allows it for continuous inputs; ours are all Real).
 */
#include <math.h>
#include <stdio.h>

#include "fmi_common.h"
#include "me2.h"

static void name_of(fmi2ValueReference vr, char *out, size_t size) {
    if (ME_MODEL.real_names)
        snprintf(out, size, "%s", ME_MODEL.real_names[vr]);
    else
        snprintf(out, size, "value reference %u", vr);
}

/* A non-finite derivative would only make the solver fail later and obscurely. */
static int derivatives_finite(MeInstance *m) {
    for (size_t i = 0; i < ME_MODEL.n_states; i++) {
        fmi2ValueReference vr = ME_MODEL.derivatives[i];
        if (isfinite(m->r[vr])) continue;
        char name[128];
        name_of(vr, name, sizeof name);
        me_log(m, fmi2Error, "logStatusError", "%s is %g at t=%.9g", name, m->r[vr], m->time);
        return 0;
    }
    return 1;
}

/* Brings every computed value up to date with time, states and inputs. */
int fmi2_refresh(MeInstance *m) {
    if (!m->stale || !(RUNNING & BIT(m->phase))) return 1;
    if (m->phase == INITIALIZATION && ME_MODEL.initial && ME_MODEL.initial(m) != 0) return 0;
    if (ME_MODEL.equations && ME_MODEL.equations(m) != 0) return 0;
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

Fmi2Instance *fmi2_create(fmi2String name, fmi2Type type, fmi2String guid, const fmi2CallbackFunctions *cb,
                          fmi2Boolean logging_on) {
    const Fmi2Model model = {.n_reals = ME_MODEL.n_reals, .real_defaults = ME_MODEL.real_defaults};
    return fmi2_instantiate(name, type, guid, cb, logging_on, ME_MODEL.guid, &model);
}

/* ---- event mode and continuous-time mode ------------------------------- */

fmi2Status fmi2EnterEventMode(fmi2Component c) {
    return fmi2_enter(c, "fmi2EnterEventMode", BIT(EVENT_MODE) | BIT(CONTINUOUS_TIME_MODE), EVENT_MODE);
}

fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *info) {
    MeInstance *m = c;
    if (!fmi2_allowed(m, "fmi2NewDiscreteStates", BIT(EVENT_MODE))) return fmi2Error;
    MeEvent event = {0};
    if (!fmi2_refresh(m)) return fmi2_fail(m);
    if (ME_MODEL.event_update) {
        if (ME_MODEL.event_update(m, &event) != 0) return fmi2_fail(m);
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
    return fmi2_enter(c, "fmi2EnterContinuousTimeMode", BIT(EVENT_MODE), CONTINUOUS_TIME_MODE);
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean no_set_prior,
                                       fmi2Boolean *enter_event_mode, fmi2Boolean *terminate) {
    (void)no_set_prior;
    MeInstance *m = c;
    if (!fmi2_allowed(m, "fmi2CompletedIntegratorStep", BIT(CONTINUOUS_TIME_MODE))) return fmi2Error;
    *enter_event_mode = fmi2False; /* our models have no step events */
    *terminate = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time) {
    MeInstance *m = c;
    if (!fmi2_allowed(m, "fmi2SetTime", BIT(EVENT_MODE) | BIT(CONTINUOUS_TIME_MODE))) return fmi2Error;
    m->time = time;
    m->stale = 1;
    return fmi2OK;
}

fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
    MeInstance *m = c;
    if (!fmi2_allowed(m, "fmi2SetContinuousStates", BIT(CONTINUOUS_TIME_MODE))) return fmi2Error;
    if (!check_length(m, "fmi2SetContinuousStates", nx, ME_MODEL.n_states)) return fmi2_fail(m);
    for (size_t i = 0; i < nx; i++) m->r[ME_MODEL.states[i]] = x[i];
    m->stale = 1;
    return fmi2OK;
}

/* Reads the model's variables at refs (its states or their derivatives) into x, up to date. */
static fmi2Status read_at(MeInstance *m, const char *function, fmi2Real x[], size_t nx,
                          const fmi2ValueReference refs[]) {
    if (!fmi2_allowed(m, function, READABLE)) return fmi2Error;
    if (!check_length(m, function, nx, ME_MODEL.n_states)) return fmi2_fail(m);
    if (!fmi2_refresh(m)) return fmi2_fail(m);
    for (size_t i = 0; i < nx; i++) x[i] = m->r[refs[i]];
    return fmi2OK;
}

fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    return read_at(c, "fmi2GetContinuousStates", x, nx, ME_MODEL.states);
}

fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real dx[], size_t nx) {
    return read_at(c, "fmi2GetDerivatives", dx, nx, ME_MODEL.derivatives);
}

fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real z[], size_t nz) {
    MeInstance *m = c;
    if (!fmi2_allowed(m, "fmi2GetEventIndicators", READABLE)) return fmi2Error;
    if (!check_length(m, "fmi2GetEventIndicators", nz, ME_MODEL.n_event_indicators)) return fmi2_fail(m);
    if (nz == 0) return fmi2OK;
    if (!fmi2_refresh(m) || ME_MODEL.event_indicators(m, z) != 0) return fmi2_fail(m);
    return fmi2OK;
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real nominals[], size_t nx) {
    MeInstance *m = c;
    if (!fmi2_allowed(m, "fmi2GetNominalsOfContinuousStates", BIT(INSTANTIATED) | READABLE))
        return fmi2Error;
    if (!check_length(m, "fmi2GetNominalsOfContinuousStates", nx, ME_MODEL.n_states)) return fmi2_fail(m);
    for (size_t i = 0; i < nx; i++) nominals[i] = ME_MODEL.nominals ? ME_MODEL.nominals[i] : 1.0;
    return fmi2OK;
}
