/*
 * fmi_common.c: the version-neutral helpers of fmi_common.h.
 */
#include <math.h>
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

int fmi_step_refused(char *why, size_t size, const char *function, double now, double t, double h) {
    if (!(h > 0.0)) {
        snprintf(why, size, "communication step size must be > 0, got %g", h);
        return 1;
    }
    if (fabs(t - now) > 1e-9 * (1.0 + fabs(t))) {
        snprintf(why, size, "%s at t=%.9g but the FMU is at t=%.9g (no rollback)", function, t, now);
        return 1;
    }
    return 0;
}
