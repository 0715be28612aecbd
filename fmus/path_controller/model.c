/*
 * path_controller: a closed-loop path-following controller for the Robotti.
 *
 * It reads a path (a CSV of waypoints x,y,speed; the path is the polyline
 * through them) and, from the vehicle pose x, y, theta, commands a ground
 * speed and a front steering angle (positive = right turn, as the vehicle
 * expects; docs/robotti-model.md).
 *
 * Steering is an active-disturbance-rejection controller (ADRC) on the
 * look-ahead cross-track error e, the lateral offset of a point `lookahead`
 * metres ahead of the vehicle from the path point as far ahead along the
 * path.  For a kinematic bicycle, e'' = b0 u + f with u the counter-clockwise
 * steering angle and b0 = v^2 / L; a linear extended-state observer estimates
 * e, e' and the total disturbance f (everything the nominal model leaves
 * out: path curvature, tyre slip, a wrong b0), and the control
 * b0 u = wc^2 (0 - e) - 2 wc e' - f cancels f.  One refinement of the textbook
 * law: a point ahead of the rear axle moves sideways as soon as the wheels
 * turn (e' = x2 + c u), and that known term is kept out of f (see observe).
 * On a straight row the closed loop is then, with r = c / b0 = (L/2 +
 * lookahead) / v,
 *     (1 + 2 r wc) s^2 + (2 wc + r wc^2) s + wc^2 = 0,
 * well damped (zeta >= sqrt(3)/2) for every r; r -> 0 gives the double pole at
 * -wc.  Optional course-error feedback (k_heading) adds damping.  The command
 * is saturated in angle and in rate, as a real steering actuator is.
 *
 * Speed is a PI loop on the speed estimated from successive poses, around
 * the path's target speed as feed-forward; past the path's end the vehicle
 * is stopped.
 *
 * The outputs computed in fmi2DoStep(t, h) from the pose at t are those the
 * vehicle receives from t + h on: the observer is propagated to t + h with
 * the steering applied over [t, t + h], so the control uses the estimate for
 * the time it takes effect.
 */
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "file_parameter.h"
#include "slave.h"

enum Real {
    /* parameters */
    OMEGA_O, OMEGA_C, LOOKAHEAD, B0_SCALE, K_HEADING, MAX_STEER_RATE, MAX_STEER, WHEELBASE, V_FLOOR,
    KP_V, KI_V, V_MAX, TAU_V,
    /* inputs */
    X, Y, THETA,
    /* outputs */
    VELOCITY, DELTA_F, CROSS_TRACK, HEADING_ERROR, STEERING_RATE, PROGRESS, SPEED_ESTIMATE,
    TARGET_SPEED, LOOKAHEAD_ERROR,
    N_REALS
};
enum String { FILE_PATH, N_STRINGS };

/* Defaults track a straight row at 0.5-3 m/s: at 1-3 m/s a 1 m offset is under
 * 5% after 10 s and under 1% after 15 s, overshooting by under 1%.  k_heading is off: on a row the
 * ADRC's own damping suffices and more only slows the approach.  The steering
 * limits are above what the recorded runs reached (0.32 rad, 0.15 rad/s) so
 * that they bound, not shape, normal use. */
static const double DEFAULTS[N_REALS] = {
    [OMEGA_O] = 3.0, [OMEGA_C] = 0.6, [LOOKAHEAD] = 0.5, [B0_SCALE] = 1.0, [K_HEADING] = 0.0,
    [MAX_STEER_RATE] = 0.3, [MAX_STEER] = 0.35, [WHEELBASE] = 1.8, [V_FLOOR] = 0.5,
    [KP_V] = 0.5, [KI_V] = 0.5, [V_MAX] = 3.0, [TAU_V] = 0.1,
};
static const char *const STRING_DEFAULTS[N_STRINGS] = {""};

enum Column { COL_X, COL_Y, COL_SPEED, N_COLUMNS };
static const char *const COLUMN_NAMES[N_COLUMNS] = {"x", "y", "speed"};

/* The closest point is searched on the segments that start at most this far
 * (arc length) ahead of the last one: far more than a vehicle covers in one
 * step, far less than the arc of a U-turn to the next row, so a path that folds
 * back on itself never makes the closest point jump to the other branch. */
#define SEARCH_AHEAD 5.0
/* An Euler sub-step of the observer is at most this fraction of its time
 * constant 1/omega_o: explicit Euler of a pole at -omega_o is stable below 2
 * and accurate well below 1, whatever the communication step. */
