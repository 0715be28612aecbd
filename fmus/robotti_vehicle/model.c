/*
 * robotti_vehicle: the baseline continuous-time model of the Robotti
 * (shared/robotti-model.md), a dynamic bicycle model with saturated linear
 * tyres and a speed-controlled drive, integrated with fixed-step RK4.
 *
 * Value references are the indices of enum Real; modelDescription.xml lists
 * the same variables in the same order.
 */
#include <math.h>

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

enum State { SX, SY, SPSI, SVX, SVY, SR, N_STATES };

static double clamp(double v, double lo, double hi) { return v < lo ? lo : v > hi ? hi : v; }

/* Right-hand side of the model's equations; p is the real-variable array. */
static void derivatives(const double *p, const double *z, double velocity, double delta_f,
                        double *dz) {
    const double m = p[MASS], mu = p[MU], g = p[G], lf = p[LF], lr = p[LR];
    const double L = lf + lr, iz = m * p[R_GYR] * p[R_GYR];
    const double delta = -delta_f; /* counter-clockwise steering angle */
    const double vx = z[SVX], vy = z[SVY], r = z[SR], psi = z[SPSI];

    const double f_drive = clamp(p[KV] * (velocity - vx), -mu * m * g, mu * m * g);
    const double fade = fmin(1.0, fmax(vx, 0.0) / p[V_MIN]);
    const double v_s = fmax(vx, p[V_MIN]);
    const double alpha_f = delta - atan((vy + lf * r) / v_s);
    const double alpha_r = -atan((vy - lr * r) / v_s);
    const double fzf = m * g * lr / L, fzr = m * g * lf / L;
    const double fyf = fade * clamp(p[C_ALPHA_F] * alpha_f, -mu * fzf, mu * fzf);
    const double fyr = fade * clamp(p[C_ALPHA_R] * alpha_r, -mu * fzr, mu * fzr);
    const double cd = cos(delta), sd = sin(delta), cp = cos(psi), sp = sin(psi);

    dz[SVX] = (f_drive - fyf * sd) / m + vy * r;
    dz[SVY] = (fyf * cd + fyr) / m - vx * r;
    dz[SR] = (lf * fyf * cd - lr * fyr) / iz;
    dz[SX] = vx * cp - vy * sp;
    dz[SY] = vx * sp + vy * cp;
    dz[SPSI] = r;
}

static void publish(Slave *s, const double *z) {
    double *p = s->r;
    p[X] = z[SX];
    p[Y] = z[SY];
    p[THETA] = z[SPSI];
    p[VX] = z[SVX];
    p[VY] = z[SVY];
    p[YAW_RATE] = z[SR];
}

/* The initial pose comes from parameters; the vehicle starts at rest. */
static int start_at_rest(Slave *s) {
    double *z = s->state;
    for (int i = 0; i < N_STATES; i++) z[i] = 0.0;
    z[SX] = s->r[X0];
    z[SY] = s->r[Y0];
    z[SPSI] = s->r[THETA0];
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
    const double velocity = p[VELOCITY], delta_f = p[DELTA_F];
    double *z = s->state;
    double k1[N_STATES], k2[N_STATES], k3[N_STATES], k4[N_STATES], tmp[N_STATES];

    /* Whole RK4 steps of at most rk4_step that end exactly at t + h. */
    const int n = (int)ceil(h / p[RK4_STEP] - 1e-9);
    const double dt = h / (n > 0 ? n : 1);
    for (int step = 0; step < n; step++) {
        derivatives(p, z, velocity, delta_f, k1);
        for (int i = 0; i < N_STATES; i++) tmp[i] = z[i] + 0.5 * dt * k1[i];
        derivatives(p, tmp, velocity, delta_f, k2);
        for (int i = 0; i < N_STATES; i++) tmp[i] = z[i] + 0.5 * dt * k2[i];
        derivatives(p, tmp, velocity, delta_f, k3);
        for (int i = 0; i < N_STATES; i++) tmp[i] = z[i] + dt * k3[i];
        derivatives(p, tmp, velocity, delta_f, k4);
        for (int i = 0; i < N_STATES; i++) z[i] += dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
    }
    for (int i = 0; i < N_STATES; i++)
        if (!isfinite(z[i])) {
            slave_log(s, fmi2Error, "logStatusError",
                      "vehicle state diverged (non-finite) during the step from t=%.6g to t=%.6g; "
                      "try a smaller rk4_step",
                      t, t + h);
            return 1;
        }
    publish(s, z);
    return 0;
}

const ModelInfo MODEL = {
    .guid = "{5d0c2b8e-6f5a-4c1e-9a57-7b3c1f0e2a11}",
    .n_reals = N_REALS,
    .real_defaults = DEFAULTS,
    .n_strings = 0,
    .string_defaults = 0,
    .state_size = N_STATES * sizeof(double),
    .enter_initialization = start_at_rest,
    .exit_initialization = check_parameters,
    .do_step = do_step,
    .release = 0,
};
