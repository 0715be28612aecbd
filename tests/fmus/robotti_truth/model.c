/*
 * robotti_truth: a test-only "real machine" for the blind diagnosis tests
 * (docs/research/diagnosis-beyond-library.md, section 6).
 *
 * It is the Robotti vehicle of docs/robotti-model.md written out again with
 * its own right-hand side and integrator, deliberately not bicycle.h: a bug
 * shared with the model under diagnosis could otherwise hide in both.  It
 * carries every effect of robotti_vehicle_effects under the same names (so a
 * blind case sets them the same way) and effects the diagnosis library does
 * not have.  Everything is off (zero) by default, and then it computes what
 * robotti_vehicle_effects computes with its effects off.
 *
 * Library effects, as in robotti_vehicle_effects:
 *   time_offset, speed_lag, steering_lag, steering_offset, wheel_slip,
 *   grade_x, grade_y, antenna_x, antenna_y
 *
 * Out-of-library effects:
 *   relaxation          tyre relaxation length sigma [m]: each axle's lateral force
 *                       follows its steady value with dF/dt = max(vx, v_min)/sigma * (F_ss - F)
 *   steer_gain_speed    k [s/m]: steering loses authority with speed, delta *= max(0, 1 - k vx)
 *   payload             mass [kg] added at payload_time [s] (the implement is lowered), with a
 *   payload_draft       draft force payload_draft * m * g against the motion from then on
 *   mast_roll           h * gamma [m]: the antenna mast rolls on a cross-slope, moving the antenna
 *   mast_roll_heading   left by mast_roll * sin(theta - mast_roll_heading)
 *   slip_pull           k: slip grows with the pull, slip = wheel_slip + k |F_drive| / (m g)
 *   steer_rate_limit    the steering turns at most this fast [rad/s]
 *   rolling_resistance  c_rr: soft soil resists a rolling wheel, a force c_rr * m * g against the
 *                       motion (m with the payload once lowered), smoothed through rest as the draft is
 *
 * Value references are the indices of enum Real; modelDescription.xml lists
 * the same variables in the same order.
 */
#include <math.h>
#include <stdlib.h>

#include "slave.h"

enum Real {
    /* vehicle parameters, as in robotti_vehicle */
    MASS, C_ALPHA_F, C_ALPHA_R, MU, LF, LR, R_GYR, KV, V_MIN, G,
    X0, Y0, THETA0, RK4_STEP,
    /* library effects, as in robotti_vehicle_effects */
    TIME_OFFSET, SPEED_LAG, STEERING_LAG, STEERING_OFFSET, WHEEL_SLIP,
    GRADE_X, GRADE_Y, ANTENNA_X, ANTENNA_Y,
    /* out-of-library effects */
    RELAXATION, STEER_GAIN_SPEED, PAYLOAD, PAYLOAD_TIME, PAYLOAD_DRAFT,
    MAST_ROLL, MAST_ROLL_HEADING, SLIP_PULL, STEER_RATE_LIMIT, ROLLING_RESISTANCE,
    /* inputs */
    VELOCITY, DELTA_F,
    /* outputs */
    X, Y, THETA, VX, VY, YAW_RATE, GPS_X, GPS_Y, DELTA_WHEELS, SLIP,
    N_REALS
};

static const double DEFAULTS[N_REALS] = {
    [MASS] = 1500.0, [C_ALPHA_F] = 30000.0, [C_ALPHA_R] = 30000.0, [MU] = 0.5,
    [LF] = 0.9, [LR] = 0.9, [R_GYR] = 0.9, [KV] = 8000.0, [V_MIN] = 0.5, [G] = 9.81,
    [X0] = 0.0, [Y0] = 0.0, [THETA0] = 0.0, [RK4_STEP] = 0.001,
    [PAYLOAD_TIME] = 10.0,
};

/* States: the rigid body's, then the actuators' and the tyres' (each used only when its effect is on). */
enum {
    S_X, S_Y, S_PSI, S_VX, S_VY, S_R,
    S_SPEED,      /* speed actuator output (speed_lag) */
    S_STEER,      /* steering actuator output (steering_lag) */
    S_STEER_RATE, /* rate-limited steering angle (steer_rate_limit) */
    S_FYF, S_FYR, /* lagging lateral tyre forces (relaxation) */
    N_STATES
};

/* The rate limiter tracks its input this fast when not at its limit: a lag far below what the GPS sees. */
#define RATE_LIMIT_TRACKING 0.01 /* s */

/* Every command received, so that a delayed one can be looked up (time_offset). */
typedef struct {
    double *time, *velocity, *delta_f;
    size_t n, capacity;
} Commands;