#define OBSERVER_STEP 0.2

typedef struct {
    double x, y, speed, s; /* waypoint, its target speed and its arc length from the start */
} Waypoint;

typedef struct {
    Waypoint *path;
    size_t n;            /* waypoints; segments are n - 1 */
    size_t cursor;       /* the segment of the last closest point */
    double progress;     /* the last closest point's arc length */
    double z[3];         /* observer: e, x2 (e' less the steering's immediate part), f */
    double integral;     /* speed PI's integral term [m/s] */
    double last_x, last_y, last_t; /* the previous pose and its time, for the speed estimate */
    double speed;        /* filtered speed estimate [m/s] */
    int finished;        /* past the path's end: stopped for good */
} State;

/* Where the vehicle is relative to the path. */
typedef struct {
    size_t segment;
    double progress;      /* arc length of the closest point */
    double cross_track;   /* reference point's lateral offset, positive = left of the path */
    double heading_error; /* theta minus the path's heading, in [-pi, pi) */
    double lookahead_error;
    int past_end;         /* the vehicle is beyond the last waypoint along the last segment */
} Fix;

static void release(Slave *s) {
    State *st = s->state;
    free(st->path);
    memset(st, 0, sizeof *st);
}

/* ---- reading the path ------------------------------------------------- */

static void strip_newline(char *line) { line[strcspn(line, "\r\n")] = '\0'; }

static char *trim(char *field) {
    while (*field == ' ' || *field == '\t') field++;
    char *end = field + strlen(field);
    while (end > field && (end[-1] == ' ' || end[-1] == '\t')) *--end = '\0';
    return field;
}

/* Maps column names to positions; returns the number of header fields, or -1 after reporting. */
static int parse_header(Slave *s, const char *path, char *line, int position[N_COLUMNS]) {
    for (int c = 0; c < N_COLUMNS; c++) position[c] = -1;
    strip_newline(line);
    int count = 0;
    /* Split by hand: strtok would merge the empty field of ",," and shift the columns. */
    for (char *field = line, *next; field; field = next, count++) {
        char *comma = strchr(field, ',');
        next = comma ? comma + 1 : NULL;
        if (comma) *comma = '\0';
        field = trim(field);
        for (int c = 0; c < N_COLUMNS; c++)
            if (strcmp(field, COLUMN_NAMES[c]) == 0) {
                if (position[c] >= 0) {
                    slave_log(s, fmi2Error, "logStatusError", "%s line 1: column '%s' appears twice",
                              path, COLUMN_NAMES[c]);
                    return -1;
                }
                position[c] = count;
            }
    }
    for (int c = 0; c < N_COLUMNS; c++)
        if (position[c] < 0) {
            slave_log(s, fmi2Error, "logStatusError",
                      "%s line 1: header has no '%s' column (expected x,y,speed)", path, COLUMN_NAMES[c]);
            return -1;
        }
    return count;
}

/* Parses one row of n_fields numbers into w; returns 0 or reports and returns 1. */
static int parse_row(Slave *s, const char *path, size_t line_no, char *line, int n_fields,
                     const int position[N_COLUMNS], Waypoint *w) {
    strip_newline(line);
    double values[N_COLUMNS] = {0};
    int index = 0;
    for (char *cursor = line;; index++) {
        char *end;
        errno = 0;
        const double value = strtod(cursor, &end);
        while (*end == ' ' || *end == '\t') end++;
        if (end == cursor || (*end != ',' && *end != '\0') || errno == ERANGE || !isfinite(value)) {
            slave_log(s, fmi2Error, "logStatusError", "%s line %zu: field %d is not a number: '%s'", path,
                      line_no, index + 1, line);
            return 1;
        }
        for (int c = 0; c < N_COLUMNS; c++)
            if (position[c] == index) values[c] = value;
        if (*end == '\0') break;
        cursor = end + 1;
    }
    if (index + 1 != n_fields) {
        slave_log(s, fmi2Error, "logStatusError", "%s line %zu: expected %d fields, got %d: '%s'", path,
                  line_no, n_fields, index + 1, line);
        return 1;
    }
    if (values[COL_SPEED] < 0.0) {
        slave_log(s, fmi2Error, "logStatusError", "%s line %zu: speed %g is negative", path, line_no,
                  values[COL_SPEED]);
        return 1;
    }
    *w = (Waypoint){values[COL_X], values[COL_Y], values[COL_SPEED], 0.0};
    return 0;
}

