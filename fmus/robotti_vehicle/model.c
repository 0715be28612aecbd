/*
 * robotti_vehicle: the baseline continuous-time model of the Robotti
 * (docs/robotti-model.md), a dynamic bicycle model with saturated linear
 * tyres and a speed-controlled drive, integrated with fixed-step RK4.
 *
 * Value references are the indices of enum Real; modelDescription.xml lists
 * the same variables in the same order.
 */
#include "bicycle.h"
#include "slave.h"

enum Real {
    /* parameters */
    MASS, C_ALPHA_F, C_ALPHA_R, MU, LF, LR, R_GYR, KV, V_MIN, G,
    X0, Y0, THETA0, RK4_STEP,
    /* inputs */
    VELOCITY, DELTA_F,
    /* outputs */
    X, Y, THETA, VX, VY, YAW_RATE,
    N_REALS
};

static const double DEFAULTS[N_REALS] = {
    [MASS] = 1500.0, [C_ALPHA_F] = 30000.0, [C_ALPHA_R] = 30000.0, [MU] = 0.5,
    [LF] = 0.9, [LR] = 0.9, [R_GYR] = 0.9, [KV] = 8000.0, [V_MIN] = 0.5, [G] = 9.81,
    [X0] = 0.0, [Y0] = 0.0, [THETA0] = 0.0, [RK4_STEP] = 0.001,
};

/* The model's parameters as the shared bicycle model takes them. */
static Bicycle bicycle_of(const double *p) {
    return (Bicycle){p[MASS], p[C_ALPHA_F], p[C_ALPHA_R], p[MU], p[LF], p[LR], p[R_GYR], p[KV], p[V_MIN], p[G]};
}

typedef struct {
    Bicycle bicycle;
    double velocity, delta_f; /* inputs, held over the communication step */
    SteeringTrig trig;
} Step;

static void rhs(void *ctx, double t, const double *z, double *dz) {
    Step *step = ctx;
    (void)t;
    bicycle_derivatives(&step->bicycle, 0, &step->trig, z, step->velocity, step->delta_f, dz);
}

static void publish(Slave *s, const double *z) {
    double *p = s->r;
    bicycle_publish(&p[X], z); /* X, Y, THETA, VX, VY, YAW_RATE are consecutive */
}

/* The initial pose comes from parameters; the vehicle starts at rest. */
static int start_at_rest(Slave *s) {
    double *z = s->state;
    for (int i = 0; i < BICYCLE_STATES; i++) z[i] = 0.0;
    z[B_X] = s->r[X0];
    z[B_Y] = s->r[Y0];
    z[B_PSI] = s->r[THETA0];
    publish(s, z);
    return 0;
}

static int check_parameters(Slave *s) {
    const double *p = s->r;
    const struct { const char *name; double value; } positive[] = {
        {"mass", p[MASS]}, {"lf + lr", p[LF] + p[LR]}, {"r_gyr", p[R_GYR]},
        {"v_min", p[V_MIN]}, {"rk4_step", p[RK4_STEP]},
    };
    for (size_t i = 0; i < sizeof positive / sizeof positive[0]; i++)
        if (!(positive[i].value > 0.0) || !isfinite(positive[i].value)) {
            slave_log(s, fmi2Error, "logStatusError", "parameter %s must be > 0, got %g",
                      positive[i].name, positive[i].value);
            return 1;
        }
    return start_at_rest(s);
}

static int do_step(Slave *s, double t, double h) {
    const double *p = s->r;
    Step step = {bicycle_of(p), p[VELOCITY], p[DELTA_F], {0}};
    double *z = s->state;
    rk4_advance(rhs, &step, BICYCLE_STATES, z, t, h, p[RK4_STEP]);
    if (check_finite(s, z, BICYCLE_STATES, t, h) != 0) return 1;
    publish(s, z);
    return 0;
}

const ModelInfo MODEL = {
    .guid = "{5d0c2b8e-6f5a-4c1e-9a57-7b3c1f0e2a11}",
    .n_reals = N_REALS,
    .real_defaults = DEFAULTS,
    .n_strings = 0,
    .string_defaults = 0,
    .state_size = BICYCLE_STATES * sizeof(double),
    .enter_initialization = start_at_rest,
    .exit_initialization = check_parameters,
    .do_step = do_step,
    .release = 0,
};