typedef struct {
    double z[N_STATES];
    Commands commands;
} State;

typedef struct {
    const double *p;
    const Commands *commands;
} Context;

/* What the wheels and the body feel at one instant, beside the state derivatives. */
typedef struct {
    double delta_wheels; /* steering angle at the wheels, positive = right [rad] */
    double slip;         /* longitudinal slip ratio in force */
} Contact;

static double clamp(double v, double lo, double hi) { return v < lo ? lo : v > hi ? hi : v; }

static void forget(Slave *s) {
    Commands *c = &((State *)s->state)->commands;
    free(c->time);
    free(c->velocity);
    free(c->delta_f);
    *c = (Commands){0};
}

static int grow(double **array, size_t capacity) {
    double *bigger = realloc(*array, capacity * sizeof(double));
    if (!bigger) return 1;
    *array = bigger;
    return 0;
}

static int record_command(Slave *s, double t, double velocity, double delta_f) {
    Commands *c = &((State *)s->state)->commands;
    if (c->n == c->capacity) {
        const size_t capacity = c->capacity ? 2 * c->capacity : 1024;
        if (grow(&c->time, capacity) || grow(&c->velocity, capacity) || grow(&c->delta_f, capacity)) {
            slave_log(s, fmi2Error, "logStatusError", "out of memory for the command log");
            return 1;
        }
        c->capacity = capacity;
    }
    c->time[c->n] = t;
    c->velocity[c->n] = velocity;
    c->delta_f[c->n] = delta_f;
    c->n++;
    return 0;
}

/* The last command received at or before t; at rest with straight wheels before the first. */
static void command_at(const Commands *c, double t, double *velocity, double *delta_f) {
    const double slack = 1e-9 * (1.0 + fabs(t));
    size_t lo = 0, hi = c->n; /* lo ends as the number of commands received at or before t */
    while (lo < hi) {
        const size_t mid = lo + (hi - lo) / 2;
        if (c->time[mid] <= t + slack) lo = mid + 1;
        else hi = mid;
    }
    const size_t n = lo;
    *velocity = n ? c->velocity[n - 1] : 0.0;
    *delta_f = n ? c->delta_f[n - 1] : 0.0;
}

/* A first-order lag with time constant tau >= 0 on signal u, its output held in state y. */
static double lag(double u, double tau, double y, double *dy) {
    *dy = tau > 0.0 ? (u - y) / tau : 0.0;
    return tau > 0.0 ? y : u;
}

/* Drive force for a slip ratio: the drive regulates wheel speed; the ground moves (1 - slip) as fast. */
static double drive_force(const double *p, double m, double speed, double vx, double slip) {
    const double limit = p[MU] * m * p[G];
    return clamp(p[KV] * (speed - vx / (1.0 - slip)), -limit, limit);
}

/* The slip ratio that the pull it causes is consistent with: slip = wheel_slip + slip_pull |F(slip)| / (m g).
 * The residual is <= 0 at wheel_slip and > 0 at 0.9 (|F| <= mu m g), so bisection finds a root. */
static double slip_of(const double *p, double m, double speed, double vx) {
    const double base = p[WHEEL_SLIP], k = p[SLIP_PULL];
    if (k <= 0.0) return base;
    double lo = base, hi = 0.9;
    for (int i = 0; i < 60 && hi - lo > 1e-15; i++) {
        const double mid = 0.5 * (lo + hi);
        const double residual = mid - base - k * fabs(drive_force(p, m, speed, vx, mid)) / (m * p[G]);
        if (residual > 0.0) hi = mid;
        else lo = mid;
    }
    return 0.5 * (lo + hi);
}

/* Lateral force of one axle, faded in at walking pace and saturated at mu * load. */
static double tyre_force(double stiffness, double slip_angle, double load, double mu, double fade) {
    return fade * clamp(stiffness * slip_angle, -mu * load, mu * load);
}