/* Appends a waypoint, growing the array; returns 0, or 1 when out of memory. */
static int append(State *st, size_t *capacity, Waypoint w) {
    if (st->n == *capacity) {
        const size_t grown = *capacity ? 2 * *capacity : 256;
        Waypoint *more = realloc(st->path, grown * sizeof *more);
        if (!more) return 1;
        st->path = more;
        *capacity = grown;
    }
    st->path[st->n++] = w;
    return 0;
}

/* Reads the rows after the header; returns 0 or reports and returns 1. */
static int read_rows(Slave *s, const char *path, FILE *f, int n_fields, const int position[N_COLUMNS]) {
    State *st = s->state;
    char line[4096];
    size_t capacity = 0, line_no = 1, previous_line = 0;
    while (fgets(line, sizeof line, f)) {
        line_no++;
        if (!strchr(line, '\n') && !feof(f)) {
            slave_log(s, fmi2Error, "logStatusError", "%s line %zu: longer than %zu characters", path,
                      line_no, sizeof line - 2);
            return 1;
        }
        if (line[strspn(line, " \t\r\n")] == '\0') continue; /* blank line */
        Waypoint w;
        if (parse_row(s, path, line_no, line, n_fields, position, &w) != 0) return 1;
        if (st->n > 0) {
            const Waypoint *p = &st->path[st->n - 1];
            const double length = hypot(w.x - p->x, w.y - p->y);
            if (!(length > 0.0)) {
                slave_log(s, fmi2Error, "logStatusError",
                          "%s line %zu: waypoint (%g, %g) equals the previous one (line %zu)", path,
                          line_no, w.x, w.y, previous_line);
                return 1;
            }
            w.s = p->s + length;
        }
        if (append(st, &capacity, w) != 0) {
            slave_log(s, fmi2Error, "logStatusError", "%s line %zu: out of memory", path, line_no);
            return 1;
        }
        previous_line = line_no;
    }
    if (st->n < 2) {
        slave_log(s, fmi2Error, "logStatusError",
                  "%s line %zu: the path needs at least 2 waypoints, the file has %zu", path, line_no, st->n);
        return 1;
    }
    return 0;
}

static int load_path(Slave *s) {
    const char *path = s->str[FILE_PATH];
    release(s);
    FILE *f = open_file_parameter(s, path, "the path CSV x,y,speed");
    if (!f) return 1;
    char header[4096];
    int position[N_COLUMNS], failed;
    if (!fgets(header, sizeof header, f)) {
        slave_log(s, fmi2Error, "logStatusError", "%s line 1: the file is empty", path);
        failed = 1;
    } else {
        const int n_fields = parse_header(s, path, header, position);
        failed = n_fields < 0 || read_rows(s, path, f, n_fields, position) != 0;
    }
    fclose(f);
    if (failed) release(s);
    return failed;
}

/* ---- parameters ------------------------------------------------------- */

static int check_parameters(Slave *s) {
    const double *p = s->r;
    const struct { const char *name; double value; int zero_ok; } limits[] = {
        {"omega_o", p[OMEGA_O], 0}, {"omega_c", p[OMEGA_C], 0}, {"lookahead", p[LOOKAHEAD], 1},
        {"b0_scale", p[B0_SCALE], 0}, {"k_heading", p[K_HEADING], 1},
        {"max_steer_rate", p[MAX_STEER_RATE], 0}, {"max_steer", p[MAX_STEER], 0},
        {"wheelbase", p[WHEELBASE], 0}, {"v_floor", p[V_FLOOR], 0}, {"kp_v", p[KP_V], 1},
        {"ki_v", p[KI_V], 1}, {"v_max", p[V_MAX], 0}, {"tau_v", p[TAU_V], 1},
    };
    for (size_t i = 0; i < sizeof limits / sizeof limits[0]; i++) {
        const double v = limits[i].value;
        if (!isfinite(v) || v < 0.0 || (v == 0.0 && !limits[i].zero_ok)) {
            slave_log(s, fmi2Error, "logStatusError", "parameter %s must be %s, got %g", limits[i].name,
                      limits[i].zero_ok ? ">= 0" : "> 0", v);
            return 1;
        }
    }
    return 0;
}

/* ---- geometry --------------------------------------------------------- */

