/*
 * fmi_common.h: what all four FMI layers share, whatever the FMI version; no FMI types.
 *
 * The layers' own files include it (a model's model.c does not): one list of
 * the phases an instance goes through, so that co-simulation and model
 * exchange, FMI 2.0 and 3.0, guard their calls and word their refusals alike;
 * the core every instance starts with, and the calls written once on it: the
 * guard, logging, the life cycle, steps and model exchange's state arrays.
 * Each version's file wraps them in its own fmi2* or fmi3* signature.
 */
#ifndef DSE_FMI_COMMON_H
#define DSE_FMI_COMMON_H

#include <stdarg.h>
#include <stddef.h>

/* Co-simulation: instantiated -> initialization -> step mode -> terminated.
 * Model exchange: instantiated -> initialization -> event mode <-> continuous-time mode -> terminated.
 * A call outside its phases, or a failed one, leaves the instance in FAILED until a reset. */
enum {
    INSTANTIATED,
    INITIALIZATION,
    STEP_MODE,
    EVENT_MODE,
    CONTINUOUS_TIME_MODE,
    TERMINATED,
    FAILED,
    N_PHASES
};

#define BIT(phase) (1u << (phase))
#define ANY_PHASE (BIT(N_PHASES) - 1u)
#define RUNNING (BIT(INITIALIZATION) | BIT(STEP_MODE) | BIT(EVENT_MODE) | BIT(CONTINUOUS_TIME_MODE))
#define SETTABLE (BIT(INSTANTIATED) | RUNNING)
#define READABLE (RUNNING | BIT(TERMINATED))

/* FMI 2.0 and 3.0 number their statuses alike (fmi2Status, fmi3Status): the
 * calls below return these, which each version's file passes on as its own. */
enum { FMI_OK = 0, FMI_WARNING = 1, FMI_DISCARD = 2, FMI_ERROR = 3, FMI_FATAL = 4 };

/* For messages: "fmi2SetReal is not allowed in terminated". */
extern const char *const fmi_phase_names[N_PHASES];

/* ---- the core of an instance ------------------------------------------ */

typedef struct FmiCore FmiCore;

/* What the calls below need of an instance's FMI version and model. */
typedef struct {
    /* Hands a finished message to the importer's logger, as its version words it. */
    void (*emit)(FmiCore *c, int status, const char *category, const char *message);
    /* Brings computed values up to date (fmi2_refresh, fmi3_refresh); 0 on failure, logged. */
    int (*refresh)(FmiCore *c);
    /* The model's initialization hooks: 0 on success, logged otherwise. */
    int (*enter_initialization)(FmiCore *c);
    int (*exit_initialization)(FmiCore *c);
} FmiCalls;

/* The fields every instance starts with. An instance declares them with
 * FMI_CORE, so a model reads s->time while fmi_common.c takes &s->core. */
#define FMI_CORE_FIELDS                                                                            \
    const FmiCalls *calls;                                                                         \
    char *instance_name;                                                                           \
    int co_simulation; /* 1: a co-simulation layer, 0: model exchange */                           \
    int logging_on;                                                                                \
    int phase;         /* see the phases above */                                                  \
    int stale;         /* model exchange: the equations must run before values are read */         \
    int stop_asked;    /* co-simulation: the model asked to end the run (fmi_ask_to_stop) */       \
    double stop_time;  /* ... having reached this time */                                          \
    double time;

struct FmiCore {
    FMI_CORE_FIELDS
};

#define FMI_CORE                                                                                   \
    union {                                                                                        \
        FmiCore core;                                                                              \
        struct {                                                                                   \
            FMI_CORE_FIELDS                                                                        \
        };                                                                                         \
    }

/* ---- helpers that need no instance --------------------------------------- */

/* A copy the caller frees; NULL text copies as "". NULL only when out of memory. */
char *fmi_copy_text(const char *text);