/* dz = f(t, z), and what the contact looks like at that instant. */
static Contact derivatives(const Context *ctx, double t, const double *z, double *dz) {
    const double *p = ctx->p;
    const double vx = z[S_VX], vy = z[S_VY], r = z[S_R], psi = z[S_PSI];

    /* Commands, through the actuators. */
    double speed, steer;
    command_at(ctx->commands, t - p[TIME_OFFSET], &speed, &steer);
    speed = lag(speed, p[SPEED_LAG], z[S_SPEED], &dz[S_SPEED]);
    steer = lag(steer, p[STEERING_LAG], z[S_STEER], &dz[S_STEER]);
    if (p[STEER_RATE_LIMIT] > 0.0) {
        const double limit = p[STEER_RATE_LIMIT];
        dz[S_STEER_RATE] = clamp((steer - z[S_STEER_RATE]) / RATE_LIMIT_TRACKING, -limit, limit);
        steer = z[S_STEER_RATE];
    } else {
        dz[S_STEER_RATE] = 0.0;
    }
    if (p[STEER_GAIN_SPEED] != 0.0) steer *= fmax(0.0, 1.0 - p[STEER_GAIN_SPEED] * vx);
    const double delta_wheels = steer + p[STEERING_OFFSET]; /* positive = right */

    /* Body: the implement, once lowered, is carried and drawn. */
    const int lowered = t >= p[PAYLOAD_TIME];
    const double m = p[MASS] + (lowered ? p[PAYLOAD] : 0.0), g = p[G];
    const double iz = m * p[R_GYR] * p[R_GYR];
    const double lf = p[LF], lr = p[LR], wheelbase = lf + lr;

    /* Longitudinal: drive, draft, rolling resistance, and gravity along the slope. */
    const double slip = slip_of(p, m, speed, vx);
    const double f_drive = drive_force(p, m, speed, vx, slip);
    const double against = -clamp(vx / p[V_MIN], -1.0, 1.0); /* against the motion, smoothed through rest */
    const double f_draft = lowered ? p[PAYLOAD_DRAFT] * m * g * against : 0.0;
    const double f_roll = p[ROLLING_RESISTANCE] * m * g * against;
    const double c = cos(psi), s = sin(psi);
    const double pull_east = -m * g * p[GRADE_X], pull_north = -m * g * p[GRADE_Y]; /* downhill */
    const double f_slope_x = pull_east * c + pull_north * s;
    const double f_slope_y = -pull_east * s + pull_north * c;

    /* Lateral: linear tyres on the slip angles, counter-clockwise steering angle a = -delta_wheels. */
    const double a = -delta_wheels;
    const double fade = fmin(1.0, fmax(vx, 0.0) / p[V_MIN]);
    const double v_ref = fmax(vx, p[V_MIN]);
    const double load_f = m * g * lr / wheelbase, load_r = m * g * lf / wheelbase;
    const double fyf_ss = tyre_force(p[C_ALPHA_F], a - atan((vy + lf * r) / v_ref), load_f, p[MU], fade);
    const double fyr_ss = tyre_force(p[C_ALPHA_R], -atan((vy - lr * r) / v_ref), load_r, p[MU], fade);
    double fyf = fyf_ss, fyr = fyr_ss;
    if (p[RELAXATION] > 0.0) {
        const double rate = v_ref / p[RELAXATION];
        dz[S_FYF] = rate * (fyf_ss - z[S_FYF]);
        dz[S_FYR] = rate * (fyr_ss - z[S_FYR]);
        fyf = z[S_FYF];
        fyr = z[S_FYR];
    } else {
        dz[S_FYF] = dz[S_FYR] = 0.0;
    }

    dz[S_X] = vx * c - vy * s;
    dz[S_Y] = vx * s + vy * c;
    dz[S_PSI] = r;
    dz[S_VX] = (f_drive + f_draft + f_roll - fyf * sin(a) + f_slope_x) / m + vy * r;
    dz[S_VY] = (fyf * cos(a) + fyr + f_slope_y) / m - vx * r;
    dz[S_R] = (lf * fyf * cos(a) - lr * fyr) / iz;
    return (Contact){delta_wheels, slip};
}

static void rhs(const Context *ctx, double t, const double *z, double *dz) {
    (void)derivatives(ctx, t, z, dz);
}

/* Classical RK4 from t to t + h, in equal whole steps of at most max_step. */
static void integrate(const Context *ctx, double *z, double t, double h, double max_step) {
    double k1[N_STATES], k2[N_STATES], k3[N_STATES], k4[N_STATES], tmp[N_STATES];
    const int steps = (int)ceil(h / max_step - 1e-9);
    const double dt = h / (steps > 0 ? steps : 1);
    for (int k = 0; k < steps; k++) {
        const double tk = t + k * dt;
        rhs(ctx, tk, z, k1);
        for (int i = 0; i < N_STATES; i++) tmp[i] = z[i] + 0.5 * dt * k1[i];
        rhs(ctx, tk + 0.5 * dt, tmp, k2);
        for (int i = 0; i < N_STATES; i++) tmp[i] = z[i] + 0.5 * dt * k2[i];
        rhs(ctx, tk + 0.5 * dt, tmp, k3);
        for (int i = 0; i < N_STATES; i++) tmp[i] = z[i] + dt * k3[i];
        rhs(ctx, tk + dt, tmp, k4);
        for (int i = 0; i < N_STATES; i++) z[i] += dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
    }
}

