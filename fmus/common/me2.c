/*
 * me2.c: the FMI 2.0 model-exchange entry points, written once for all our ME
 * FMUs; fmi2_common.c has the ones co-simulation shares.
 *
 * The model (model.c) supplies an MeInfo; this file owns its part of the life
 * cycle, instantiation, event mode and continuous-time mode; fmi2_common.c
 * the rest (instantiated -> initialization mode -> event mode <->
 * continuous-time mode -> terminated, and fmi2Reset back to the start values
 * so an importer can reuse one instance for many runs).  The importer
 * integrates: it sets time and states, reads derivatives
 * and event indicators.
 *
 * Inputs may be set in continuous-time mode as well as in event mode (the
 * standard allows it for continuous inputs; ours are all Real).
 */
#include <math.h>
#include <stdio.h>

#include "fmi_common.h"
#include "me2.h"

/* The model's states, as fmi_common.h's model-exchange calls take them. */
static FmiStates states(void) {
    return (FmiStates){ME_MODEL.n_states, ME_MODEL.states, ME_MODEL.derivatives, ME_MODEL.nominals,
                       ME_MODEL.real_names};
}

/* Brings every computed value up to date with time, states and inputs. */
int fmi2_refresh(MeInstance *m) {
    if (!m->stale || !(RUNNING & BIT(m->phase))) return 1;
    if (m->phase == INITIALIZATION && ME_MODEL.initial && ME_MODEL.initial(m) != 0) return 0;
    if (ME_MODEL.equations && ME_MODEL.equations(m) != 0) return 0;
    if (!fmi_derivatives_finite(&m->core, m->r, states())) return 0;
    m->stale = 0;
    return 1;
}

Fmi2Instance *fmi2_create(fmi2String name, fmi2Type type, fmi2String guid, const fmi2CallbackFunctions *cb,
                          fmi2Boolean logging_on) {
    const Fmi2Model model = {.n_reals = ME_MODEL.n_reals, .real_defaults = ME_MODEL.real_defaults};
    return fmi2_instantiate(name, type, guid, cb, logging_on, ME_MODEL.guid, &model);
}

/* ---- event mode and continuous-time mode ------------------------------- */

fmi2Status fmi2EnterEventMode(fmi2Component c) {
    unsigned from = BIT(EVENT_MODE) | BIT(CONTINUOUS_TIME_MODE);
    return (fmi2Status)fmi_enter(fmi2_core(c), "fmi2EnterEventMode", from, EVENT_MODE);
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
    return (fmi2Status)fmi_enter(fmi2_core(c), "fmi2EnterContinuousTimeMode", BIT(EVENT_MODE),
                                 CONTINUOUS_TIME_MODE);
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
    return (fmi2Status)fmi_set_time(fmi2_core(c), "fmi2SetTime", time);
}

fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
    MeInstance *m = c;
    return (fmi2Status)fmi_set_states(fmi2_core(c), "fmi2SetContinuousStates", m ? m->r : NULL, states(), x,
                                      nx);
}

fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    MeInstance *m = c;
    return (fmi2Status)fmi_read_states(fmi2_core(c), "fmi2GetContinuousStates", m ? m->r : NULL, states(),
                                       ME_MODEL.states, x, nx);
}

fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real dx[], size_t nx) {
    MeInstance *m = c;
    return (fmi2Status)fmi_read_states(fmi2_core(c), "fmi2GetDerivatives", m ? m->r : NULL, states(),
                                       ME_MODEL.derivatives, dx, nx);
}

fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real z[], size_t nz) {
    MeInstance *m = c;
    if (!fmi2_allowed(m, "fmi2GetEventIndicators", READABLE)) return fmi2Error;
    if (!fmi_check_length(&m->core, "fmi2GetEventIndicators", nz, ME_MODEL.n_event_indicators))
        return fmi2_fail(m);
    if (nz == 0) return fmi2OK;
    if (!fmi2_refresh(m) || ME_MODEL.event_indicators(m, z) != 0) return fmi2_fail(m);
    return fmi2OK;
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real nominals[], size_t nx) {
    return (fmi2Status)fmi_nominals(fmi2_core(c), "fmi2GetNominalsOfContinuousStates", states(), nominals,
                                    nx);
}
