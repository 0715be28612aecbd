/*
 * robotti_vehicle_effects: the baseline Robotti vehicle (docs/robotti-model.md)
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
 * and the correction block (corr_*, after gps_y): a sparse data-driven correction
 * whose coefficients are parameters, each term adding coefficient x feature to a
 * channel (docs/research/diagnosis-beyond-library.md section 4.3). With every
 * coefficient zero the block is skipped, so the model is exactly the one above.
 *
 * Value references are the indices of enum Real; modelDescription.xml lists
 * the same variables in the same order.
 */
#include <stdint.h>
#include <stdlib.h>

#include "bicycle.h"
#include "slave.h"

/*
 * The correction block's terms, corr_<channel>_<feature>, in the order of
 * dse_runner/cases/robotti_diagnosis/correction.py's TERMS (a test checks the names,
 * their order and the value references against it and modelDescription.xml).
 * dynamic_features() and gps_features() below evaluate the features with correction.py's definitions:
 *   v = vx, psi = heading, r = yaw rate, s = distance travelled (a state, ds/dt = |v|);
 *   v_cmd, delta = the speed set-point and steering angle as acted on (after time_offset
 *   and the actuator lags, before steering_offset); a_cmd, ddelta their derivatives
 *   through a first-order filter of time constant TAU_F (one state each);
 *   fdrive = the drive force over the mass, as bicycle.h computes it;
 *   sgnv = clamp(v / v_min, -1, 1), the direction of motion smoothed through rest (a force
 *   against the motion, like rolling resistance, is a negative coefficient);
 *   onset_* = the feature after it times [t >= corr_onset_time]: a change from one moment of
 *   the run on (an implement lowered, a tank filled);
 *   ratelim = lim(delta, L) - delta: the steering through a rate limit of L = corr_rate_limit
 *   rad/s (a state that follows delta within TAU_TRACK and turns at most L fast), less delta.
 *   corr_onset_time and corr_rate_limit shape features and are not coefficients; they follow
 *   the coefficients.
 *   channel    adds to
 *   acc        d(vx)/dt [m/s^2]
 *   steer      the steering angle after the actuators, positive = right [rad]
 *   yaw        d(r)/dt [rad/s^2]
 *   gps_along  the antenna's position forward of the reference point [m] (like antenna_x)
 *   gps_cross  the antenna's position left of it [m] (like antenna_y)
 */
#define CORR_TERMS(X) \
    X(ACC_1, "corr_acc_1") X(ACC_V, "corr_acc_v") X(ACC_V2, "corr_acc_v2") X(ACC_VERR, "corr_acc_verr") \
    X(ACC_ACMD, "corr_acc_acmd") X(ACC_COSPSI, "corr_acc_cospsi") X(ACC_SINPSI, "corr_acc_sinpsi") \
    X(ACC_S, "corr_acc_s") X(ACC_ABSVR, "corr_acc_absvr") X(ACC_FDRIVE, "corr_acc_fdrive") \
    X(ACC_SGNV, "corr_acc_sgnv") X(ACC_ONSET_SGNV, "corr_acc_onset_sgnv") X(ACC_ONSET_FDRIVE, "corr_acc_onset_fdrive") \
    X(STEER_1, "corr_steer_1") X(STEER_DELTA, "corr_steer_delta") X(STEER_DDELTA, "corr_steer_ddelta") \
    X(STEER_DDELTAV, "corr_steer_ddeltav") X(STEER_VDELTA, "corr_steer_vdelta") X(STEER_V, "corr_steer_v") \
    X(STEER_R, "corr_steer_r") X(STEER_RATELIM, "corr_steer_ratelim") \
    X(YAW_1, "corr_yaw_1") X(YAW_DELTA, "corr_yaw_delta") X(YAW_VDELTA, "corr_yaw_vdelta") X(YAW_R, "corr_yaw_r") \
    X(YAW_VR, "corr_yaw_vr") \
    X(ALONG_1, "corr_gps_along_1") X(ALONG_COSPSI, "corr_gps_along_cospsi") \
    X(ALONG_SINPSI, "corr_gps_along_sinpsi") X(ALONG_COS2PSI, "corr_gps_along_cos2psi") \
    X(ALONG_SIN2PSI, "corr_gps_along_sin2psi") X(ALONG_V, "corr_gps_along_v") \
    X(CROSS_1, "corr_gps_cross_1") X(CROSS_COSPSI, "corr_gps_cross_cospsi") \
    X(CROSS_SINPSI, "corr_gps_cross_sinpsi") X(CROSS_COS2PSI, "corr_gps_cross_cos2psi") \
    X(CROSS_SIN2PSI, "corr_gps_cross_sin2psi") X(CROSS_V, "corr_gps_cross_v")

