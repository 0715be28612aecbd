/*
 * slave.h: the small FMI 2.0 co-simulation layer shared by dse-runner's FMUs.
 *
 * slave.c implements every fmi2* function once: the state machine, value
 * access by value reference, logging and memory.  A model (model.c of each
 * FMU) only describes its variables and supplies three callbacks.  Real,
 * Integer, Boolean and String variables each use value references 0..n-1 (FMI
 * 2.0 scopes a value reference to its type), in the order of the model's
 * default arrays; modelDescription.xml lists the same order.  An enumeration
 * is an Integer variable.
 */
#ifndef DSE_SLAVE_H
#define DSE_SLAVE_H

#include <stddef.h>
#include "fmi2Functions.h"

typedef struct Slave Slave;

/* Returns 0 on success; on failure it has called slave_log with the reason. */
typedef int (*SlaveHook)(Slave *s);
typedef int (*SlaveStep)(Slave *s, double t, double h);

typedef struct {
    const char *guid;
    size_t n_reals;
    const double *real_defaults;        /* start values, value reference = index */
    size_t n_strings;
    const char *const *string_defaults;
    size_t n_integers;                  /* Integer and enumeration variables */
    const int *integer_defaults;
    size_t n_booleans;
    const int *boolean_defaults;        /* 0 or 1 */
    size_t state_size;                  /* bytes of model-private state */
    SlaveHook enter_initialization;     /* parameters are final from here on */
    SlaveHook exit_initialization;
    SlaveStep do_step;                  /* advance from t to t + h */
    void (*release)(Slave *s);          /* free model-private allocations */
} ModelInfo;

struct Slave {
    const ModelInfo *info;
    const fmi2CallbackFunctions *cb;
    char *instance_name;
    int logging_on;
    int phase;                          /* see slave.c */
    double time;
    double *r;                          /* real variables */
    char **str;                         /* string variables (owned copies) */
    fmi2Integer *i;                     /* integer variables */
    fmi2Boolean *b;                     /* boolean variables, always fmi2False or fmi2True */
    void *state;                        /* model-private, state_size bytes, zeroed on reset */
};

/* Every FMU defines exactly one of these in its model.c. */
extern const ModelInfo MODEL;

/* Reports through the importer's logger; printf-style. */
void slave_log(Slave *s, fmi2Status status, const char *category, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));

#endif