#define PI 3.14159265358979323846 /* M_PI is not in strict C11 */

static double wrap_angle(double a) { return a - 2.0 * PI * floor((a + PI) / (2.0 * PI)); }

static double segment_length(const State *st, size_t i) { return st->path[i + 1].s - st->path[i].s; }

/* Fraction along segment i of the projection of (x, y), not clamped. */
static double projection(const State *st, size_t i, double x, double y) {
    const Waypoint *a = &st->path[i], *b = &st->path[i + 1];
    const double dx = b->x - a->x, dy = b->y - a->y;
    return ((x - a->x) * dx + (y - a->y) * dy) / (dx * dx + dy * dy);
}

/* Squared distance from (x, y) to segment i. */
static double distance2(const State *st, size_t i, double x, double y) {
    const Waypoint *a = &st->path[i], *b = &st->path[i + 1];
    const double f = fmin(1.0, fmax(0.0, projection(st, i, x, y)));
    const double px = a->x + f * (b->x - a->x), py = a->y + f * (b->y - a->y);
    return (x - px) * (x - px) + (y - py) * (y - py);
}

/* The nearest of the segments first..last (inclusive); the earlier one on a tie. */
static size_t nearest_segment(const State *st, size_t first, size_t last, double x, double y) {
    size_t best = first;
    double best_d2 = distance2(st, first, x, y);
    for (size_t i = first + 1; i <= last; i++) {
        const double d2 = distance2(st, i, x, y);
        if (d2 < best_d2) {
            best = i;
            best_d2 = d2;
        }
    }
    return best;
}

/* The closest segment from the cursor on, searching only a window ahead (see SEARCH_AHEAD). */
static size_t advance_cursor(const State *st, double x, double y) {
    const size_t segments = st->n - 1;
    const double horizon = st->progress + SEARCH_AHEAD;
    size_t last = st->cursor;
    while (last + 1 < segments && st->path[last + 1].s <= horizon) last++;
    return nearest_segment(st, st->cursor, last, x, y);
}

/* Unit tangent of segment i. */
static void tangent(const State *st, size_t i, double *tx, double *ty) {
    const Waypoint *a = &st->path[i], *b = &st->path[i + 1];
    const double length = segment_length(st, i);
    *tx = (b->x - a->x) / length;
    *ty = (b->y - a->y) / length;
}

/* The segment holding arc length s, searched from segment `from` on; beyond the
 * last waypoint the last segment (extended straight on). */
static size_t segment_at(const State *st, size_t from, double s) {
    size_t i = from;
    while (i + 2 < st->n && st->path[i + 1].s < s) i++;
    return i;
}

/* Lateral offset (positive = left) of (x, y) from the path point at arc length s. */
static double offset_at(const State *st, size_t from, double s, double x, double y) {
    const size_t i = segment_at(st, from, s);
    double tx, ty;
    tangent(st, i, &tx, &ty);
    const double along = s - st->path[i].s;
    const double px = st->path[i].x + along * tx, py = st->path[i].y + along * ty;
    return -(x - px) * ty + (y - py) * tx;
}

/* Locates the pose on the path and moves the cursor there. */
static Fix locate(State *st, double x, double y, double theta, double lookahead) {
    Fix fix;
    st->cursor = advance_cursor(st, x, y);
    const size_t i = st->cursor;
    const double raw = projection(st, i, x, y);
    const double f = fmin(1.0, fmax(0.0, raw));
    double tx, ty;
    tangent(st, i, &tx, &ty);
    fix.segment = i;
    fix.progress = st->path[i].s + f * segment_length(st, i);
    st->progress = fix.progress;
    fix.past_end = i + 2 == st->n && raw > 1.0;
    fix.cross_track = offset_at(st, i, fix.progress, x, y);
    fix.heading_error = wrap_angle(theta - atan2(ty, tx));
    /* The look-ahead point and the path point as far ahead: their offset previews
     * the path's bends, and is 0 on the path even across a corner's tangent jump. */
    fix.lookahead_error = offset_at(st, i, fix.progress + lookahead, x + lookahead * cos(theta),
                                    y + lookahead * sin(theta));
    return fix;
}

/* The path's target speed at arc length s, linear in s between waypoints. */
static double target_speed(const State *st, size_t segment, double s) {
    const Waypoint *a = &st->path[segment], *b = &st->path[segment + 1];
    const double f = fmin(1.0, fmax(0.0, (s - a->s) / (b->s - a->s)));
    return a->speed + f * (b->speed - a->speed);
}