#define CORR_INDEX(id, name) id,
enum CorrTerm { CORR_TERMS(CORR_INDEX) N_CORR };
#define CORR_NAME(id, name) name,
static const char *const CORR_NAMES[N_CORR] = {CORR_TERMS(CORR_NAME)};

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
    /* correction coefficients: CORR + the index in CORR_TERMS */
    CORR,
    /* the time from which the onset_* features are on [s], the ratelim feature's rate limit [rad/s] */
    CORR_ONSET_TIME = CORR + N_CORR, CORR_RATE_LIMIT,
    N_REALS
};

/* Each channel's terms are consecutive in CORR_TERMS. */
enum Channel { C_ACC, C_STEER, C_YAW, C_ALONG, C_CROSS, N_CHANNELS };
static const int CHANNEL_FIRST[N_CHANNELS + 1] = {ACC_1, STEER_1, YAW_1, ALONG_1, CROSS_1, N_CORR};

static const double TAU_F = 0.1; /* s: the filtered derivatives' time constant (correction.TAU_F) */
static const double TAU_TRACK = 0.01; /* s: how fast the rate limiter follows below its limit (correction.TAU_TRACK) */

static const double DEFAULTS[N_REALS] = {
    [MASS] = 1500.0, [C_ALPHA_F] = 30000.0, [C_ALPHA_R] = 30000.0, [MU] = 0.5,
    [LF] = 0.9, [LR] = 0.9, [R_GYR] = 0.9, [KV] = 8000.0, [V_MIN] = 0.5, [G] = 9.81,
    [X0] = 0.0, [Y0] = 0.0, [THETA0] = 0.0, [RK4_STEP] = 0.001, [CORR_RATE_LIMIT] = 1.0,
};

/* States: the bicycle's, then the two actuators' (used only when their lag is > 0), then the
 * correction block's (integrated only when a coefficient is nonzero): the filters of the speed
 * set-point and of the steering angle, the distance travelled and the rate-limited steering. */
enum { ACT_SPEED = BICYCLE_STATES, ACT_STEERING, F_SPEED, F_STEERING, DISTANCE, RATE_LIMITED, N_STATES };
_Static_assert((int)N_STATES <= (int)RK4_MAX_STATES, "too many states for rk4_advance");

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
    int active[N_CHANNELS]; /* a channel with a nonzero coefficient */
    int any;                /* any channel active: the block runs */
    SteeringTrig trig;
    size_t next_command; /* command_at's place in the history */
} Step;

/* Which channels have a nonzero coefficient; returns whether any has. */
static int active_channels(const double *p, int *active) {
    int any = 0;
    for (int c = 0; c < N_CHANNELS; c++) {
        active[c] = 0;
        for (int k = CHANNEL_FIRST[c]; k < CHANNEL_FIRST[c + 1]; k++)
            if (p[CORR + k] != 0.0) active[c] = 1;
        any |= active[c];
    }
    return any;
}

/* sum of coefficient x feature over one channel's terms (zero coefficients skipped). */
static double channel_sum(const double *p, int channel, const double *f) {
    double sum = 0.0;
    for (int k = CHANNEL_FIRST[channel]; k < CHANNEL_FIRST[channel + 1]; k++)
        if (p[CORR + k] != 0.0) sum += p[CORR + k] * f[k];
    return sum;
}

/* The drive force over the mass, exactly as bicycle_derivatives computes it. */
static double drive_per_mass(const Bicycle *b, const Ground *ground, double vx, double velocity) {
    const double wheel_speed = vx / (1.0 - ground->slip);
    return bicycle_clamp(b->kv * (velocity - wheel_speed), -b->mu * b->m * b->g, b->mu * b->m * b->g) / b->m;
}

