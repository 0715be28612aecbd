/*
 * fmi2_common.h: what dse-runner's two FMI 2.0 layers share, co-simulation
 * (slave.h) and model exchange (me2.h).
 *
 * One instance type for both (slave.h names it Slave, me2.h MeInstance), and
 * fmi2_common.c implements once every fmi2* function whose meaning does not
 * depend on the interface: logging, value access by type, the life cycle up
 * to termination and reset, and the optional capabilities the descriptions
 * declare absent.  What does not depend on the FMI version either (the guard,
 * logging, the life cycle's phases, steps) is fmi_common.c's, on the core the
 * instance starts with; the fmi2* functions wrap it in FMI 2.0's types.  Real,
 * Integer, Boolean and String variables each use value references 0..n-1
 * (FMI 2.0 scopes a value reference to its type), in the order of the model's
 * default arrays; modelDescription.xml lists the same order.  An enumeration
 * is an Integer variable.
 */
#ifndef DSE_FMI2_COMMON_H
#define DSE_FMI2_COMMON_H

#include <stddef.h>
#include "fmi2Functions.h"
#include "fmi_common.h"

typedef struct Fmi2Instance Fmi2Instance;

/* What the shared part needs of a model: its interface, its variables' start
 * values (a type without defaults starts at 0 / false), its private state and
 * its initialization hooks. */
typedef struct {
    int co_simulation;                  /* 1: slave.c's co-simulation, 0: me2.c's model exchange */
    size_t n_reals;
    const double *real_defaults;
    size_t n_integers;
    const int *integer_defaults;
    size_t n_booleans;
    const int *boolean_defaults;
    size_t n_strings;
    const char *const *string_defaults;
    size_t state_size;                  /* bytes of model-private state */
    void (*release)(Fmi2Instance *s);   /* frees model-private allocations; NULL if none */
    int (*enter_initialization)(Fmi2Instance *s); /* 0 on success; NULL if none */
    int (*exit_initialization)(Fmi2Instance *s);
} Fmi2Model;

struct Fmi2Instance {
    FMI_CORE; /* name, phase, time, ... (fmi_common.h): s->time, and &s->core for its calls */
    Fmi2Model model;
    const fmi2CallbackFunctions *cb;
    double *r;                          /* real variables */
    char **str;                         /* string variables (owned copies) */
    fmi2Integer *i;                     /* integer variables */
    fmi2Boolean *b;                     /* boolean variables, always fmi2False or fmi2True */
    void *state;                        /* model-private, state_size bytes, zeroed on reset */
};

/* The core of an instance, which fmi_common.h's calls take; NULL for none. */
static inline FmiCore *fmi2_core(fmi2Component c) { return c ? &((Fmi2Instance *)c)->core : NULL; }

/* Reports through the importer's logger; printf-style.  slave_log and me_log name it too. */
void fmi2_log(Fmi2Instance *s, fmi2Status status, const char *category, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));

/* ---- for the interface files ------------------------------------------ */

/* A new instance at its start values, or NULL after telling the importer why
 * (a wrong interface type or GUID, or no memory). */
Fmi2Instance *fmi2_instantiate(fmi2String name, fmi2Type type, fmi2String guid,
                               const fmi2CallbackFunctions *cb, fmi2Boolean logging_on,
                               const char *model_guid, const Fmi2Model *model);

/* fmi_common.h's guard and failures, on an FMI 2.0 instance. */
#define fmi2_allowed(s, function, phases) fmi_allowed(fmi2_core(s), function, phases)
#define fmi2_fail(s) ((fmi2Status)fmi_fail(fmi2_core(s)))

/* Defines an fmi2* function the FMU does not have, with the standard's
 * signature (fmi2Functions.h checks it): it logs and returns fmi2Error. */
#define FMI2_UNSUPPORTED(function, ...)                                                            \
    _Pragma("GCC diagnostic push") _Pragma("GCC diagnostic ignored \"-Wunused-parameter\"")      \
    fmi2Status function(fmi2Component c, __VA_ARGS__) {                                                  \
        return (fmi2Status)fmi_unsupported(fmi2_core(c), #function);                         \
    }                                                                                           \
    _Pragma("GCC diagnostic pop")

/* Each interface file defines these two. */

/* fmi2Instantiate's work: the interface's model, through fmi2_instantiate. */
Fmi2Instance *fmi2_create(fmi2String name, fmi2Type type, fmi2String guid, const fmi2CallbackFunctions *cb,
                          fmi2Boolean logging_on);

/* Brings every computed value up to date before a read; returns 0 on
 * failure, after logging. */
int fmi2_refresh(Fmi2Instance *s);

#endif