/* Outputs at time t: the pose, the antenna (on its rolling mast) and the contact. */
static void publish(Slave *s, double t) {
    double *p = s->r;
    const State *st = s->state;
    const double *z = st->z;
    double dz[N_STATES];
    const Context ctx = {p, &st->commands};
    const Contact contact = derivatives(&ctx, t, z, dz);
    const double c = cos(z[S_PSI]), sn = sin(z[S_PSI]);
    const double left = p[ANTENNA_Y] + p[MAST_ROLL] * sin(z[S_PSI] - p[MAST_ROLL_HEADING]);
    p[X] = z[S_X];
    p[Y] = z[S_Y];
    p[THETA] = z[S_PSI];
    p[VX] = z[S_VX];
    p[VY] = z[S_VY];
    p[YAW_RATE] = z[S_R];
    p[GPS_X] = z[S_X] + p[ANTENNA_X] * c - left * sn;
    p[GPS_Y] = z[S_Y] + p[ANTENNA_X] * sn + left * c;
    p[DELTA_WHEELS] = contact.delta_wheels;
    p[SLIP] = contact.slip;
}

/* At rest at the initial pose, wheels straight, no command received yet. */
static int start_at_rest(Slave *s) {
    State *st = s->state;
    for (int i = 0; i < N_STATES; i++) st->z[i] = 0.0;
    st->commands.n = 0;
    st->z[S_X] = s->r[X0];
    st->z[S_Y] = s->r[Y0];
    st->z[S_PSI] = s->r[THETA0];
    publish(s, 0.0);
    return 0;
}

static int check_parameters(Slave *s) {
    const double *p = s->r;
    const struct { const char *name; double value; double lo; int open; } ranges[] = {
        {"mass", p[MASS], 0.0, 1}, {"lf + lr", p[LF] + p[LR], 0.0, 1}, {"r_gyr", p[R_GYR], 0.0, 1},
        {"v_min", p[V_MIN], 0.0, 1}, {"rk4_step", p[RK4_STEP], 0.0, 1},
        {"time_offset", p[TIME_OFFSET], 0.0, 0}, {"speed_lag", p[SPEED_LAG], 0.0, 0},
        {"steering_lag", p[STEERING_LAG], 0.0, 0}, {"wheel_slip", p[WHEEL_SLIP], 0.0, 0},
        {"relaxation", p[RELAXATION], 0.0, 0}, {"payload", p[PAYLOAD], 0.0, 0},
        {"payload_draft", p[PAYLOAD_DRAFT], 0.0, 0}, {"slip_pull", p[SLIP_PULL], 0.0, 0},
        {"steer_rate_limit", p[STEER_RATE_LIMIT], 0.0, 0},
        {"rolling_resistance", p[ROLLING_RESISTANCE], 0.0, 0},
    };
    for (size_t i = 0; i < sizeof ranges / sizeof ranges[0]; i++) {
        const double v = ranges[i].value;
        if (!isfinite(v) || v < ranges[i].lo || (ranges[i].open && v == ranges[i].lo)) {
            slave_log(s, fmi2Error, "logStatusError", "parameter %s must be %s %g, got %g", ranges[i].name,
                      ranges[i].open ? ">" : ">=", ranges[i].lo, v);
            return 1;
        }
    }
    if (!(p[WHEEL_SLIP] < 0.9)) {
        slave_log(s, fmi2Error, "logStatusError", "parameter wheel_slip must be < 0.9, got %g", p[WHEEL_SLIP]);
        return 1;
    }
    return start_at_rest(s);
}

static int do_step(Slave *s, double t, double h) {
    State *st = s->state;
    if (record_command(s, t, s->r[VELOCITY], s->r[DELTA_F]) != 0) return 1;
    const Context ctx = {s->r, &st->commands};
    integrate(&ctx, st->z, t, h, s->r[RK4_STEP]);
    for (int i = 0; i < N_STATES; i++)
        if (!isfinite(st->z[i])) {
            slave_log(s, fmi2Error, "logStatusError",
                      "vehicle state diverged (non-finite) during the step from t=%.6g to t=%.6g; "
                      "try a smaller rk4_step", t, t + h);
            return 1;
        }
    publish(s, t + h);
    return 0;
}

const ModelInfo MODEL = {
    .guid = "{5d1c7e2b-8a4f-4c3e-9b6d-1f0a2e7c4b83}",
    .n_reals = N_REALS,
    .real_defaults = DEFAULTS,
    .n_strings = 0,
    .string_defaults = 0,
    .state_size = sizeof(State),
    .enter_initialization = start_at_rest,
    .exit_initialization = check_parameters,
    .do_step = do_step,
    .release = forget,
};
