/*
 * wild_dual_me: the model-exchange half of a test FMU offering both FMI 2.0
 * interfaces (tests/simulation/test_fmi_types.py merges it with wild_dual_cs into one
 * .fmu with two binaries, dual_me.so and dual_cs.so, as FMI 2.0 allows).
 *
 *   x' = -a x,  x(0) = x0          a: default 1, x0: default 1
 *   me = 1                         (wild_dual_cs sets it to 0: shows which binary ran)
 *
 * Both halves share the GUID and the variables, value references included.
 */
#include "me2.h"

enum Real { A, X0, X, DER_X, ME, N_REALS };

static const double DEFAULTS[N_REALS] = {[A] = 1.0, [X0] = 1.0, [X] = 1.0, [DER_X] = 0.0, [ME] = 1.0};
static const char *const NAMES[N_REALS] = {"a", "x0", "x", "der(x)", "me"};
static const fmi2ValueReference STATES[] = {X};
static const fmi2ValueReference DERIVATIVES[] = {DER_X};

static int initial(MeInstance *m) {
    m->r[X] = m->r[X0];
    return 0;
}

static int equations(MeInstance *m) {
    m->r[DER_X] = -m->r[A] * m->r[X];
    m->r[ME] = 1.0;
    return 0;
}

const MeInfo ME_MODEL = {
    .guid = "{6f0c1f7e-2a4b-4d8e-9a55-0d7c3b9e1a21}",
    .n_reals = N_REALS,
    .real_defaults = DEFAULTS,
    .real_names = NAMES,
    .n_states = 1,
    .states = STATES,
    .derivatives = DERIVATIVES,
    .initial = initial,
    .equations = equations,
};