/* calloc that never asks for 0 bytes, so NULL always means out of memory. */
void *fmi_zeroed(size_t n, size_t size);

/* ---- calls on an instance's core ----------------------------------------- */

/* Logs through the version's emit, printf-style: always for a status other
 * than FMI_OK, else only with logging on. */
void fmi_log(FmiCore *c, int status, const char *category, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
void fmi_vlog(FmiCore *c, int status, const char *category, const char *fmt, va_list ap)
    __attribute__((format(printf, 4, 0)));

/* Guards a call: 1 if the instance's phase is one of `phases`; else 0, after
 * logging and failing the instance. A NULL instance is refused silently. */
int fmi_allowed(FmiCore *c, const char *function, unsigned phases);

/* Marks the instance failed, until a reset; returns FMI_ERROR. */
int fmi_fail(FmiCore *c);

/* Logs an error (printf-style) and fails the instance, for a call that must not go on. */
int fmi_error(FmiCore *c, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

/* A call that only changes the phase: to `to` if the phase is one of `phases`. */
int fmi_enter(FmiCore *c, const char *function, unsigned phases, int to);

/* An error for a function the FMU does not implement, logged. */
int fmi_unsupported(FmiCore *c, const char *function);

/* Debug logging on or off. */
int fmi_set_debug_logging(FmiCore *c, int on);

/* The life cycle up to termination: into initialization mode at time `start`,
 * out of it into step mode (co-simulation) or event mode (model exchange),
 * and termination, which computes the last values first. */
int fmi_enter_initialization(FmiCore *c, const char *function, double start);
int fmi_exit_initialization(FmiCore *c, const char *function);
int fmi_terminate(FmiCore *c, const char *function);

/* A co-simulation step from t by h: in step mode, forward from the instance's
 * time only (no rollback), then the model's `step`, which returns 0 on success
 * after logging otherwise. The instance's time is then t + h. */
int fmi_do_step(FmiCore *c, const char *function, double t, double h,
                int (*step)(FmiCore *c, double t, double h));

/* Called by a model's step: it asks to end the simulation, having reached time `at` (t < at <= t + h).
 * The step then ends at `at`, and each version says so its own way: FMI 2.0's fmi2DoStep returns
 * fmi2Discard with fmi2Terminated true, FMI 3.0's sets terminateSimulation. Cleared on entering
 * initialization, so a reset instance runs again. */
void fmi_ask_to_stop(FmiCore *c, double at);

/* ---- model exchange: time, and states held in the Real variables ------------- */

/* What the states of a model-exchange model are: the value references (=
 * indices into its Real variables) of each state and of its derivative, their
 * nominals (NULL: all 1) and the Real variables' names (NULL: value references). */
typedef struct {
    size_t n_states;
    const unsigned *states;
    const unsigned *derivatives;
    const double *nominals;
    const char *const *names;
} FmiStates;

/* The time an importer sets, in event or continuous-time mode. */
int fmi_set_time(FmiCore *c, const char *function, double time);

/* The states from x[nx], in continuous-time mode, into the Real variables r. */
int fmi_set_states(FmiCore *c, const char *function, double *r, FmiStates m, const double x[],
                   size_t nx);

/* The Real variables at refs (the states, or their derivatives), up to date, into x[nx]. */
int fmi_read_states(FmiCore *c, const char *function, const double *r, FmiStates m,
                    const unsigned refs[], double x[], size_t nx);

/* The states' nominals into out[nx], from instantiation on. */
int fmi_nominals(FmiCore *c, const char *function, FmiStates m, double out[], size_t nx);

/* Whether every derivative in r is finite; else 0, after naming the first
 * that is not: it would only make the importer's solver fail later and obscurely. */
int fmi_derivatives_finite(FmiCore *c, const double *r, FmiStates m);

/* Whether an importer's array length matches the model's; else 0, logged. */
int fmi_check_length(FmiCore *c, const char *function, size_t given, size_t expected);

#endif
