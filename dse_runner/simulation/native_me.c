/*
 * native_me.c: a model-exchange FMU integrated by CVode in C, stepped by the native loop like a
 * co-simulation FMU (dse_runner/simulation/native_me.py).
 *
 * model_exchange.py integrates a model-exchange instance with FMPy's CVodeSolver, whose right-hand
 * side and root functions are Python callbacks: for a cheap FMU those callbacks, not the model, are
 * the cost of a run. This file does the same in C, call for call: the same SUNDIALS functions (the
 * libraries FMPy ships, handed over as pointers), set up with the same options, fed the same FMU
 * calls in the same order, with the same event handling as ModelExchangeStepper.do_step. So the
 * trajectories are bit-identical; test_native_loop.py checks it.
 *
 * dse_me_step has fmi2DoStep's shape, so native_loop.c steps an ME unit as it steps any other. It
 * returns 3 (fmi2Error) when something failed, and records what in the unit (Failure) for Python to
 * word as ModelExchangeStepper would. No FMI or SUNDIALS header is needed: only their calling
 * conventions are used.
 *
 * Derivative terms (derivative_terms.py) are added to the FMU's derivatives in the right-hand side as
 * Corrector.add adds them, factor by factor in the same order with the same libm functions.
 */
#include <math.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#define FMI_WARNING 1
#define FMI_ERROR 3
#define CV_BDF 2
#define CV_NORMAL 1
#define MAX_EVENT_ITERATIONS 1000  /* model_exchange.MAX_EVENT_ITERATIONS */
#define MAX_NUM_STEPS 500  /* FMPy's CVodeSolver default */

/* What failed, for Python's message (native_me.py words each as model_exchange.py does). */
enum { OK, FMU_CALL, CALLBACK_CALL, SOLVER, TERMINATE_ASKED, UNSETTLED, OFF_GRID, BAD_STEP, NO_MEMORY };
/* The stage a failure happened in, as ModelExchangeStepper._reported names it. */
enum { STARTING, INPUT_CHANGE, INTEGRATING, COMPLETING };
/* The FMU functions, indexes into Functions and into native_me.FUNCTIONS (their names per version). */
enum { SET_TIME, SET_STATES, GET_STATES, GET_DERIVATIVES, GET_INDICATORS, GET_NOMINALS, COMPLETED_STEP,
       ENTER_EVENT_MODE, UPDATE_DISCRETE, ENTER_CONTINUOUS, N_FUNCTIONS };

typedef int (*TimeFn)(void *, double);
typedef int (*VectorFn)(void *, double *, size_t);
typedef int (*ModeFn)(void *);
typedef int (*Completed2)(void *, int, int *, int *);
typedef int (*Completed3)(void *, bool, bool *, bool *);
typedef int (*Update3)(void *, bool *, bool *, bool *, bool *, bool *, double *);
typedef int (*Get2)(void *, const uint32_t *, size_t, void *);
typedef int (*Get3)(void *, const uint32_t *, size_t, void *, size_t);
typedef struct { int needed, terminate, nominals_changed, values_changed, next_defined; double next_time; } EventInfo2;
typedef int (*Update2)(void *, EventInfo2 *);

typedef int (*RhsFn)(double, void *, void *, void *);
typedef int (*RootFn)(double, void *, double *, void *);
typedef void (*ErrFn)(int, const char *, const char *, const char *, int, void *, void *);

typedef struct {          /* the SUNDIALS functions, from the libraries FMPy loaded */
    int (*context_create)(int, void **);
    int (*context_free)(void **);
    int (*push_err_handler)(void *, ErrFn, void *);
    int (*clear_err_handlers)(void *);
    void *(*new_serial)(int64_t, void *);
    void (*destroy_serial)(void *);
    double *(*array)(void *);
    void *(*cvode_create)(int, void *);
    int (*cvode_init)(void *, RhsFn, double, void *);
    int (*sv_tolerances)(void *, double, void *);
    int (*root_init)(void *, int, RootFn);
    void *(*dense_matrix)(int64_t, int64_t, void *);
    void *(*dense_solver)(void *, void *, void *);
    int (*set_linear_solver)(void *, void *, void *);
    int (*set_max_step)(void *, double);
    int (*set_max_num_steps)(void *, long);
    int (*no_inactive_root_warn)(void *);
    int (*set_user_data)(void *, void *);
    int (*cvode)(void *, double, void *, double *, int);
    int (*reinit)(void *, double, void *);
    void (*cvode_free)(void **);
    int (*solver_free)(void *);
    void (*matrix_destroy)(void *);
    int (*set_max_hnil_warns)(void *, int);
} Sundials;