/* Every feature of the dynamic channels (acc, steer, yaw) at state z, commands as acted on. */
static void dynamic_features(const Step *step, double t, const double *z, double velocity, double delta_f,
                             double *f) {
    const double v = z[B_VX], r = z[B_R], psi = z[B_PSI];
    const double after = t >= step->p[CORR_ONSET_TIME] ? 1.0 : 0.0;
    const double a_cmd = (velocity - z[F_SPEED]) / TAU_F, ddelta = (delta_f - z[F_STEERING]) / TAU_F;
    f[ACC_1] = 1.0;
    f[ACC_V] = v;
    f[ACC_V2] = v * v;
    f[ACC_VERR] = velocity - v;
    f[ACC_ACMD] = a_cmd;
    f[ACC_COSPSI] = cos(psi);
    f[ACC_SINPSI] = sin(psi);
    f[ACC_S] = z[DISTANCE];
    f[ACC_ABSVR] = fabs(v * r);
    f[ACC_FDRIVE] = step->active[C_ACC] ? drive_per_mass(&step->bicycle, &step->ground, v, velocity) : 0.0;
    f[ACC_SGNV] = bicycle_clamp(v / step->p[V_MIN], -1.0, 1.0);
    f[ACC_ONSET_SGNV] = after * f[ACC_SGNV];
    f[ACC_ONSET_FDRIVE] = after * f[ACC_FDRIVE];
    f[STEER_1] = 1.0;
    f[STEER_DELTA] = delta_f;
    f[STEER_DDELTA] = ddelta;
    f[STEER_DDELTAV] = ddelta / fmax(v, step->p[V_MIN]);
    f[STEER_VDELTA] = v * delta_f;
    f[STEER_V] = v;
    f[STEER_R] = r;
    f[STEER_RATELIM] = z[RATE_LIMITED] - delta_f;
    f[YAW_1] = 1.0;
    f[YAW_DELTA] = delta_f;
    f[YAW_VDELTA] = v * delta_f;
    f[YAW_R] = r;
    f[YAW_VR] = v * r;
}

/* The features of the antenna channels, which act on the output only. */
static void gps_features(const double *z, double *f) {
    const double psi = z[B_PSI], v = z[B_VX];
    const double values[] = {1.0, cos(psi), sin(psi), cos(2.0 * psi), sin(2.0 * psi), v};
    for (int k = 0; k < ALONG_V - ALONG_1 + 1; k++) f[ALONG_1 + k] = f[CROSS_1 + k] = values[k];
}

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
 * before the first command the vehicle is held at rest, wheels straight.
 * *next is the index after the command found last time: the RK4 stages of a
 * step ask for times that do not decrease, so the search steps on from there;
 * SIZE_MAX (nothing found yet), or an earlier time, searches the whole history. */
static void command_at(const History *h, double t, size_t *next, double *velocity, double *delta_f) {
    const double tolerance = 1e-9 * (1.0 + fabs(t));
    size_t lo = *next; /* first index with time > t, once the loops below end */
    if (lo > h->n || (lo > 0 && !(h->time[lo - 1] <= t + tolerance))) {
        size_t hi = h->n;
        lo = 0;
        while (lo < hi) {
            size_t mid = (lo + hi) / 2;
            if (h->time[mid] <= t + tolerance) lo = mid + 1;
            else hi = mid;
        }
    }
    while (lo < h->n && h->time[lo] <= t + tolerance) lo++;
    *next = lo;
    if (lo == 0) {
        *velocity = 0.0;
        *delta_f = 0.0;
        return;
    }
    *velocity = h->velocity[lo - 1];
    *delta_f = h->delta_f[lo - 1];
}

/* First-order actuator: its state when lagging, the command itself otherwise
 * (the state is then not read: it is not integrated, moving_states). */
static double actuator(double command, double lag, const double *state, double *d_state) {
    if (lag > 0.0) {
        *d_state = (command - *state) / lag;
        return *state;
    }
    *d_state = 0.0;
    return command;
}

