/*
 * cosim_floor: the floor for FMI co-simulation on this machine.  It drives a
 * controller FMU and a vehicle FMU through their FMI 2.0 C API with the same
 * fixed-step Jacobi scheme as dse-runner's master, with nothing else around
 * it, and prints the median wall time of one run (reset, set-up, initialise,
 * step to the end, terminate), in seconds.
 *
 * usage: cosim_floor VEHICLE_SO VEHICLE_GUID CONTROLLER_SO CONTROLLER_GUID
 *                    STOP STEP REPEATS FILE_VR CSV_PATH C2V V2C VEHICLE_SETS
 *   C2V, V2C      connections "out_vr:in_vr,..." (controller->vehicle, vehicle->controller)
 *   VEHICLE_SETS  real values "vr=value,..." set on the vehicle before initialisation
 */
#define _POSIX_C_SOURCE 200809L
#include <dlfcn.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "fmi2Functions.h"

typedef struct {
    void *lib;
    fmi2Component c;
    fmi2InstantiateTYPE *instantiate;
    fmi2ResetTYPE *reset;
    fmi2SetupExperimentTYPE *setup;
    fmi2EnterInitializationModeTYPE *enter;
    fmi2ExitInitializationModeTYPE *exit_;
    fmi2TerminateTYPE *terminate;
    fmi2DoStepTYPE *do_step;
    fmi2GetRealTYPE *get_real;
    fmi2SetRealTYPE *set_real;
    fmi2SetStringTYPE *set_string;
} Fmu;

static void die(const char *what) {
    fprintf(stderr, "cosim_floor: %s\n", what);
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

static Fmu load(const char *path, const char *guid, const char *name, const fmi2CallbackFunctions *cb) {
    Fmu f;
    f.lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!f.lib) die(dlerror());
    f.instantiate = symbol(f.lib, "fmi2Instantiate");
    f.reset = symbol(f.lib, "fmi2Reset");
    f.setup = symbol(f.lib, "fmi2SetupExperiment");
    f.enter = symbol(f.lib, "fmi2EnterInitializationMode");
    f.exit_ = symbol(f.lib, "fmi2ExitInitializationMode");
    f.terminate = symbol(f.lib, "fmi2Terminate");
    f.do_step = symbol(f.lib, "fmi2DoStep");
    f.get_real = symbol(f.lib, "fmi2GetReal");
    f.set_real = symbol(f.lib, "fmi2SetReal");
    f.set_string = symbol(f.lib, "fmi2SetString");
    f.c = f.instantiate(name, fmi2CoSimulation, guid, "", cb, fmi2False, fmi2False);
    if (!f.c) die("fmi2Instantiate failed");
    return f;
}

/* Parses "a:b,c:d" (sep ':') or "a=b,..." (sep '=') into parallel arrays; returns the count. */
static int pairs(const char *text, char sep, unsigned *left, double *right, int max) {
    int n = 0;
    const char *p = text;
    while (*p && n < max) {
        char *end;
        left[n] = (unsigned)strtoul(p, &end, 10);
        if (*end != sep) die("bad pair list");
        right[n] = strtod(end + 1, &end);
        n++;
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
    if (argc != 13) die("usage: see the comment at the top of cosim_floor.c");
    const double stop = atof(argv[5]), step = atof(argv[6]);
    const int repeats = atoi(argv[7]);
    const fmi2ValueReference file_vr = (fmi2ValueReference)atoi(argv[8]);
    const char *csv = argv[9];
    unsigned c2v_out[16], v2c_out[16], set_vr[32];
    double c2v_in[16], v2c_in[16], set_value[32];
    const int n_c2v = pairs(argv[10], ':', c2v_out, c2v_in, 16);
    const int n_v2c = pairs(argv[11], ':', v2c_out, v2c_in, 16);
    const int n_set = pairs(argv[12], '=', set_vr, set_value, 32);
    fmi2ValueReference c2v_from[16], c2v_to[16], v2c_from[16], v2c_to[16];
    for (int i = 0; i < n_c2v; i++) c2v_from[i] = c2v_out[i], c2v_to[i] = (fmi2ValueReference)c2v_in[i];
    for (int i = 0; i < n_v2c; i++) v2c_from[i] = v2c_out[i], v2c_to[i] = (fmi2ValueReference)v2c_in[i];

    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    Fmu vehicle = load(argv[1], argv[2], "vehicle", &cb);
    Fmu controller = load(argv[3], argv[4], "controller", &cb);
    const int n_steps = (int)ceil(stop / step - 1e-9);
    double *times = malloc(sizeof(double) * (repeats > 0 ? repeats : 1));
    double c_out[16], v_out[16], last_x = 0;

    for (int rep = 0; rep < repeats; rep++) {
        const double t0 = now();
        CHECK(vehicle.reset(vehicle.c));
        CHECK(controller.reset(controller.c));
        CHECK(vehicle.setup(vehicle.c, fmi2False, 0, 0, fmi2False, 0));
        CHECK(controller.setup(controller.c, fmi2False, 0, 0, fmi2False, 0));
        for (int i = 0; i < n_set; i++) CHECK(vehicle.set_real(vehicle.c, &set_vr[i], 1, &set_value[i]));
        CHECK(controller.set_string(controller.c, &file_vr, 1, &csv));
        CHECK(vehicle.enter(vehicle.c));
        CHECK(controller.enter(controller.c));
        CHECK(vehicle.exit_(vehicle.c));
        CHECK(controller.exit_(controller.c));
        CHECK(controller.get_real(controller.c, c2v_from, n_c2v, c_out));
        CHECK(vehicle.get_real(vehicle.c, v2c_from, n_v2c, v_out));
        for (int k = 0; k < n_steps; k++) {
            const double t = k * step, h = (k + 1 == n_steps) ? stop - t : step;
            CHECK(vehicle.set_real(vehicle.c, c2v_to, n_c2v, c_out));
            CHECK(controller.set_real(controller.c, v2c_to, n_v2c, v_out));
            CHECK(vehicle.do_step(vehicle.c, t, h, fmi2True));
            CHECK(controller.do_step(controller.c, t, h, fmi2True));
            CHECK(controller.get_real(controller.c, c2v_from, n_c2v, c_out));
            CHECK(vehicle.get_real(vehicle.c, v2c_from, n_v2c, v_out));
        }
        CHECK(vehicle.terminate(vehicle.c));
        CHECK(controller.terminate(controller.c));
        times[rep] = now() - t0;
        last_x = v_out[0];
    }
    qsort(times, repeats, sizeof(double), by_value);
    printf("%.9f %.9f\n", times[repeats / 2], last_x);
    return 0;
}
