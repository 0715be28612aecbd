/*
 * me3.h: the small FMI 3.0 model-exchange layer, the FMI 3 twin of me2.h.
 *
 * me3.c implements the model-exchange part (the mode machine instantiated ->
 * initialization -> event mode <-> continuous-time mode -> terminated,
 * continuous states and derivatives); fmi3_common.c the rest of the fmi3*
 * functions, which co-simulation (slave3.h) shares.  A model (model.c) lists
 * its Float64 variables, value reference = index, and supplies its
 * equations; the importer's solver integrates.  The independent variable
 * (time) is one of them, at time_vr: reading it gives the current time.  No
 * other types, no event indicators, no discrete states.
 *
 * Values are computed lazily, as in me2.c: setting time, states or inputs
 * marks the instance stale; the next read runs the model's callbacks once.
 */
#ifndef DSE_ME3_H
#define DSE_ME3_H

#include <stddef.h>
#include "fmi3_common.h"

/* An instance: the time (m->time) and the Float64 variables (m->r); see fmi3_common.h. */
typedef Fmi3Instance Me3Instance;

/* Returns 0 on success; on failure it has called me3_log with the reason. */
typedef int (*Me3Hook)(Me3Instance *m);

typedef struct {
    const char *instantiation_token;    /* modelDescription.xml's instantiationToken */
    size_t n_reals;                     /* Float64 variables, value reference = index */
    const double *real_defaults;        /* start values */
    const char *const *real_names;      /* for error messages; NULL: value references */
    fmi3ValueReference time_vr;         /* the independent variable; reads the current time */
    size_t n_states;
    const fmi3ValueReference *states;       /* value reference of each continuous state */
    const fmi3ValueReference *derivatives;  /* value reference of each state's derivative */
    const double *nominals;             /* nominal of each state; NULL: all 1 */
    /* Initialization mode only: check parameters, set the states from them. */
    Me3Hook initial;
    /* Derivatives and outputs from time, states, inputs and parameters. */
    Me3Hook equations;
} Me3Info;

/* Every FMI 3 ME FMU defines exactly one of these in its model.c. */
extern const Me3Info ME3_MODEL;

/* Reports through the importer's logger; printf-style. */
#define me3_log fmi3_log

#endif