static void rhs(void *ctx, double t, const double *z, double *dz) {
    Step *step = ctx;
    const double *p = step->p;
    double velocity, delta_f;
    command_at(step->history, t - p[TIME_OFFSET], &step->next_command, &velocity, &delta_f);
    velocity = actuator(velocity, p[SPEED_LAG], &z[ACT_SPEED], &dz[ACT_SPEED]);
    delta_f = actuator(delta_f, p[STEERING_LAG], &z[ACT_STEERING], &dz[ACT_STEERING]);
    if (!step->any) {
        dz[F_SPEED] = dz[F_STEERING] = dz[DISTANCE] = dz[RATE_LIMITED] = 0.0;
        const double steering = delta_f + p[STEERING_OFFSET];
        bicycle_derivatives(&step->bicycle, &step->ground, &step->trig, z, velocity, steering, dz);
        return;
    }
    double f[N_CORR];
    dynamic_features(step, t, z, velocity, delta_f, f);
    dz[F_SPEED] = f[ACC_ACMD];
    dz[F_STEERING] = f[STEER_DDELTA];
    dz[DISTANCE] = fabs(z[B_VX]);
    dz[RATE_LIMITED] = bicycle_clamp((delta_f - z[RATE_LIMITED]) / TAU_TRACK, -p[CORR_RATE_LIMIT], p[CORR_RATE_LIMIT]);
    double steering = delta_f + p[STEERING_OFFSET];
    if (step->active[C_STEER]) steering += channel_sum(p, C_STEER, f);
    bicycle_derivatives(&step->bicycle, &step->ground, &step->trig, z, velocity, steering, dz);
    if (step->active[C_ACC]) dz[B_VX] += channel_sum(p, C_ACC, f);
    if (step->active[C_YAW]) dz[B_R] += channel_sum(p, C_YAW, f);
}

static void publish(Slave *s, const double *z) {
    double *p = s->r;
    const double c = cos(z[B_PSI]), sn = sin(z[B_PSI]);
    bicycle_publish(&p[X], z); /* X, Y, THETA, VX, VY, YAW_RATE are consecutive */
    double along = p[ANTENNA_X], cross = p[ANTENNA_Y];
    int active[N_CHANNELS];
    if (active_channels(p, active) && (active[C_ALONG] || active[C_CROSS])) {
        double f[N_CORR];
        gps_features(z, f);
        if (active[C_ALONG]) along += channel_sum(p, C_ALONG, f);
        if (active[C_CROSS]) cross += channel_sum(p, C_CROSS, f);
    }
    p[GPS_X] = z[B_X] + along * c - cross * sn;
    p[GPS_Y] = z[B_Y] + along * sn + cross * c;
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
    for (int k = 0; k < N_CORR; k++)
        if (!isfinite(p[CORR + k])) {
            slave_log(s, fmi2Error, "logStatusError", "parameter %s must be finite, got %g", CORR_NAMES[k],
                      p[CORR + k]);
            return 1;
        }
    if (isnan(p[CORR_ONSET_TIME])) {
        slave_log(s, fmi2Error, "logStatusError", "parameter corr_onset_time must be a number, got nan");
        return 1;
    }
    if (!(p[CORR_RATE_LIMIT] > 0.0 && isfinite(p[CORR_RATE_LIMIT]))) {
        slave_log(s, fmi2Error, "logStatusError", "parameter corr_rate_limit must be > 0, got %g", p[CORR_RATE_LIMIT]);
        return 1;
    }
    return start_at_rest(s);
}

/* How many states (in enum order) move: the bicycle's; the actuators' when one lags; all when the
 * correction block runs. The others keep their values (zero derivatives), so they are left out of RK4. */
static int moving_states(const double *p, int any) {
    if (any) return N_STATES;
    return p[SPEED_LAG] > 0.0 || p[STEERING_LAG] > 0.0 ? ACT_STEERING + 1 : BICYCLE_STATES;
}

static int do_step(Slave *s, double t, double h) {
    const double *p = s->r;
    State *st = s->state;
    if (remember(s, t, p[VELOCITY], p[DELTA_F]) != 0) return 1;
    Step step = {
        p, {p[MASS], p[C_ALPHA_F], p[C_ALPHA_R], p[MU], p[LF], p[LR], p[R_GYR], p[KV], p[V_MIN], p[G]},
        {p[WHEEL_SLIP], p[GRADE_X], p[GRADE_Y]}, &st->history, {0}, 0, {0}, SIZE_MAX,
    };
    step.any = active_channels(p, step.active);
    rk4_advance(rhs, &step, moving_states(p, step.any), st->z, t, h, p[RK4_STEP]);
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
