/*
 * fmi2_common.h: what dse-runner's two FMI 2.0 layers share, co-simulation
 * (slave.h) and model exchange (me2.h).
 *
 * One instance type for both (slave.h names it Slave, me2.h MeInstance), and
 * fmi2_common.c implements once every fmi2* function whose meaning does not
 * depend on the interface: logging, value access by type, the life cycle up
 * to termination and reset, and the optional capabilities the descriptions
 * declare absent.  Real,
 * Integer, Boolean and String variables each use value references 0..n-1
 * (FMI 2.0 scopes a value reference to its type), in the order of the model's
 * default arrays; modelDescription.xml lists the same order.  An enumeration
 * is an Integer variable.
 */
#ifndef DSE_FMI2_COMMON_H
#define DSE_FMI2_COMMON_H

#include <stddef.h>
#include "fmi2Functions.h"

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
    Fmi2Model model;
    const fmi2CallbackFunctions *cb;
    char *instance_name;
    int logging_on;
    int phase;                          /* see fmi_common.h */
    int stale;                          /* model exchange: the equations must run before values are read */
    double time;
    double *r;                          /* real variables */
    char **str;                         /* string variables (owned copies) */
    fmi2Integer *i;                     /* integer variables */
    fmi2Boolean *b;                     /* boolean variables, always fmi2False or fmi2True */
    void *state;                        /* model-private, state_size bytes, zeroed on reset */
};

/* Reports through the importer's logger; printf-style.  slave_log and me_log name it too. */
void fmi2_log(Fmi2Instance *s, fmi2Status status, const char *category, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));

/* ---- for the interface files ------------------------------------------ */

/* A new instance at its start values, or NULL after telling the importer why
 * (a wrong interface type or GUID, or no memory). */
Fmi2Instance *fmi2_instantiate(fmi2String name, fmi2Type type, fmi2String guid,
                               const fmi2CallbackFunctions *cb, fmi2Boolean logging_on,
                               const char *model_guid, const Fmi2Model *model);

/* Guards a call: 1 if the instance's phase is one of `phases` (bits of
 * fmi_common.h's phases); else 0, after logging and failing the instance. */
int fmi2_allowed(Fmi2Instance *s, const char *function, unsigned phases);

/* Marks the instance failed: its use ends until a reset. */
fmi2Status fmi2_fail(Fmi2Instance *s);

/* Logs an error (printf-style) and fails the instance, for a call that must not go on (a refused step). */
fmi2Status fmi2_error(Fmi2Instance *s, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

/* A call that only changes the phase: to `to` if the instance's phase is one of `phases`
 * (fmi2_allowed's guard). */
fmi2Status fmi2_enter(fmi2Component c, const char *function, unsigned phases, int to);

/* An error for a function the FMU does not implement, logged. */
fmi2Status fmi2_unsupported(fmi2Component c, const char *function);

/* Defines an fmi2* function the FMU does not have, with the standard's
 * signature (fmi2Functions.h checks it): it logs and returns fmi2Error. */
#define FMI2_UNSUPPORTED(function, ...)                                                           \
    _Pragma("GCC diagnostic push") _Pragma("GCC diagnostic ignored \"-Wunused-parameter\"")     \
    fmi2Status function(fmi2Component c, __VA_ARGS__) { return fmi2_unsupported(c, #function); } \
    _Pragma("GCC diagnostic pop")

/* Each interface file defines these two. */

/* fmi2Instantiate's work: the interface's model, through fmi2_instantiate. */
Fmi2Instance *fmi2_create(fmi2String name, fmi2Type type, fmi2String guid, const fmi2CallbackFunctions *cb,
                          fmi2Boolean logging_on);

/* Brings every computed value up to date before a read; returns 0 on
 * failure, after logging. */
int fmi2_refresh(Fmi2Instance *s);

#endif