typedef struct {          /* one group of inputs, read back to see whether the master changed them */
    void *fn;             /* fmi2GetReal, fmi3GetInt64, ... */
    int64_t n;
    const uint32_t *vrs;
    void *now, *before;   /* this step's values, and those the solver last started from */
    int32_t size;         /* bytes per value */
    int32_t floating;     /* compared as numbers (0.0 == -0.0, NaN != NaN), as Python compares them */
} Inputs;

/* A term, der(states[STATE]) += COEFFICIENT * the product of its factors, is a row of TERM_COLUMNS doubles;
 * a factor, FUNCTION(value / WIDTH) ^ POWER of the term inputs' (INPUT != 0) or the states' [INDEX], a row of
 * FACTOR_COLUMNS. FUNCTION: 0 none, then derivative_terms.FUNCTIONS' order: 1 abs, 2 tanh, 3 sin, 4 cos,
 * 5 sign (-1, 0, +1; NaN stays NaN, as np.sign), 6 sqrt (signed: sqrt(|x|) with the sign of x). */
enum { STATE, FIRST, COUNT, COEFFICIENT, TERM_COLUMNS };
enum { INPUT, INDEX, FUNCTION, POWER, WIDTH, FACTOR_COLUMNS };
/* A bounded state (state_limits.Row) is a row of LIMIT_COLUMNS doubles: its index, bounds, the state its
 * overflow passes into (-1: none) and the fraction passed. */
enum { LIMITED, LOW, HIGH, TO, FRACTION, LIMIT_COLUMNS };

typedef struct {
    int32_t code, stage, function, status;
    double from, to;      /* INTEGRATING: the step the solver was asked for; else from is the time */
    int32_t solver_code;  /* SOLVER: CVode's error, as its error handler gave it */
    char solver_module[64], solver_file[64], solver_message[256];
} Failure;

typedef struct {
    const Sundials *sun;
    void *fn[N_FUNCTIONS];
    void *component;
    const Inputs *inputs;
    const double *terms, *factors, *limits;
    const Inputs *term_inputs;  /* the real inputs the terms read (now: their values); NULL: none */
    double *term_states;        /* the states, read back for the terms */
    int32_t n_terms, n_limits, n_inputs, version, needs_completed, discrete;
    int64_t nx, nz;       /* nx as the solver sees it: a dummy state when the FMU has none */
    double tolerance, max_step;
    double time, next_event;
    int32_t next_defined;
    void *context, *memory, *x, *abstol, *matrix, *solver;  /* CVode's, made by dse_me_start */
    Failure failure;
} ModelExchangeUnit;

static bool isclose(double a, double b) {  /* math.isclose with its defaults: relative 1e-9, absolute 0 */
    if (a == b) return true;
    if (isinf(a) || isinf(b)) return false;
    double diff = fabs(b - a);
    return diff <= fabs(1e-9 * b) || diff <= fabs(1e-9 * a);
}

static int fail(ModelExchangeUnit *m, int code, int stage, int function, int status) {
    if (m->failure.code == OK) {
        m->failure.code = code;
        m->failure.stage = stage;
        m->failure.function = function;
        m->failure.status = status;
        m->failure.from = m->time;
    }
    return FMI_ERROR;
}

static int vector(ModelExchangeUnit *m, int function, double *values, size_t n) {
    return ((VectorFn)m->fn[function])(m->component, values, n);
}

