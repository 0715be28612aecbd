/*
 * cosim_floor_single: the floor for driving one FMI 2.0 co-simulation FMU on
 * this machine.  It runs the FMU through its C API with a fixed step, reading
 * the given outputs into a buffer after every step, with nothing else around
 * it, and prints the median wall time of one run (reset, set-up, set the
 * reals, initialise, step to the end, terminate) in seconds, the final
 * value of the first output, and the fastest run's time.  benchmarks/cosim.py compares dse-runner's
 * master against it on a cheap FMU, where the master's overhead is all there
 * is to see.
 *
 * usage: cosim_floor_single SO GUID STOP STEP REPEATS OUT_VRS SETS
 *   OUT_VRS  real value references recorded every step, "vr,vr,..." (at least one)
 *   SETS     real values "vr=value,..." set before initialisation ("" for none)
 */
#define _POSIX_C_SOURCE 200809L
#include <dlfcn.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "fmi2Functions.h"

#define MAX_VARS 64

static void die(const char *what) {
    fprintf(stderr, "cosim_floor_single: %s\n", what);
    exit(1);
}

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String cat,
                   fmi2String msg, ...) {
    (void)env;
    (void)cat;
    fprintf(stderr, "%s [%d]: %s\n", name, status, msg);
}

static void *symbol(void *lib, const char *name) {
    void *f = dlsym(lib, name);
    if (!f) die(name);
    return f;
}

/* Parses "a,b,..." into value references; returns the count. */
static int refs(const char *text, fmi2ValueReference *vr, int max) {
    int n = 0;
    const char *p = text;
    while (*p && n < max) {
        char *end;
        vr[n++] = (fmi2ValueReference)strtoul(p, &end, 10);
        if (end == p || (*end && *end != ',')) die("bad value reference list");
        p = *end == ',' ? end + 1 : end;
    }
    return n;
}

/* Parses "vr=value,..." into parallel arrays; returns the count. */
static int sets(const char *text, fmi2ValueReference *vr, double *value, int max) {
    int n = 0;
    const char *p = text;
    while (*p && n < max) {
        char *end;
        vr[n] = (fmi2ValueReference)strtoul(p, &end, 10);
        if (*end != '=') die("bad value list");
        value[n++] = strtod(end + 1, &end);
        p = *end == ',' ? end + 1 : end;
    }
    return n;
}

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

static int by_value(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

#define CHECK(call) \
    if ((call) > fmi2Warning) die(#call)

int main(int argc, char **argv) {
    if (argc != 8) die("usage: see the comment at the top of cosim_floor_single.c");
    const double stop = atof(argv[3]), step = atof(argv[4]);
    const int repeats = atoi(argv[5]);
    if (repeats < 1) die("REPEATS must be >= 1");
    fmi2ValueReference out_vr[MAX_VARS], set_vr[MAX_VARS];
    double set_value[MAX_VARS];
    const int n_out = refs(argv[6], out_vr, MAX_VARS);
    const int n_set = sets(argv[7], set_vr, set_value, MAX_VARS);
    if (n_out < 1) die("no output to record");

    void *lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!lib) die(dlerror());
    fmi2InstantiateTYPE *instantiate = symbol(lib, "fmi2Instantiate");
    fmi2ResetTYPE *reset = symbol(lib, "fmi2Reset");
    fmi2SetupExperimentTYPE *setup = symbol(lib, "fmi2SetupExperiment");
    fmi2EnterInitializationModeTYPE *enter = symbol(lib, "fmi2EnterInitializationMode");
    fmi2ExitInitializationModeTYPE *exit_ = symbol(lib, "fmi2ExitInitializationMode");
    fmi2TerminateTYPE *terminate = symbol(lib, "fmi2Terminate");
    fmi2DoStepTYPE *do_step = symbol(lib, "fmi2DoStep");
    fmi2GetRealTYPE *get_real = symbol(lib, "fmi2GetReal");
    fmi2SetRealTYPE *set_real = symbol(lib, "fmi2SetReal");
    fmi2FreeInstanceTYPE *free_instance = symbol(lib, "fmi2FreeInstance");

    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    fmi2Component c = instantiate("model", fmi2CoSimulation, argv[2], "", &cb, fmi2False, fmi2False);
    if (!c) die("fmi2Instantiate failed");
    const int n_steps = (int)ceil(stop / step - 1e-9);
    double *record = malloc(sizeof(double) * (size_t)(n_steps + 1) * (size_t)n_out);
    double *times = malloc(sizeof(double) * (size_t)repeats);
    if (!record || !times) die("out of memory");

    for (int rep = 0; rep < repeats; rep++) {
        const double t0 = now();
        CHECK(reset(c));
        CHECK(setup(c, fmi2False, 0, 0, fmi2False, 0));
        if (n_set) CHECK(set_real(c, set_vr, n_set, set_value));
        CHECK(enter(c));
        CHECK(exit_(c));
        CHECK(get_real(c, out_vr, n_out, record));
        for (int k = 0; k < n_steps; k++) {
            const double t = k * step, h = (k + 1 == n_steps) ? stop - t : step;
            CHECK(do_step(c, t, h, fmi2True));
            CHECK(get_real(c, out_vr, n_out, record + (size_t)(k + 1) * n_out));
        }
        CHECK(terminate(c));
        times[rep] = now() - t0;
    }
    const double last = record[(size_t)n_steps * n_out];
    free_instance(c);
    qsort(times, repeats, sizeof(double), by_value);
    printf("%.9f %.17g %.9f\n", times[repeats / 2], last, times[0]);
    free(record);
    free(times);
    return 0;
}
