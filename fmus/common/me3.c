/*
 * me3.c: the FMI 3.0 model-exchange entry points, written once for all our
 * FMI 3 ME FMUs, the FMI 3 twin of me2.c; fmi3_common.c has the ones
 * co-simulation shares.
 *
 * The model (model.c) supplies an Me3Info; this file owns its part of the
 * life cycle, instantiation, event mode and continuous-time mode;
 * fmi3_common.c the rest (instantiated -> initialization mode -> event mode
 * <-> continuous-time mode -> terminated, and fmi3Reset back to the start
 * values so an importer can reuse one instance for many runs).  The
 * importer integrates: it sets time and states and reads derivatives.
 * There are no event indicators and fmi3UpdateDiscreteStates never reports
 * an event.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "fmi_common.h"
#include "me3.h"

/* The model's states, as fmi_common.h's model-exchange calls take them. */
static FmiStates states(void) {
    return (FmiStates){ME3_MODEL.n_states, ME3_MODEL.states, ME3_MODEL.derivatives, ME3_MODEL.nominals,
                       ME3_MODEL.real_names};
}

/* Brings every computed value up to date with time, states and inputs. */
int fmi3_refresh(Me3Instance *m) {
    if (!m->stale || !(RUNNING & BIT(m->phase))) return 1;
    m->r[ME3_MODEL.time_vr] = m->time;
    if (m->phase == INITIALIZATION && ME3_MODEL.initial && ME3_MODEL.initial(m) != 0) return 0;
    if (ME3_MODEL.equations && ME3_MODEL.equations(m) != 0) return 0;
    if (!fmi_derivatives_finite(&m->core, m->r, states())) return 0;
    m->stale = 0;
    return 1;
}

/* The table fmi3_common.c works from: value reference = index, all Float64.
 * The time variable keeps its slot in m->r (refresh sets it to the time for
 * the equations), so the table is checked with it as Float64 and then marked
 * as the independent variable, which reads the time and cannot be set. */
Fmi3Instance *fmi3_create(int co_simulation, fmi3String name, fmi3String token, fmi3Boolean event_mode_used,
                          fmi3Boolean logging_on, fmi3InstanceEnvironment environment,
                          fmi3LogMessageCallback logger) {
    (void)event_mode_used;
    if (co_simulation)
        return fmi3_instantiate(name, token, ME3_MODEL.instantiation_token,
                                "fmi3InstantiateCoSimulation is not supported: this FMU is model exchange only",
                                logging_on, environment, logger, NULL);
    Variable3 *table = fmi_zeroed(ME3_MODEL.n_reals, sizeof *table);
    if (!table) return NULL;
    for (size_t k = 0; k < ME3_MODEL.n_reals; k++)
        table[k] = (Variable3){.vr = (fmi3ValueReference)k, .type = V3_FLOAT64, .index = k,
                               .start = ME3_MODEL.real_defaults[k]};
    const Fmi3Model model = {.variables = table, .n_variables = ME3_MODEL.n_reals};
    Me3Instance *m = fmi3_instantiate(name, token, ME3_MODEL.instantiation_token, NULL, logging_on,
                                      environment, logger, &model);
    if (!m) {
        free(table);
        return NULL;
    }
    m->own_variables = table;
    if (ME3_MODEL.time_vr < ME3_MODEL.n_reals) table[ME3_MODEL.time_vr].type = V3_TIME;
    return m;
}

/* ---- event mode and continuous-time mode ------------------------------- */

fmi3Status fmi3EnterEventMode(fmi3Instance c) {
    unsigned from = BIT(EVENT_MODE) | BIT(CONTINUOUS_TIME_MODE);
    return (fmi3Status)fmi_enter(fmi3_core(c), "fmi3EnterEventMode", from, EVENT_MODE);
}

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance c) {
    return (fmi3Status)fmi_enter(fmi3_core(c), "fmi3EnterContinuousTimeMode", BIT(EVENT_MODE),
                                 CONTINUOUS_TIME_MODE);
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance c, fmi3Boolean no_set_prior,
                                       fmi3Boolean *enter_event_mode, fmi3Boolean *terminate) {
    (void)no_set_prior;
    Me3Instance *m = c;
    if (!fmi3_allowed(m, "fmi3CompletedIntegratorStep", BIT(CONTINUOUS_TIME_MODE))) return fmi3Error;
    *enter_event_mode = fmi3False; /* our models have no step events */
    *terminate = fmi3False;
    return fmi3OK;
}