static double factor(const double *f, const double *states, const double *inputs) {
    double v = f[INPUT] != 0.0 ? inputs[(int64_t)f[INDEX]] : states[(int64_t)f[INDEX]];
    int function = (int)f[FUNCTION];
    if (function) {
        double x = f[WIDTH] != 1.0 ? v / f[WIDTH] : v;
        switch (function) {
            case 1: v = fabs(x); break;
            case 2: v = tanh(x); break;
            case 3: v = sin(x); break;
            case 4: v = cos(x); break;
            case 5: v = x > 0.0 ? 1.0 : x < 0.0 ? -1.0 : x == 0.0 ? 0.0 : x; break;
            default: v = copysign(sqrt(fabs(x)), x); break;
        }
    }
    return f[POWER] == 1.0 ? v : pow(v, f[POWER]);
}

/* Corrector.add: the terms at the states the FMU holds, and the inputs read at the step's start; then the limits. */
static int add_terms(ModelExchangeUnit *m, double *dx) {
    int status = vector(m, GET_STATES, m->term_states, (size_t)m->nx);
    if (status > FMI_WARNING) return fail(m, CALLBACK_CALL, INTEGRATING, GET_STATES, status), -1;
    const double *inputs = m->term_inputs ? (const double *)m->term_inputs->now : NULL;
    for (int32_t i = 0; i < m->n_terms; i++) {
        const double *term = m->terms + i * TERM_COLUMNS;
        double product = 1.0;
        for (int64_t j = (int64_t)term[FIRST]; j < (int64_t)(term[FIRST] + term[COUNT]); j++)
            product = product * factor(m->factors + j * FACTOR_COLUMNS, m->term_states, inputs);
        dx[(int64_t)term[STATE]] += term[COEFFICIENT] * product;
    }
    for (int32_t i = 0; i < m->n_limits; i++) {  /* state_limits.hold */
        const double *limit = m->limits + i * LIMIT_COLUMNS;
        int64_t k = (int64_t)limit[LIMITED];
        double rate = dx[k], value = m->term_states[k];
        if ((value >= limit[HIGH] && rate > 0.0) || (value <= limit[LOW] && rate < 0.0)) {
            dx[k] = 0.0;
            if (limit[TO] >= 0.0) dx[(int64_t)limit[TO]] += limit[FRACTION] * rate;
        }
    }
    return 0;
}

/* The term inputs' values, held over the step as the FMU's inputs are. */
static int read_term_inputs(ModelExchangeUnit *m, int stage) {
    const Inputs *in = m->term_inputs;
    if (!in) return 0;
    size_t n = (size_t)in->n;
    int status = m->version == 3 ? ((Get3)in->fn)(m->component, in->vrs, n, in->now, n)
                                 : ((Get2)in->fn)(m->component, in->vrs, n, in->now);
    return status > FMI_WARNING ? fail(m, FMU_CALL, stage, N_FUNCTIONS + m->n_inputs, status) : 0;
}

/* FMPy's CVodeSolver.f through model_exchange's guard: a failed FMU call makes CVode stop (-1). */
static int rhs(double t, void *y, void *ydot, void *data) {
    ModelExchangeUnit *m = data;
    int status = ((TimeFn)m->fn[SET_TIME])(m->component, t);
    if (status > FMI_WARNING) return fail(m, CALLBACK_CALL, INTEGRATING, SET_TIME, status), -1;
    double *dx = m->sun->array(ydot);
    if (m->discrete) { dx[0] = 0.0; return 0; }
    if ((status = vector(m, SET_STATES, m->sun->array(y), (size_t)m->nx)) > FMI_WARNING)
        return fail(m, CALLBACK_CALL, INTEGRATING, SET_STATES, status), -1;
    if ((status = vector(m, GET_DERIVATIVES, dx, (size_t)m->nx)) > FMI_WARNING)
        return fail(m, CALLBACK_CALL, INTEGRATING, GET_DERIVATIVES, status), -1;
    return m->n_terms || m->n_limits ? add_terms(m, dx) : 0;
}

/* CVodeSolver.g: the event indicators at the solver's states. */
static int roots(double t, void *y, double *gout, void *data) {
    ModelExchangeUnit *m = data;
    int status = ((TimeFn)m->fn[SET_TIME])(m->component, t);
    if (status > FMI_WARNING) return fail(m, CALLBACK_CALL, INTEGRATING, SET_TIME, status), -1;
    if (!m->discrete && (status = vector(m, SET_STATES, m->sun->array(y), (size_t)m->nx)) > FMI_WARNING)
        return fail(m, CALLBACK_CALL, INTEGRATING, SET_STATES, status), -1;
    if ((status = vector(m, GET_INDICATORS, gout, (size_t)m->nz)) > FMI_WARNING)
        return fail(m, CALLBACK_CALL, INTEGRATING, GET_INDICATORS, status), -1;
    return 0;
}