/* ---- control ---------------------------------------------------------- */

/* The nominal lateral model at speed v.  For a kinematic bicycle the look-ahead
 * point, `lever` = L/2 + lookahead ahead of the rear axle (the reference point
 * is midway between the axles), moves sideways at e' = x2 + c u, with x2 = v
 * sin(heading error) and c = v lever / L the steering's immediate effect, and
 * x2' = b0 u + f with b0 = v^2 / L.  Both gains scale with b0_scale. */
typedef struct {
    double b0, c;
} Nominal;

static Nominal nominal(const double *p, double v) {
    const double lever = 0.5 * p[WHEELBASE] + p[LOOKAHEAD];
    return (Nominal){p[B0_SCALE] * v * v / p[WHEELBASE], p[B0_SCALE] * v * lever / p[WHEELBASE]};
}

/* Propagates the extended-state observer over h with measurement e and input
 * u held; its gains place the three poles at -omega_o.  It estimates e, x2
 * and the total disturbance f.  The steering's immediate effect c u on e' is
 * known, so it is modelled rather than left to f: in f it would be an impulse
 * at every steering change, which the observer can only follow late, and
 * the controller's reaction to that late estimate makes the steering chatter. */
static void observe(double z[3], double e, double u, Nominal m, double omega_o, double h) {
    const double l1 = 3.0 * omega_o, l2 = 3.0 * omega_o * omega_o, l3 = omega_o * omega_o * omega_o;
    int n = (int)ceil(omega_o * h / OBSERVER_STEP - 1e-9);
    if (n < 1) n = 1;
    const double dt = h / n;
    for (int k = 0; k < n; k++) {
        const double err = e - z[0];
        const double d0 = z[1] + m.c * u + l1 * err, d1 = z[2] + m.b0 * u + l2 * err, d2 = l3 * err;
        z[0] += dt * d0;
        z[1] += dt * d1;
        z[2] += dt * d2;
    }
}

/* The next steering angle (positive = right) from the observer's estimates:
 * the ADRC law b0 u = kp (0 - e) - kd e' - f with kp = wc^2, kd = 2 wc, where
 * e' = z2 + c u is the rate the new u itself brings about, hence solved for u;
 * plus heading-error feedback. */
static double steering_command(const double *p, const double z[3], double heading_error, double speed) {
    /* Below v_floor the plant's gain vanishes: dividing by it would ask for
     * unbounded steering, so the control uses the gains at v_floor. */
    const Nominal m = nominal(p, fmax(speed, p[V_FLOOR]));
    const double kp = p[OMEGA_C] * p[OMEGA_C], kd = 2.0 * p[OMEGA_C];
    const double u = (kp * (0.0 - z[0]) - kd * z[1] - z[2]) / (m.b0 + kd * m.c) - p[K_HEADING] * heading_error;
    return -u; /* u turns counter-clockwise; delta_f is positive to the right */
}

/* Saturates the command in angle, then in rate from the angle now applied. */
static double actuate(const double *p, double command, double applied, double h) {
    const double angle = fmin(p[MAX_STEER], fmax(-p[MAX_STEER], command));
    const double step = p[MAX_STEER_RATE] * h;
    return fmin(applied + step, fmax(applied - step, angle));
}

static void estimate_speed(Slave *s, double t) {
    State *st = s->state;
    const double *p = s->r;
    const double dt = t - st->last_t;
    if (dt > 0.0) {
        const double dx = p[X] - st->last_x, dy = p[Y] - st->last_y;
        /* Distance over time, negative when the vehicle moved backwards. */
        const double forward = dx * cos(p[THETA]) + dy * sin(p[THETA]);
        const double raw = copysign(hypot(dx, dy), forward) / dt;
        st->speed += dt / (p[TAU_V] + dt) * (raw - st->speed);
    }
    st->last_x = p[X];
    st->last_y = p[Y];
    st->last_t = t;
}

/* PI on the speed error around the target as feed-forward, clamped to
 * [0, v_max]; the integral stops growing while the clamp holds it back. */
static double speed_command(Slave *s, double target, double h) {
    State *st = s->state;
    const double *p = s->r;
    const double error = target - st->speed;
    const double integral = st->integral + p[KI_V] * error * h;
    const double wanted = target + p[KP_V] * error + integral;
    const double command = fmin(p[V_MAX], fmax(0.0, wanted));
    const int winding_up = (wanted > p[V_MAX] && integral > st->integral) || (wanted < 0.0 && integral < st->integral);
    if (!winding_up) st->integral = integral;
    return command;
}

