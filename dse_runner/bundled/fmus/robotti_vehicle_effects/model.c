/*
 * robotti_vehicle_effects: the baseline Robotti vehicle (shared/robotti-model.md)
 * plus the effects discrepancy diagnosis can add to it, each off (zero) by
 * default, so that with every effect parameter at zero it computes exactly
 * what robotti_vehicle computes:
 *
 *   time_offset      the vehicle acts on each command this long after its log time [s]
 *   speed_lag        first-order lag of the speed actuator [s]
 *   steering_lag     first-order lag of the steering actuator [s]
 *   steering_offset  added to the steering angle, positive = right [rad]
 *   wheel_slip       longitudinal slip ratio on soil: ground speed = (1 - slip) * wheel speed
 *   grade_x, grade_y terrain rise per metre east and north; gravity pulls downhill
 *   antenna_x, _y    GPS antenna position forward and left of the reference point [m];
 *                    gps_x, gps_y are where the antenna is
 *
 * Value references are the indices of enum Real; modelDescription.xml lists
 * the same variables in the same order.
 */
#include <stdlib.h>

#include "bicycle.h"
#include "slave.h"

enum Real {
    /* baseline parameters, as in robotti_vehicle */
    MASS, C_ALPHA_F, C_ALPHA_R, MU, LF, LR, R_GYR, KV, V_MIN, G,
    X0, Y0, THETA0, RK4_STEP,
    /* effect parameters */
    TIME_OFFSET, SPEED_LAG, STEERING_LAG, STEERING_OFFSET, WHEEL_SLIP,
    GRADE_X, GRADE_Y, ANTENNA_X, ANTENNA_Y,
    /* inputs */
    VELOCITY, DELTA_F,
    /* outputs */
    X, Y, THETA, VX, VY, YAW_RATE, GPS_X, GPS_Y,
    N_REALS
};

static const double DEFAULTS[N_REALS] = {
    [MASS] = 1500.0, [C_ALPHA_F] = 30000.0, [C_ALPHA_R] = 30000.0, [MU] = 0.5,
    [LF] = 0.9, [LR] = 0.9, [R_GYR] = 0.9, [KV] = 8000.0, [V_MIN] = 0.5, [G] = 9.81,
    [X0] = 0.0, [Y0] = 0.0, [THETA0] = 0.0, [RK4_STEP] = 0.001,
};

/* States: the bicycle's, then the two actuators' (used only when their lag is > 0). */
enum { ACT_SPEED = BICYCLE_STATES, ACT_STEERING, N_STATES };

/* Every command received, so that a delayed one can be looked up. */
typedef struct {
    double *time, *velocity, *delta_f;
    size_t n, capacity;
} History;

typedef struct {
    double z[N_STATES];
    History history;
} State;

typedef struct {
    const double *p;
    Bicycle bicycle;
    Ground ground;
    const History *history;
} Step;

static void release(Slave *s) {
    State *st = s->state;
    free(st->history.time);
    free(st->history.velocity);
    free(st->history.delta_f);
    st->history = (History){0};
}

static int remember(Slave *s, double t, double velocity, double delta_f) {
    History *h = &((State *)s->state)->history;
    if (h->n == h->capacity) {
        size_t capacity = h->capacity ? 2 * h->capacity : 1024;
        double *time = realloc(h->time, capacity * sizeof(double));
        if (time) h->time = time;
        double *v = time ? realloc(h->velocity, capacity * sizeof(double)) : 0;
        if (v) h->velocity = v;
        double *d = v ? realloc(h->delta_f, capacity * sizeof(double)) : 0;
        if (!d) {
            slave_log(s, fmi2Error, "logStatusError", "out of memory for the command history");
            return 1;
        }
        h->delta_f = d;
        h->capacity = capacity;
    }
    h->time[h->n] = t;
    h->velocity[h->n] = velocity;
    h->delta_f[h->n] = delta_f;
    h->n++;
    return 0;
}

/* The command in force at time t (the last one received at or before t);
 * before the first command the vehicle is held at rest, wheels straight. */
static void command_at(const History *h, double t, double *velocity, double *delta_f) {
    const double tolerance = 1e-9 * (1.0 + fabs(t));
    size_t lo = 0, hi = h->n; /* first index with time > t is in [lo, hi] */
    while (lo < hi) {
        size_t mid = (lo + hi) / 2;
        if (h->time[mid] <= t + tolerance) lo = mid + 1;
        else hi = mid;
    }
    if (lo == 0) {
        *velocity = 0.0;
        *delta_f = 0.0;
        return;
    }
    *velocity = h->velocity[lo - 1];
    *delta_f = h->delta_f[lo - 1];
}

