/*
 * replay_controller: the paper's open-loop discrete-event controller.  It
 * plays back a recorded steering_inputs.csv (time,velocity,delta_f), each row
 * held from its time until the next row's.  The pose inputs x, y, theta are
 * the interface a closed-loop controller will share; replay ignores them.
 */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "file_parameter.h"
#include "slave.h"

enum Real { VELOCITY, DELTA_F, X, Y, THETA, N_REALS };
enum String { FILE_PATH, N_STRINGS };

static const double DEFAULTS[N_REALS] = {0.0};
static const char *const STRING_DEFAULTS[N_STRINGS] = {""};

enum Column { TIME, COL_VELOCITY, COL_DELTA_F, N_COLUMNS };
static const char *const COLUMN_NAMES[N_COLUMNS] = {"time", "velocity", "delta_f"};

typedef struct {
    double *rows;  /* n_rows x N_COLUMNS, in column order time, velocity, delta_f */
    size_t n_rows;
    size_t cursor; /* the row in force at the current time */
} Log;

static void release(Slave *s) {
    Log *log = s->state;
    free(log->rows);
    log->rows = NULL;
    log->n_rows = 0;
    log->cursor = 0;
}

static void strip_newline(char *line) { line[strcspn(line, "\r\n")] = '\0'; }

/* Maps the header's column names to positions; returns 0 or reports and returns 1. */
static int parse_header(Slave *s, const char *path, char *line, int position[N_COLUMNS]) {
    for (int c = 0; c < N_COLUMNS; c++) position[c] = -1;
    strip_newline(line);
    int index = 0;
    for (char *field = strtok(line, ","); field; field = strtok(NULL, ","), index++) {
        while (*field == ' ') field++;
        for (int c = 0; c < N_COLUMNS; c++)
            if (strcmp(field, COLUMN_NAMES[c]) == 0) position[c] = index;
    }
    for (int c = 0; c < N_COLUMNS; c++)
        if (position[c] < 0) {
            slave_log(s, fmi2Error, "logStatusError",
                      "%s line 1: header has no '%s' column (expected time,velocity,delta_f)", path,
                      COLUMN_NAMES[c]);
            return 1;
        }
    return 0;
}

/* Parses one data row into out[]; returns 0 or reports and returns 1. */
static int parse_row(Slave *s, const char *path, size_t line_no, char *line,
                     const int position[N_COLUMNS], double out[N_COLUMNS]) {
    strip_newline(line);
    int seen = 0, index = 0;
    char *cursor = line;
    while (1) {
        char *end;
        errno = 0;
        double value = strtod(cursor, &end);
        while (*end == ' ') end++;
        if (end == cursor || (*end != ',' && *end != '\0') || errno == ERANGE || !isfinite(value)) {
            slave_log(s, fmi2Error, "logStatusError", "%s line %zu: field %d is not a number: '%s'",
                      path, line_no, index + 1, line);
            return 1;
        }
        for (int c = 0; c < N_COLUMNS; c++)
            if (position[c] == index) {
                out[c] = value;
                seen++;
            }
        index++;
        if (*end == '\0') break;
        cursor = end + 1;
    }
    if (seen != N_COLUMNS) {
        slave_log(s, fmi2Error, "logStatusError", "%s line %zu: expected %d fields, got %d: '%s'",
                  path, line_no, N_COLUMNS, index, line);
        return 1;
    }
    return 0;
}

static int load_log(Slave *s) {
    Log *log = s->state;
    const char *path = s->str[FILE_PATH];
    release(s);
    FILE *f = open_file_parameter(s, path, "the steering_inputs.csv");
    if (!f) return 1;
    char line[4096];
    int position[N_COLUMNS];
    size_t capacity = 0, line_no = 1;
    int failed = 0;
    if (!fgets(line, sizeof line, f)) {
        slave_log(s, fmi2Error, "logStatusError", "%s line 1: the file is empty", path);
        failed = 1;
    } else {
        failed = parse_header(s, path, line, position);
    }
    while (!failed && fgets(line, sizeof line, f)) {
        line_no++;
        if (line[strspn(line, " \r\n")] == '\0') continue; /* blank line */
        if (log->n_rows == capacity) {
            capacity = capacity ? 2 * capacity : 1024;
            double *grown = realloc(log->rows, capacity * N_COLUMNS * sizeof(double));
            if (!grown) {
                slave_log(s, fmi2Error, "logStatusError", "%s: out of memory", path);
                failed = 1;
                break;
            }
            log->rows = grown;
        }
        double *row = log->rows + log->n_rows * N_COLUMNS;
        failed = parse_row(s, path, line_no, line, position, row);
        if (!failed && log->n_rows > 0 && !(row[TIME] > (row - N_COLUMNS)[TIME])) {
            slave_log(s, fmi2Error, "logStatusError",
                      "%s line %zu: time %g does not increase (previous row has %g)", path, line_no,
                      row[TIME], (row - N_COLUMNS)[TIME]);
            failed = 1;
        }
        log->n_rows++;
    }
    fclose(f);
    if (!failed && log->n_rows == 0) {
        slave_log(s, fmi2Error, "logStatusError", "%s: no data rows after the header", path);
        failed = 1;
    }
    if (failed) release(s);
    return failed;
}

/* Outputs the row in force at time t: the last row whose time is <= t. */
static void hold(Slave *s, double t) {
    Log *log = s->state;
    const double tolerance = 1e-9 * (1.0 + fabs(t));
    while (log->cursor + 1 < log->n_rows && log->rows[(log->cursor + 1) * N_COLUMNS + TIME] <= t + tolerance)
        log->cursor++;
    const double *row = log->rows + log->cursor * N_COLUMNS;
    s->r[VELOCITY] = row[COL_VELOCITY];
    s->r[DELTA_F] = row[COL_DELTA_F];
}

static int enter_initialization(Slave *s) {
    if (load_log(s) != 0) return 1;
    hold(s, s->time);
    return 0;
}

static int do_step(Slave *s, double t, double h) {
    hold(s, t + h);
    return 0;
}

const ModelInfo MODEL = {
    .guid = "{a3f7e1c4-2b9d-4e8a-8c61-0d5f4b7a9e23}",
    .n_reals = N_REALS,
    .real_defaults = DEFAULTS,
    .n_strings = N_STRINGS,
    .string_defaults = STRING_DEFAULTS,
    .state_size = sizeof(Log),
    .enter_initialization = enter_initialization,
    .exit_initialization = 0,
    .do_step = do_step,
    .release = release,
};
