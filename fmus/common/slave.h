/*
 * slave.h: the small FMI 2.0 co-simulation layer shared by dse-runner's FMUs.
 *
 * slave.c implements the co-simulation part (initialization, steps,
 * status); fmi2_common.c the rest of the fmi2* functions, which model
 * exchange (me2.h) shares.  A model (model.c of each FMU) only describes its
 * variables and supplies three callbacks.  Real, Integer, Boolean and String
 * variables each use value references 0..n-1 (FMI 2.0 scopes a value
 * reference to its type), in the order of the model's default arrays;
 * modelDescription.xml lists the same order.  An enumeration is an Integer
 * variable.
 */
#ifndef DSE_SLAVE_H
#define DSE_SLAVE_H

#include <stddef.h>
#include "fmi2_common.h"

/* An instance: the time, the variables (s->r, s->i, s->b, s->str) and the
 * model-private state (s->state); see fmi2_common.h. */
typedef Fmi2Instance Slave;

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

/* Every FMU defines exactly one of these in its model.c. */
extern const ModelInfo MODEL;

/* Reports through the importer's logger; printf-style. */
#define slave_log fmi2_log

#endif
