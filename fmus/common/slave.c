/*
 * slave.c: the FMI 2.0 co-simulation entry points, written once for all our
 * FMUs; fmi2_common.c has the ones model exchange shares.
 *
 * The model (model.c) supplies a ModelInfo; this file owns its part of the
 * life cycle, instantiation and the steps; fmi2_common.c the rest
 * (instantiated -> initialization mode -> step mode -> terminated, and
 * fmi2Reset back to the start values so an importer can reuse one instance
 * for many runs).
 */
#include "fmi_common.h"
#include "slave.h"

/* Values are always up to date: the model computes them in its steps. */
int fmi2_refresh(Fmi2Instance *s) {
    (void)s;
    return 1;
}

Fmi2Instance *fmi2_create(fmi2String name, fmi2Type type, fmi2String guid, const fmi2CallbackFunctions *cb,
                          fmi2Boolean logging_on) {
    const Fmi2Model model = {
        .co_simulation = 1,
        .n_reals = MODEL.n_reals, .real_defaults = MODEL.real_defaults,
        .n_integers = MODEL.n_integers, .integer_defaults = MODEL.integer_defaults,
        .n_booleans = MODEL.n_booleans, .boolean_defaults = MODEL.boolean_defaults,
        .n_strings = MODEL.n_strings, .string_defaults = MODEL.string_defaults,
        .state_size = MODEL.state_size, .release = MODEL.release,
        .enter_initialization = MODEL.enter_initialization, .exit_initialization = MODEL.exit_initialization,
    };
    return fmi2_instantiate(name, type, guid, cb, logging_on, MODEL.guid, &model);
}

/* ---- steps ----------------------------------------------------------- */

static int step(FmiCore *c, double t, double h) { return MODEL.do_step((Slave *)c, t, h); }

/* A model that asks to stop (fmi_ask_to_stop) makes the step fmi2Discard: fmi2Terminated then reads
 * true and fmi2LastSuccessfulTime the time it reached, as FMI 2.0 says and FMPy reads them. */
fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean no_set_prior) {
    (void)no_set_prior;
    fmi2Status status = (fmi2Status)fmi_do_step(fmi2_core(c), "fmi2DoStep", t, h, step);
    return status == fmi2OK && ((Slave *)c)->stop_asked ? fmi2Discard : status;
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    Slave *s = c;
    if (s) slave_log(s, fmi2Error, "logStatusError", "fmi2CancelStep: steps are synchronous");
    return fmi2Error;
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
    if (k != fmi2LastSuccessfulTime)
        return (fmi2Status)fmi_unsupported(fmi2_core(c), "fmi2GetRealStatus for this kind");
    *v = s->time;
    return fmi2OK;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind k, fmi2Boolean *v) {
    Slave *s = c;
    if (!s) return fmi2Error;
    if (k != fmi2Terminated)
        return (fmi2Status)fmi_unsupported(fmi2_core(c), "fmi2GetBooleanStatus for this kind");
    *v = s->stop_asked ? fmi2True : fmi2False;
    return fmi2OK;
}

/* ---- optional capabilities this FMU declares it does not have ---------- */

FMI2_UNSUPPORTED(fmi2GetIntegerStatus, const fmi2StatusKind k, fmi2Integer *v)
FMI2_UNSUPPORTED(fmi2GetStringStatus, const fmi2StatusKind k, fmi2String *v)
FMI2_UNSUPPORTED(fmi2SetRealInputDerivatives, const fmi2ValueReference vr[], size_t n,
                 const fmi2Integer order[], const fmi2Real v[])
FMI2_UNSUPPORTED(fmi2GetRealOutputDerivatives, const fmi2ValueReference vr[], size_t n,
                 const fmi2Integer order[], fmi2Real v[])
