/*
 * vanderpol: the Van der Pol oscillator as an FMI 2.0 co-simulation FMU, with
 * the shape of the Modelica Reference FMU VanDerPol (same variables, value
 * references, start values and default experiment).
 *
 *   der(x0) = x1
 *   der(x1) = mu * ((1 - x0 * x0) * x1) - x0          x0(0) = 2, x1(0) = 0, mu = 1
 *
 * Why it exists: a cheap FMU for the master-overhead benchmark of issue 16
 * (benchmarks/cosim.py, case "cheap").  A step costs a few floating-point
 * operations, so what a run of 2000 steps costs is almost all the master's.
 *
 * What it computes: like the Reference FMU's co-simulation, forward Euler at a
 * fixed internal step H = 1e-2 s.  fmi2DoStep(t, h) takes n = ceil(h / H)
 * equal Euler steps of h / n (exactly one step of h when h equals H), each
 *
 *   x0 += dt * x1;  x1 += dt * (mu * ((1 - x0 * x0) * x1) - x0)     (both from the old x)
 *
 * der(x0) and der(x1) are kept equal to the derivatives at the current state.
 */
#include <math.h>

#include "slave.h"

/* The Reference FMU's value references: x0, der(x0), x1, der(x1), mu. */
enum Real { X0, DER_X0, X1, DER_X1, MU, N_REALS };

static const double DEFAULTS[N_REALS] = {[X0] = 2.0, [DER_X0] = 0.0, [X1] = 0.0, [DER_X1] = -2.0, [MU] = 1.0};

static const double SOLVER_STEP = 1e-2; /* the Reference FMU's FIXED_SOLVER_STEP */

static void derivatives(double *r) {
    r[DER_X0] = r[X1];
    r[DER_X1] = r[MU] * ((1.0 - r[X0] * r[X0]) * r[X1]) - r[X0];
}

/* The start state and mu are final here: check them once, where a bad value can be blamed on them. */
static int exit_initialization(Slave *s) {
    if (!isfinite(s->r[MU]) || !isfinite(s->r[X0]) || !isfinite(s->r[X1])) {
        slave_log(s, fmi2Error, "logStatusError", "mu, x0 and x1 must be finite, got %g, %g, %g",
                  s->r[MU], s->r[X0], s->r[X1]);
        return 1;
    }
    derivatives(s->r);
    return 0;
}

static int do_step(Slave *s, double t, double h) {
    (void)t;
    double *r = s->r;
    int n = (int)ceil(h / SOLVER_STEP - 1e-9);
    if (n < 1) n = 1;
    const double dt = h / n;
    for (int i = 0; i < n; i++) {
        derivatives(r);
        r[X0] += dt * r[DER_X0];
        r[X1] += dt * r[DER_X1];
    }
    derivatives(r);
    if (!isfinite(r[X0]) || !isfinite(r[X1])) {
        slave_log(s, fmi2Error, "logStatusError", "the state diverged at t=%g (mu=%g): x0=%g, x1=%g", t + h,
                  r[MU], r[X0], r[X1]);
        return 1;
    }
    return 0;
}

const ModelInfo MODEL = {
    .guid = "{6f1d2a0e-5b7c-4c39-9a8e-2d4b1f7c3e90}",
    .n_reals = N_REALS,
    .real_defaults = DEFAULTS,
    .exit_initialization = exit_initialization,
    .do_step = do_step,
};