/* CVodeSolver.ehfun: keeps CVode's last error, for the message. (FMPy names func the module and
 * file the function; native_me.py words it as FMPy does.) */
static void on_error(int line, const char *func, const char *file, const char *msg, int code, void *data,
                     void *context) {
    (void)line;
    (void)context;
    ModelExchangeUnit *m = data;
    m->failure.solver_code = code;
    strncpy(m->failure.solver_module, func ? func : "", sizeof m->failure.solver_module - 1);
    strncpy(m->failure.solver_file, file ? file : "", sizeof m->failure.solver_file - 1);
    strncpy(m->failure.solver_message, msg ? msg : "", sizeof m->failure.solver_message - 1);
}

/* Reads every input group into its ``now`` buffer; true if one differs from ``before``. */
static int read_inputs(ModelExchangeUnit *m, int stage, bool *changed) {
    *changed = false;
    for (int32_t g = 0; g < m->n_inputs; g++) {
        const Inputs *in = &m->inputs[g];
        size_t n = (size_t)in->n;
        int status = m->version == 3 ? ((Get3)in->fn)(m->component, in->vrs, n, in->now, n)
                                     : ((Get2)in->fn)(m->component, in->vrs, n, in->now);
        if (status > FMI_WARNING) return fail(m, FMU_CALL, stage, N_FUNCTIONS + g, status);
        if (*changed) continue;
        if (!in->floating) { *changed = memcmp(in->now, in->before, n * (size_t)in->size) != 0; continue; }
        for (size_t i = 0; i < n && !*changed; i++)
            *changed = in->size == 8 ? ((double *)in->now)[i] != ((double *)in->before)[i]
                                     : ((float *)in->now)[i] != ((float *)in->before)[i];
    }
    return 0;
}

static void keep_inputs(ModelExchangeUnit *m) {
    for (int32_t g = 0; g < m->n_inputs; g++)
        memcpy(m->inputs[g].before, m->inputs[g].now, (size_t)m->inputs[g].n * (size_t)m->inputs[g].size);
}

static void free_solver(ModelExchangeUnit *m) {
    const Sundials *s = m->sun;
    if (m->memory) s->cvode_free(&m->memory);
    if (m->solver) s->solver_free(m->solver);
    if (m->matrix) s->matrix_destroy(m->matrix);
    if (m->x) s->destroy_serial(m->x);
    if (m->abstol) s->destroy_serial(m->abstol);
    if (m->context) s->context_free(&m->context);
    m->memory = m->solver = m->matrix = m->x = m->abstol = m->context = NULL;
}

/* The discrete states to their fixed point (ModelExchangeStepper._update_discrete_states). */
static int update_discrete_states(ModelExchangeUnit *m, int stage) {
    for (int i = 0; i < MAX_EVENT_ITERATIONS; i++) {
        bool needed, terminate, defined;
        double next;
        int status;
        if (m->version == 3) {
            bool nominals, values;
            status = ((Update3)m->fn[UPDATE_DISCRETE])(m->component, &needed, &terminate, &nominals, &values,
                                                       &defined, &next);
        } else {
            EventInfo2 info = {0};
            status = ((Update2)m->fn[UPDATE_DISCRETE])(m->component, &info);
            needed = info.needed != 0, terminate = info.terminate != 0, defined = info.next_defined != 0;
            next = info.next_time;
        }
        if (status > FMI_WARNING) return fail(m, FMU_CALL, stage, UPDATE_DISCRETE, status);
        if (terminate) return fail(m, TERMINATE_ASKED, stage, UPDATE_DISCRETE, 0);
        if (!needed) {
            m->next_defined = defined;
            m->next_event = next;
            return 0;
        }
    }
    return fail(m, UNSETTLED, stage, UPDATE_DISCRETE, 0);
}

