/*
 * fmi_common.c: the version-neutral calls of fmi_common.h, written once for
 * FMI 2.0 and 3.0, co-simulation and model exchange.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi_common.h"

const char *const fmi_phase_names[N_PHASES] = {
    "instantiated", "initialization mode", "step mode", "event mode", "continuous-time mode",
    "terminated",   "error"};

char *fmi_copy_text(const char *text) {
    const char *source = text ? text : "";
    size_t n = strlen(source) + 1;
    char *copy = malloc(n);
    if (copy) memcpy(copy, source, n);
    return copy;
}

void *fmi_zeroed(size_t n, size_t size) { return calloc(n ? n : 1, size); }

/* ---- logging and the guard ------------------------------------------------ */

void fmi_vlog(FmiCore *c, int status, const char *category, const char *fmt, va_list ap) {
    if (status == FMI_OK && !c->logging_on) return;
    char message[1024];
    vsnprintf(message, sizeof message, fmt, ap);
    c->calls->emit(c, status, category, message);
}

void fmi_log(FmiCore *c, int status, const char *category, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    fmi_vlog(c, status, category, fmt, ap);
    va_end(ap);
}

int fmi_allowed(FmiCore *c, const char *function, unsigned phases) {
    if (!c) return 0;
    if (phases & BIT(c->phase)) return 1;
    fmi_log(c, FMI_ERROR, "logStatusError", "%s is not allowed in %s", function, fmi_phase_names[c->phase]);
    c->phase = FAILED;
    return 0;
}

int fmi_fail(FmiCore *c) {
    c->phase = FAILED;
    return FMI_ERROR;
}

int fmi_error(FmiCore *c, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    fmi_vlog(c, FMI_ERROR, "logStatusError", fmt, ap);
    va_end(ap);
    return fmi_fail(c);
}

int fmi_enter(FmiCore *c, const char *function, unsigned phases, int to) {
    if (!fmi_allowed(c, function, phases)) return FMI_ERROR;
    c->phase = to;
    return FMI_OK;
}

int fmi_unsupported(FmiCore *c, const char *function) {
    if (c) fmi_log(c, FMI_ERROR, "logStatusError", "%s is not supported by this FMU", function);
    return FMI_ERROR;
}

int fmi_set_debug_logging(FmiCore *c, int on) {
    if (!c) return FMI_ERROR;
    c->logging_on = on;
    return FMI_OK;
}

/* ---- life cycle ------------------------------------------------------------- */

int fmi_enter_initialization(FmiCore *c, const char *function, double start) {
    if (!fmi_allowed(c, function, BIT(INSTANTIATED))) return FMI_ERROR;
    c->time = start;
    c->phase = INITIALIZATION;
    c->stale = 1;
    c->stop_asked = 0;
    if (c->calls->enter_initialization(c) != 0) return fmi_fail(c);
    return FMI_OK;
}

int fmi_exit_initialization(FmiCore *c, const char *function) {
    if (!fmi_allowed(c, function, BIT(INITIALIZATION))) return FMI_ERROR;
    c->stale = 1; /* model exchange: the initial states are final now, compute them one last time */
    if (!c->calls->refresh(c)) return fmi_fail(c);
    if (c->calls->exit_initialization(c) != 0) return fmi_fail(c);
    c->phase = c->co_simulation ? STEP_MODE : EVENT_MODE;
    return FMI_OK;
}

int fmi_terminate(FmiCore *c, const char *function) {
    if (!fmi_allowed(c, function, BIT(STEP_MODE) | BIT(EVENT_MODE) | BIT(CONTINUOUS_TIME_MODE)))
        return FMI_ERROR;
    if (!c->calls->refresh(c)) return fmi_fail(c);
    c->phase = TERMINATED;
    return FMI_OK;
}

int fmi_do_step(FmiCore *c, const char *function, double t, double h,
                int (*step)(FmiCore *c, double t, double h)) {
    if (!fmi_allowed(c, function, BIT(STEP_MODE))) return FMI_ERROR;
    if (!(h > 0.0)) return fmi_error(c, "communication step size must be > 0, got %g", h);
    if (fabs(t - c->time) > 1e-9 * (1.0 + fabs(t)))
        return fmi_error(c, "%s at t=%.9g but the FMU is at t=%.9g (no rollback)", function, t, c->time);
    if (c->stop_asked) return fmi_error(c, "%s after the FMU asked to stop at t=%.9g", function, c->stop_time);
    if (step(c, t, h) != 0) return fmi_fail(c);
    c->time = c->stop_asked ? c->stop_time : t + h;
    return FMI_OK;
}

void fmi_ask_to_stop(FmiCore *c, double at) {
    c->stop_asked = 1;
    c->stop_time = at;
}

/* ---- model exchange ------------------------------------------------------ */

int fmi_check_length(FmiCore *c, const char *function, size_t given, size_t expected) {
    if (given == expected) return 1;
    fmi_log(c, FMI_ERROR, "logStatusError", "%s: %zu values given, the model has %zu", function, given,
            expected);
    return 0;
}

int fmi_set_time(FmiCore *c, const char *function, double time) {
    if (!fmi_allowed(c, function, BIT(EVENT_MODE) | BIT(CONTINUOUS_TIME_MODE))) return FMI_ERROR;
    c->time = time;
    c->stale = 1;
    return FMI_OK;
}

int fmi_set_states(FmiCore *c, const char *function, double *r, FmiStates m, const double x[],
                   size_t nx) {
    if (!fmi_allowed(c, function, BIT(CONTINUOUS_TIME_MODE))) return FMI_ERROR;
    if (!fmi_check_length(c, function, nx, m.n_states)) return fmi_fail(c);
    for (size_t i = 0; i < nx; i++) r[m.states[i]] = x[i];
    c->stale = 1;
    return FMI_OK;
}

int fmi_read_states(FmiCore *c, const char *function, const double *r, FmiStates m,
                    const unsigned refs[], double x[], size_t nx) {
    if (!fmi_allowed(c, function, READABLE)) return FMI_ERROR;
    if (!fmi_check_length(c, function, nx, m.n_states)) return fmi_fail(c);
    if (!c->calls->refresh(c)) return fmi_fail(c);
    for (size_t i = 0; i < nx; i++) x[i] = r[refs[i]];
    return FMI_OK;
}

int fmi_nominals(FmiCore *c, const char *function, FmiStates m, double out[], size_t nx) {
    if (!fmi_allowed(c, function, BIT(INSTANTIATED) | READABLE)) return FMI_ERROR;
    if (!fmi_check_length(c, function, nx, m.n_states)) return fmi_fail(c);
    for (size_t i = 0; i < nx; i++) out[i] = m.nominals ? m.nominals[i] : 1.0;
    return FMI_OK;
}

int fmi_derivatives_finite(FmiCore *c, const double *r, FmiStates m) {
    for (size_t i = 0; i < m.n_states; i++) {
        unsigned vr = m.derivatives[i];
        if (isfinite(r[vr])) continue;
        if (m.names)
            fmi_log(c, FMI_ERROR, "logStatusError", "%s is %g at t=%.9g", m.names[vr], r[vr], c->time);
        else
            fmi_log(c, FMI_ERROR, "logStatusError", "value reference %u is %g at t=%.9g", vr, r[vr],
                    c->time);
        return 0;
    }
    return 1;
}
