/*
 * slave3.h: the small FMI 3.0 co-simulation layer, the FMI 3 twin of slave.h.
 *
 * slave3.c implements the co-simulation part (instantiation, initialization,
 * steps); fmi3_common.c the rest of the fmi3* functions, which model
 * exchange (me3.h) shares.  A model (model.c of each FMU) describes its
 * variables in one table (Variable3, see fmi3_common.h) and supplies the same
 * callbacks as with slave.h.
 *
 * Only scalar variables: arrays, Binary and Clock variables, event mode,
 * early return and FMU state are not supported (those calls return
 * fmi3Error with a log message).
 */
#ifndef DSE_SLAVE3_H
#define DSE_SLAVE3_H

#include <stddef.h>
#include "fmi3_common.h"

/* An instance: the time, one array per type (s->f64, s->i32, ..., s->str)
 * and the model-private state (s->state); see fmi3_common.h. */
typedef Fmi3Instance Slave3;

/* Returns 0 on success; on failure it has called slave3_log with the reason. */
typedef int (*Slave3Hook)(Slave3 *s);
typedef int (*Slave3Step)(Slave3 *s, double t, double h);

typedef struct {
    const char *instantiation_token;    /* modelDescription.xml's instantiationToken */
    const Variable3 *variables;
    size_t n_variables;
    size_t state_size;                  /* bytes of model-private state */
    Slave3Hook enter_initialization;    /* parameters are final from here on */
    Slave3Hook exit_initialization;
    Slave3Step do_step;                 /* advance from t to t + h */
    void (*release)(Slave3 *s);         /* free model-private allocations */
} ModelInfo3;

/* Every FMI 3 FMU defines exactly one of these in its model.c. */
extern const ModelInfo3 MODEL;

/* Reports through the importer's logger; printf-style. */
#define slave3_log fmi3_log

#endif