/* CVodeSolver.reset: the states again, and a restart at the current time. (FMPy also reads the
 * nominals into its tolerance vector, which CVode copied at set-up: the read changes nothing.) */
static int reset_solver(ModelExchangeUnit *m, int stage) {
    if (!m->discrete) {
        int status = vector(m, GET_STATES, m->sun->array(m->x), (size_t)m->nx);
        if (status > FMI_WARNING) return fail(m, FMU_CALL, stage, GET_STATES, status);
        if ((status = vector(m, GET_NOMINALS, m->sun->array(m->abstol), (size_t)m->nx)) > FMI_WARNING)
            return fail(m, FMU_CALL, stage, GET_NOMINALS, status);
        double *abstol = m->sun->array(m->abstol);
        for (int64_t i = 0; i < m->nx; i++) abstol[i] *= m->tolerance;
    }
    m->sun->reinit(m->memory, m->time, m->x);
    return 0;
}

/* Event mode, discrete states to their fixed point, continuous time again, a solver restart. */
static int event_iteration(ModelExchangeUnit *m, int stage) {
    int status = ((ModeFn)m->fn[ENTER_EVENT_MODE])(m->component);
    if (status > FMI_WARNING) return fail(m, FMU_CALL, stage, ENTER_EVENT_MODE, status);
    if (update_discrete_states(m, stage)) return FMI_ERROR;
    if ((status = ((ModeFn)m->fn[ENTER_CONTINUOUS])(m->component)) > FMI_WARNING)
        return fail(m, FMU_CALL, stage, ENTER_CONTINUOUS, status);
    return reset_solver(m, stage);
}

/* CVodeSolver.step from m->time towards target; *event: CVode stopped early (a root). */
static int integrate(ModelExchangeUnit *m, double target, bool *event) {
    const Sundials *s = m->sun;
    double *x = s->array(m->x);
    m->failure.to = target;
    if (!m->discrete) {
        int status = vector(m, GET_STATES, x, (size_t)m->nx);
        if (status > FMI_WARNING) return fail(m, FMU_CALL, INTEGRATING, GET_STATES, status);
    }
    double reached = 0.0;
    int flag = s->cvode(m->memory, target, m->x, &reached, CV_NORMAL);
    if (!m->discrete) {
        int status = vector(m, SET_STATES, x, (size_t)m->nx);
        if (status > FMI_WARNING) return fail(m, FMU_CALL, INTEGRATING, SET_STATES, status);
    }
    if (flag < 0) return fail(m, SOLVER, INTEGRATING, 0, flag);
    *event = flag > 0;
    m->time = reached;
    return 0;
}

static double earliest(double target, bool defined, double other) {
    return !defined || other > target || isclose(other, target) ? target : other;
}

/* One pass of simulateME's loop (ModelExchangeStepper._advance). */
static int advance(ModelExchangeUnit *m, double end) {
    bool due = m->next_defined && m->next_event > m->time;
    double target = earliest(end, due, m->next_event);
    bool time_event = due && isclose(target, m->next_event), state_event = false, step_event = false;
    double start = m->time;
    if (integrate(m, target, &state_event)) {
        m->failure.from = start;
        return FMI_ERROR;
    }
    int status = ((TimeFn)m->fn[SET_TIME])(m->component, m->time);
    if (status > FMI_WARNING) return fail(m, FMU_CALL, COMPLETING, SET_TIME, status);
    if (m->needs_completed) {
        bool terminate;
        if (m->version == 3) {
            status = ((Completed3)m->fn[COMPLETED_STEP])(m->component, true, &step_event, &terminate);
        } else {
            int event = 0, asked = 0;
            status = ((Completed2)m->fn[COMPLETED_STEP])(m->component, 1, &event, &asked);
            step_event = event != 0, terminate = asked != 0;
        }
        if (status > FMI_WARNING) return fail(m, FMU_CALL, COMPLETING, COMPLETED_STEP, status);
        if (terminate) return fail(m, TERMINATE_ASKED, COMPLETING, COMPLETED_STEP, 0);
    }
    if (time_event || state_event || step_event) return event_iteration(m, COMPLETING);
    return 0;
}

