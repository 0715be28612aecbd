/*
 * slave3.c: the FMI 3.0 co-simulation entry points, written once for all our
 * FMI 3 FMUs; fmi3_common.c has the ones model exchange shares.
 *
 * The model (model.c) supplies a ModelInfo3; this file owns its part of the
 * life cycle, instantiation and the steps; fmi3_common.c the rest
 * (instantiated -> initialization mode -> step mode -> terminated, and
 * fmi3Reset back to the start values so an importer can reuse one instance
 * for many runs).  It mirrors slave.c so the two layers can be read side by
 * side.
 */
#include "fmi_common.h"
#include "slave3.h"

/* Values are always up to date: the model computes them in its steps. */
int fmi3_refresh(Fmi3Instance *s) {
    (void)s;
    return 1;
}

Fmi3Instance *fmi3_create(int co_simulation, fmi3String name, fmi3String token, fmi3Boolean event_mode_used,
                          fmi3Boolean logging_on, fmi3InstanceEnvironment environment,
                          fmi3LogMessageCallback logger) {
    const char *refusal =
        !co_simulation   ? "fmi3InstantiateModelExchange is not supported: this FMU is co-simulation only"
        : event_mode_used ? "event mode is not supported (the FMU declares hasEventMode=\"false\")"
                          : NULL;
    const Fmi3Model model = {
        .co_simulation = 1, .variables = MODEL.variables, .n_variables = MODEL.n_variables,
        .state_size = MODEL.state_size, .release = MODEL.release,
        .enter_initialization = MODEL.enter_initialization, .exit_initialization = MODEL.exit_initialization,
    };
    return fmi3_instantiate(name, token, MODEL.instantiation_token, refusal, logging_on, environment,
                            logger, &model);
}

/* ---- steps ----------------------------------------------------------- */

static int step(FmiCore *c, double t, double h) { return MODEL.do_step((Slave3 *)c, t, h); }

fmi3Status fmi3DoStep(fmi3Instance c, fmi3Float64 t, fmi3Float64 h, fmi3Boolean no_set_prior,
                      fmi3Boolean *event_handling_needed, fmi3Boolean *terminate_simulation,
                      fmi3Boolean *early_return, fmi3Float64 *last_successful_time) {
    (void)no_set_prior;
    Slave3 *s = c;
    if (!fmi3_allowed(s, "fmi3DoStep", BIT(STEP_MODE))) return fmi3Error;
    /* Set the flags first: whatever happens, the importer reads defined values. */
    if (event_handling_needed) *event_handling_needed = fmi3False;
    if (terminate_simulation) *terminate_simulation = fmi3False;
    if (early_return) *early_return = fmi3False;
    fmi3Status status = (fmi3Status)fmi_do_step(&s->core, "fmi3DoStep", t, h, step);
    if (terminate_simulation && status == fmi3OK) *terminate_simulation = s->stop_asked ? fmi3True : fmi3False;
    if (last_successful_time) *last_successful_time = s->time;
    return status;
}

/* ---- what co-simulation without event mode does not have --------------- */

FMI3_UNSUPPORTED_CALL(fmi3EnterEventMode)
FMI3_UNSUPPORTED_CALL(fmi3EnterStepMode)
FMI3_UNSUPPORTED_CALL(fmi3EnterContinuousTimeMode)

FMI3_UNSUPPORTED(fmi3UpdateDiscreteStates, fmi3Boolean *update, fmi3Boolean *terminate,
                 fmi3Boolean *nominals, fmi3Boolean *values, fmi3Boolean *next_defined, fmi3Float64 *next)
FMI3_UNSUPPORTED(fmi3CompletedIntegratorStep, fmi3Boolean no_set_prior, fmi3Boolean *enter_event_mode,
                 fmi3Boolean *terminate_simulation)
FMI3_UNSUPPORTED(fmi3SetTime, fmi3Float64 time)
FMI3_UNSUPPORTED(fmi3SetContinuousStates, const fmi3Float64 x[], size_t n)
FMI3_UNSUPPORTED(fmi3GetContinuousStateDerivatives, fmi3Float64 dx[], size_t n)
FMI3_UNSUPPORTED(fmi3GetEventIndicators, fmi3Float64 z[], size_t n)
FMI3_UNSUPPORTED(fmi3GetContinuousStates, fmi3Float64 x[], size_t n)
FMI3_UNSUPPORTED(fmi3GetNominalsOfContinuousStates, fmi3Float64 nominals[], size_t n)
FMI3_UNSUPPORTED(fmi3GetNumberOfEventIndicators, size_t *n)
FMI3_UNSUPPORTED(fmi3GetNumberOfContinuousStates, size_t *n)
