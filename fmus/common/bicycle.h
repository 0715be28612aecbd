/*
 * bicycle.h: the Robotti's dynamic bicycle model (docs/robotti-model.md) and
 * a fixed-step RK4 integrator, shared by the baseline vehicle FMU and its
 * effects variant.  Ground carries what the baseline leaves out of the
 * vehicle-ground contact (soil slip, terrain slope); NULL is the baseline.
 */
#ifndef DSE_BICYCLE_H
#define DSE_BICYCLE_H

#include <math.h>
#include <stdint.h>
#include <string.h>

#include "slave.h"

typedef struct {
    double m, c_alpha_f, c_alpha_r, mu, lf, lr, r_gyr, kv, v_min, g;
} Bicycle;

typedef struct {
    double slip;             /* longitudinal slip ratio: ground speed = (1 - slip) * wheel speed */
    double grade_x, grade_y; /* terrain rise per metre east and north */
} Ground;

enum BicycleState { B_X, B_Y, B_PSI, B_VX, B_VY, B_R, BICYCLE_STATES };

/* The cosine and sine of the last steering angle seen. The inputs are held over a communication
 * step, so its RK4 stages (200 at 1 ms in a 50 ms step) share one evaluation of each: a fifth of
 * the model's instructions. The angle is compared bit for bit, so -0.0 keeps its own sine. */
typedef struct {
    uint64_t angle; /* the bits of the angle; valid once set */
    int set;
    double cos, sin;
} SteeringTrig;

static inline void steering_trig(SteeringTrig *trig, double angle) {
    uint64_t bits;
    memcpy(&bits, &angle, sizeof bits);
    if (trig->set && bits == trig->angle) return;
    trig->angle = bits;
    trig->set = 1;
    trig->cos = cos(angle);
    trig->sin = sin(angle);
}

static inline double bicycle_clamp(double v, double lo, double hi) { return v < lo ? lo : v > hi ? hi : v; }

/* Right-hand side for the six bicycle states z; velocity is the commanded
 * (wheel) speed, delta_f the front steering angle, positive = right turn;
 * trig remembers the angle's cosine and sine between calls. */
static inline void bicycle_derivatives(const Bicycle *b, const Ground *ground, SteeringTrig *trig,
                                       const double *z, double velocity, double delta_f, double *dz) {
    const double m = b->m, mu = b->mu, g = b->g, lf = b->lf, lr = b->lr;
    const double L = lf + lr, iz = m * b->r_gyr * b->r_gyr;
    const double delta = -delta_f; /* counter-clockwise steering angle */
    const double vx = z[B_VX], vy = z[B_VY], r = z[B_R], psi = z[B_PSI];
    const double cp = cos(psi), sp = sin(psi);

    /* The drive regulates wheel speed; on slipping soil the ground speed is lower. */
    const double wheel_speed = ground ? vx / (1.0 - ground->slip) : vx;
    const double f_drive = bicycle_clamp(b->kv * (velocity - wheel_speed), -mu * m * g, mu * m * g);
    const double fade = fmin(1.0, fmax(vx, 0.0) / b->v_min);
    const double v_s = fmax(vx, b->v_min);
    const double alpha_f = delta - atan((vy + lf * r) / v_s);
    const double alpha_r = -atan((vy - lr * r) / v_s);
    const double fzf = m * g * lr / L, fzr = m * g * lf / L;
    const double fyf = fade * bicycle_clamp(b->c_alpha_f * alpha_f, -mu * fzf, mu * fzf);
    const double fyr = fade * bicycle_clamp(b->c_alpha_r * alpha_r, -mu * fzr, mu * fzr);
    steering_trig(trig, delta);
    const double cd = trig->cos, sd = trig->sin;

    /* Gravity along a sloped terrain, pulling downhill, in the body frame. */
    double fx_slope = 0.0, fy_slope = 0.0;
    if (ground) {
        const double down_x = -m * g * ground->grade_x, down_y = -m * g * ground->grade_y;
        fx_slope = down_x * cp + down_y * sp;
        fy_slope = -down_x * sp + down_y * cp;
    }

    dz[B_VX] = (f_drive - fyf * sd + fx_slope) / m + vy * r;
    dz[B_VY] = (fyf * cd + fyr + fy_slope) / m - vx * r;
    dz[B_R] = (lf * fyf * cd - lr * fyr) / iz;
    dz[B_X] = vx * cp - vy * sp;
    dz[B_Y] = vx * sp + vy * cp;
    dz[B_PSI] = r;
}

enum { RK4_MAX_STATES = 16 };

/* dz = f(t, z) for a model with context ctx (which may keep what it caches between calls). */
typedef void (*Rhs)(void *ctx, double t, const double *z, double *dz);

/* Classical RK4 from t to t + h in whole steps of at most max_step ending exactly at t + h. */
static inline void rk4_advance(Rhs f, void *ctx, int n, double *z, double t, double h, double max_step) {
    double k1[RK4_MAX_STATES], k2[RK4_MAX_STATES], k3[RK4_MAX_STATES], k4[RK4_MAX_STATES],
        tmp[RK4_MAX_STATES];
    const int steps = (int)ceil(h / max_step - 1e-9);
    const double dt = h / (steps > 0 ? steps : 1);
    for (int k = 0; k < steps; k++) {
        const double tk = t + k * dt;
        f(ctx, tk, z, k1);
        for (int i = 0; i < n; i++) tmp[i] = z[i] + 0.5 * dt * k1[i];
        f(ctx, tk + 0.5 * dt, tmp, k2);
        for (int i = 0; i < n; i++) tmp[i] = z[i] + 0.5 * dt * k2[i];
        f(ctx, tk + 0.5 * dt, tmp, k3);
        for (int i = 0; i < n; i++) tmp[i] = z[i] + dt * k3[i];
        f(ctx, tk + dt, tmp, k4);
        for (int i = 0; i < n; i++) z[i] += dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
    }
}

/* The six outputs x, y, theta, vx, vy, yaw_rate, consecutive from out[0]. */
static inline void bicycle_publish(double *out, const double *z) {
    out[0] = z[B_X];
    out[1] = z[B_Y];
    out[2] = z[B_PSI];
    out[3] = z[B_VX];
    out[4] = z[B_VY];
    out[5] = z[B_R];
}

/* 0 if every state is finite; otherwise logs the step that diverged and returns 1. */
static inline int check_finite(Slave *s, const double *z, int n, double t, double h) {
    for (int i = 0; i < n; i++)
        if (!isfinite(z[i])) {
            slave_log(s, fmi2Error, "logStatusError",
                      "vehicle state diverged (non-finite) during the step from t=%.6g to t=%.6g; "
                      "try a smaller rk4_step",
                      t, t + h);
            return 1;
        }
    return 0;
}

#endif