/* ModelExchangeStepper._make_solver and the first read of the inputs, after initialization: the
 * solver simulateME builds, with the same arguments, and our handler of its errors. */
int dse_me_start(ModelExchangeUnit *m) {
    const Sundials *s = m->sun;
    free_solver(m);
    memset(&m->failure, 0, sizeof m->failure);
    if (read_term_inputs(m, STARTING)) return FMI_ERROR;
    if (s->context_create(0, &m->context) != 0) return fail(m, NO_MEMORY, STARTING, 0, 0);
    m->x = s->new_serial(m->nx, m->context);
    m->abstol = s->new_serial(m->nx, m->context);
    if (!m->x || !m->abstol) return fail(m, NO_MEMORY, STARTING, 0, 0);
    double *x = s->array(m->x), *abstol = s->array(m->abstol);
    if (m->discrete) {
        x[0] = abstol[0] = 1.0;
    } else {
        int status = vector(m, GET_STATES, x, (size_t)m->nx);
        if (status > FMI_WARNING) return fail(m, FMU_CALL, STARTING, GET_STATES, status);
        if ((status = vector(m, GET_NOMINALS, abstol, (size_t)m->nx)) > FMI_WARNING)
            return fail(m, FMU_CALL, STARTING, GET_NOMINALS, status);
    }
    for (int64_t i = 0; i < m->nx; i++) abstol[i] *= m->tolerance;
    if (!(m->memory = s->cvode_create(CV_BDF, m->context))) return fail(m, NO_MEMORY, STARTING, 0, 0);
    bool ok = s->cvode_init(m->memory, rhs, m->time, m->x) == 0
        && s->sv_tolerances(m->memory, m->tolerance, m->abstol) == 0
        && s->root_init(m->memory, (int)m->nz, roots) == 0
        && (m->matrix = s->dense_matrix(m->nx, m->nx, m->context)) != NULL
        && (m->solver = s->dense_solver(m->x, m->matrix, m->context)) != NULL
        && s->set_linear_solver(m->memory, m->solver, m->matrix) == 0
        && s->set_max_step(m->memory, m->max_step) == 0
        && s->set_max_num_steps(m->memory, MAX_NUM_STEPS) == 0
        && s->no_inactive_root_warn(m->memory) == 0
        /* ours alone: CVode's "t + h = t" warnings go to the worker's standard output, which a local cluster
         * shares with the command's (and --json's); the step goes on, and a run that cannot is a failure */
        && s->set_max_hnil_warns(m->memory, -1) == 0
        /* ours alone: SUNDIALS's own handler would print every failure of a trial run to the worker's stderr */
        && s->clear_err_handlers(m->context) == 0
        && s->push_err_handler(m->context, on_error, m) == 0
        && s->set_user_data(m->memory, m) == 0;
    if (!ok) return fail(m, SOLVER, STARTING, 0, 0);
    bool changed;
    if (read_inputs(m, STARTING, &changed)) return FMI_ERROR;
    keep_inputs(m);
    return 0;
}

/* ModelExchangeStepper.do_step, in fmi2DoStep's shape: integrate from t to t + h, stopping at every
 * event on the way. */
int dse_me_step(void *unit, double t, double h, int no_set_prior) {
    (void)no_set_prior;
    ModelExchangeUnit *m = unit;
    if (!isclose(t, m->time)) {
        m->failure.to = t;
        return fail(m, OFF_GRID, INPUT_CHANGE, 0, 0);
    }
    if (!(h > 0)) {
        m->failure.to = h;
        return fail(m, BAD_STEP, INPUT_CHANGE, 0, 0);
    }
    double end = t + h;
    bool changed;
    if (read_inputs(m, INPUT_CHANGE, &changed)) return FMI_ERROR;
    if (changed && event_iteration(m, INPUT_CHANGE)) return FMI_ERROR;
    keep_inputs(m);
    if (read_term_inputs(m, INPUT_CHANGE)) return FMI_ERROR;
    while (m->time < end && !isclose(m->time, end))
        if (advance(m, end)) return FMI_ERROR;
    m->time = end;
    return 0;
}

void dse_me_end(ModelExchangeUnit *m) { free_solver(m); }