fmi3Status fmi3SetTime(fmi3Instance c, fmi3Float64 time) {
    return (fmi3Status)fmi_set_time(fmi3_core(c), "fmi3SetTime", time);
}

fmi3Status fmi3SetContinuousStates(fmi3Instance c, const fmi3Float64 x[], size_t nx) {
    Me3Instance *m = c;
    return (fmi3Status)fmi_set_states(fmi3_core(c), "fmi3SetContinuousStates", m ? m->r : NULL, states(), x,
                                      nx);
}

fmi3Status fmi3GetContinuousStates(fmi3Instance c, fmi3Float64 x[], size_t nx) {
    Me3Instance *m = c;
    return (fmi3Status)fmi_read_states(fmi3_core(c), "fmi3GetContinuousStates", m ? m->r : NULL, states(),
                                       ME3_MODEL.states, x, nx);
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance c, fmi3Float64 dx[], size_t nx) {
    Me3Instance *m = c;
    return (fmi3Status)fmi_read_states(fmi3_core(c), "fmi3GetContinuousStateDerivatives", m ? m->r : NULL,
                                       states(), ME3_MODEL.derivatives, dx, nx);
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance c, fmi3Float64 nominals[], size_t nx) {
    return (fmi3Status)fmi_nominals(fmi3_core(c), "fmi3GetNominalsOfContinuousStates", states(), nominals,
                                    nx);
}

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance c, fmi3Boolean *update, fmi3Boolean *terminate,
                                    fmi3Boolean *nominals, fmi3Boolean *values,
                                    fmi3Boolean *next_defined, fmi3Float64 *next) {
    Me3Instance *m = c;
    if (!fmi3_allowed(m, "fmi3UpdateDiscreteStates", BIT(EVENT_MODE))) return fmi3Error;
    if (!fmi3_refresh(m)) return fmi3_fail(m);
    if (update) *update = fmi3False;
    if (terminate) *terminate = fmi3False;
    if (nominals) *nominals = fmi3False;
    if (values) *values = fmi3False;
    if (next_defined) *next_defined = fmi3False;
    if (next) *next = 0.0;
    return fmi3OK;
}

fmi3Status fmi3GetEventIndicators(fmi3Instance c, fmi3Float64 z[], size_t n) {
    (void)z;
    Me3Instance *m = c;
    if (!fmi3_allowed(m, "fmi3GetEventIndicators", READABLE)) return fmi3Error;
    if (!fmi_check_length(&m->core, "fmi3GetEventIndicators", n, 0)) return fmi3_fail(m);
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance c, size_t *n) {
    Me3Instance *m = c;
    if (!fmi3_allowed(m, "fmi3GetNumberOfEventIndicators", ANY_PHASE)) return fmi3Error;
    *n = 0;
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance c, size_t *n) {
    Me3Instance *m = c;
    if (!fmi3_allowed(m, "fmi3GetNumberOfContinuousStates", ANY_PHASE)) return fmi3Error;
    *n = ME3_MODEL.n_states;
    return fmi3OK;
}

/* ---- what model exchange does not have --------------------------------- */

FMI3_UNSUPPORTED_CALL(fmi3EnterStepMode)

FMI3_UNSUPPORTED(fmi3DoStep, fmi3Float64 t, fmi3Float64 h, fmi3Boolean no_set_prior,
                 fmi3Boolean *event_handling_needed, fmi3Boolean *terminate_simulation,
                 fmi3Boolean *early_return, fmi3Float64 *last_successful_time)
