/*
 * me2.h: the small FMI 2.0 model-exchange layer shared by dse-runner's ME FMUs.
 *
 * me2.c implements the model-exchange part (the mode state machine,
 * continuous states and event handling); fmi2_common.c the rest of the fmi2*
 * functions, which co-simulation (slave.h) shares.  A model (model.c)
 * describes its Real variables and supplies its equations; the importer's
 * solver does the integrating.  Real variables use value references 0..n-1 in
 * the order of the model's default array, which modelDescription.xml lists in
 * the same order.  There are no Integer, Boolean or String variables.
 *
 * Values are computed lazily: setting time, states or inputs marks the
 * instance stale, and the next read (fmi2GetReal, fmi2GetDerivatives, ...)
 * runs the model's callbacks once.
 */
#ifndef DSE_ME2_H
#define DSE_ME2_H

#include <stddef.h>
#include "fmi2_common.h"

/* An instance: the time (m->time) and the Real variables (m->r); see fmi2_common.h. */
typedef Fmi2Instance MeInstance;

/* Returns 0 on success; on failure it has called me_log with the reason. */
typedef int (*MeHook)(MeInstance *m);

/* What an event update (fmi2NewDiscreteStates) reports back; all zero = nothing. */
typedef struct {
    int terminate;          /* the simulation should stop here */
    int states_changed;     /* the update changed continuous states (e.g. a bounce) */
    int next_time_defined;  /* a time event is due at next_time */
    double next_time;
} MeEvent;

typedef struct {
    const char *guid;
    size_t n_reals;
    const double *real_defaults;        /* start values, value reference = index */
    const char *const *real_names;      /* for error messages; NULL: value references */
    size_t n_states;
    const fmi2ValueReference *states;       /* value reference of each continuous state */
    const fmi2ValueReference *derivatives;  /* value reference of each state's derivative */
    const double *nominals;             /* nominal of each state; NULL: all 1 */
    size_t n_event_indicators;          /* = numberOfEventIndicators in the description */
    /* Initialization mode only: check parameters, set the states from them.
       Runs whenever values are read in initialization mode, last at its exit. */
    MeHook initial;
    /* Derivatives and outputs from time, states, inputs and parameters. */
    MeHook equations;
    /* z[n_event_indicators]; a sign change of z[i] is a state event. NULL if none. */
    int (*event_indicators)(MeInstance *m, double z[]);
    /* Event mode: discrete changes, once per fmi2NewDiscreteStates; it must reach
       its fixed point in one call.  NULL if the model has no discrete behaviour. */
    int (*event_update)(MeInstance *m, MeEvent *e);
} MeInfo;

/* Every ME FMU defines exactly one of these in its model.c. */
extern const MeInfo ME_MODEL;

/* Reports through the importer's logger; printf-style. */
#define me_log fmi2_log

#endif