static void publish_fix(Slave *s, const Fix *fix) {
    State *st = s->state;
    s->r[CROSS_TRACK] = fix->cross_track;
    s->r[HEADING_ERROR] = fix->heading_error;
    s->r[PROGRESS] = fix->progress;
    s->r[LOOKAHEAD_ERROR] = fix->lookahead_error;
    s->r[SPEED_ESTIMATE] = st->speed;
    s->r[TARGET_SPEED] = st->finished ? 0.0 : target_speed(st, fix->segment, fix->progress);
}

/* ---- life cycle ------------------------------------------------------- */

/* Parameters (fixed ones may still be set in initialization mode) and the pose
 * inputs are final here: read the path, start the cursor, the observer and the
 * outputs from them. */
static int exit_initialization(Slave *s) {
    State *st = s->state;
    double *p = s->r;
    if (check_parameters(s) != 0 || load_path(s) != 0) return 1;
    /* Walk the window along the path from its start until the closest point stays
     * put: the first stretch of path that passes by the vehicle, never a later
     * branch that happens to be nearer (a global search would take that). */
    st->cursor = 0;
    st->progress = 0.0;
    Fix fix = locate(st, p[X], p[Y], p[THETA], p[LOOKAHEAD]);
    for (size_t before = SIZE_MAX; st->cursor != before;) {
        before = st->cursor;
        fix = locate(st, p[X], p[Y], p[THETA], p[LOOKAHEAD]);
    }
    st->z[0] = fix.lookahead_error;
    st->z[1] = st->z[2] = 0.0;
    st->integral = st->speed = 0.0;
    st->last_x = p[X];
    st->last_y = p[Y];
    st->last_t = s->time;
    st->finished = fix.past_end;
    publish_fix(s, &fix);
    p[DELTA_F] = 0.0; /* the wheels start straight; the rate limit starts from here */
    p[STEERING_RATE] = 0.0;
    p[VELOCITY] = st->finished ? 0.0 : fmin(p[V_MAX], p[TARGET_SPEED]);
    return 0;
}

static int do_step(Slave *s, double t, double h) {
    State *st = s->state;
    double *p = s->r;
    if (!isfinite(p[X]) || !isfinite(p[Y]) || !isfinite(p[THETA])) {
        slave_log(s, fmi2Error, "logStatusError", "pose input is not finite at t=%g: x=%g y=%g theta=%g",
                  t, p[X], p[Y], p[THETA]);
        return 1;
    }
    estimate_speed(s, t);
    const Fix fix = locate(st, p[X], p[Y], p[THETA], p[LOOKAHEAD]);
    st->finished = st->finished || fix.past_end;
    publish_fix(s, &fix);
    if (st->finished) { /* stop, and hold the steering where it is */
        p[VELOCITY] = 0.0;
        p[STEERING_RATE] = 0.0;
        return 0;
    }
    const double v = fmax(st->speed, 0.0);
    const double applied = p[DELTA_F];
    /* The observer sees the steering actually applied (saturated), so it never winds up. */
    observe(st->z, fix.lookahead_error, -applied, nominal(p, v), p[OMEGA_O], h);
    /* The reference point's course differs from the heading by the kinematic side-slip
     * atan(tan(u) / 2) (midway between the axles); on a steady curve the course, not
     * the heading, is tangent to the path, so that is what the feedback compares. */
    const double course_error = wrap_angle(fix.heading_error + atan(0.5 * tan(-applied)));
    p[DELTA_F] = actuate(p, steering_command(p, st->z, course_error, v), applied, h);
    p[STEERING_RATE] = (p[DELTA_F] - applied) / h;
    p[VELOCITY] = speed_command(s, p[TARGET_SPEED], h);
    return 0;
}

const ModelInfo MODEL = {
    .guid = "{7c2e9b14-5a3f-4d86-b0e1-93f6a2c48d57}",
    .n_reals = N_REALS,
    .real_defaults = DEFAULTS,
    .n_strings = N_STRINGS,
    .string_defaults = STRING_DEFAULTS,
    .state_size = sizeof(State),
    .enter_initialization = 0,
    .exit_initialization = exit_initialization,
    .do_step = do_step,
    .release = release,
};