/* First-order actuator: its state when lagging, the command itself otherwise. */
static double actuator(double command, double lag, double state, double *d_state) {
    if (lag > 0.0) {
        *d_state = (command - state) / lag;
        return state;
    }
    *d_state = 0.0;
    return command;
}

static void rhs(const void *ctx, double t, const double *z, double *dz) {
    const Step *step = ctx;
    const double *p = step->p;
    double velocity, delta_f;
    command_at(step->history, t - p[TIME_OFFSET], &velocity, &delta_f);
    velocity = actuator(velocity, p[SPEED_LAG], z[ACT_SPEED], &dz[ACT_SPEED]);
    delta_f = actuator(delta_f, p[STEERING_LAG], z[ACT_STEERING], &dz[ACT_STEERING]);
    bicycle_derivatives(&step->bicycle, &step->ground, z, velocity, delta_f + p[STEERING_OFFSET], dz);
}

static void publish(Slave *s, const double *z) {
    double *p = s->r;
    const double c = cos(z[B_PSI]), sn = sin(z[B_PSI]);
    bicycle_publish(&p[X], z); /* X, Y, THETA, VX, VY, YAW_RATE are consecutive */
    p[GPS_X] = z[B_X] + p[ANTENNA_X] * c - p[ANTENNA_Y] * sn;
    p[GPS_Y] = z[B_Y] + p[ANTENNA_X] * sn + p[ANTENNA_Y] * c;
}

/* The initial pose comes from parameters; the vehicle starts at rest. */
static int start_at_rest(Slave *s) {
    State *st = s->state;
    for (int i = 0; i < N_STATES; i++) st->z[i] = 0.0;
    st->history.n = 0;
    st->z[B_X] = s->r[X0];
    st->z[B_Y] = s->r[Y0];
    st->z[B_PSI] = s->r[THETA0];
    publish(s, st->z);
    return 0;
}

static int check_parameters(Slave *s) {
    const double *p = s->r;
    const struct { const char *name; double value; double lo; int lo_open; } ranges[] = {
        {"mass", p[MASS], 0.0, 1}, {"lf + lr", p[LF] + p[LR], 0.0, 1}, {"r_gyr", p[R_GYR], 0.0, 1},
        {"v_min", p[V_MIN], 0.0, 1}, {"rk4_step", p[RK4_STEP], 0.0, 1},
        {"time_offset", p[TIME_OFFSET], 0.0, 0}, {"speed_lag", p[SPEED_LAG], 0.0, 0},
        {"steering_lag", p[STEERING_LAG], 0.0, 0}, {"wheel_slip", p[WHEEL_SLIP], 0.0, 0},
    };
    for (size_t i = 0; i < sizeof ranges / sizeof ranges[0]; i++) {
        const double v = ranges[i].value;
        if (!isfinite(v) || v < ranges[i].lo || (ranges[i].lo_open && v == ranges[i].lo)) {
            slave_log(s, fmi2Error, "logStatusError", "parameter %s must be %s %g, got %g", ranges[i].name,
                      ranges[i].lo_open ? ">" : ">=", ranges[i].lo, v);
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
    const double *p = s->r;
    State *st = s->state;
    if (remember(s, t, p[VELOCITY], p[DELTA_F]) != 0) return 1;
    const Step step = {
        p, {p[MASS], p[C_ALPHA_F], p[C_ALPHA_R], p[MU], p[LF], p[LR], p[R_GYR], p[KV], p[V_MIN], p[G]},
        {p[WHEEL_SLIP], p[GRADE_X], p[GRADE_Y]}, &st->history,
    };
    rk4_advance(rhs, &step, N_STATES, st->z, t, h, p[RK4_STEP]);
    if (check_finite(s, st->z, N_STATES, t, h) != 0) return 1;
    publish(s, st->z);
    return 0;
}

const ModelInfo MODEL = {
    .guid = "{0e6b5f4a-93c2-4d7e-b1a8-6c2f7d9e3b54}",
    .n_reals = N_REALS,
    .real_defaults = DEFAULTS,
    .n_strings = 0,
    .string_defaults = 0,
    .state_size = sizeof(State),
    .enter_initialization = start_at_rest,
    .exit_initialization = check_parameters,
    .do_step = do_step,
    .release = release,
};
