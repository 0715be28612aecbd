/*
 * fmi3_common.h: what dse-runner's two FMI 3.0 layers share, co-simulation
 * (slave3.h) and model exchange (me3.h).
 *
 * One instance type for both (slave3.h names it Slave3, me3.h Me3Instance),
 * and fmi3_common.c implements once every fmi3* function whose meaning does
 * not depend on the interface: logging, value access by type, the life cycle
 * up to termination and reset, and everything neither layer has (arrays, Binary and Clock variables,
 * scheduled execution, configuration mode, FMU state, derivatives), which
 * returns fmi3Error with a log message; FMPy binds every fmi3* function at
 * load, so all must exist.  What does not depend on the FMI version either
 * (the guard, logging, the life cycle's phases, steps) is fmi_common.c's, on
 * the core the instance starts with; the fmi3* functions wrap it.
 *
 * FMI 3.0 value references are unique across all types (unlike FMI 2.0), so
 * a model is one table: for each variable its value reference, its type and
 * its index into the instance's array of that type (s->f64, s->i32, ...).
 * Indices of one type run 0..n-1; the model's own enums name them, so model
 * code reads s->f64[LEVEL] whatever the value references are.  The table also
 * holds the start values, which Reset restores.
 */
#ifndef DSE_FMI3_COMMON_H
#define DSE_FMI3_COMMON_H

#include <stddef.h>
#include "fmi3Functions.h"
#include "fmi_common.h"

typedef struct Fmi3Instance Fmi3Instance;

typedef enum {
    V3_FLOAT64,
    V3_FLOAT32,
    V3_INT8,
    V3_UINT8,
    V3_INT16,
    V3_UINT16,
    V3_INT32,
    V3_UINT32,
    V3_INT64,               /* also enumerations: FMI 3 enumerations are Int64-valued */
    V3_UINT64,
    V3_BOOLEAN,
    V3_STRING,
    V3_N_STORED,            /* the types above each have an array in the instance */
    V3_TIME = V3_N_STORED,  /* the independent Float64 variable: reads the current time, no index */
    V3_N_TYPES
} VarType3;

typedef struct {
    fmi3ValueReference vr;
    VarType3 type;
    size_t index;           /* into the array of this type; ignored for V3_TIME */
    double start;           /* numeric and Boolean start value (64-bit integers: exact to 2^53) */
    const char *start_string; /* String start value; NULL means "" */
} Variable3;

/* What the shared part needs of a model: its interface, its variable table,
 * its private state and its initialization hooks. */
typedef struct {
    int co_simulation;                  /* 1: slave3.c's co-simulation, 0: me3.c's model exchange */
    const Variable3 *variables;
    size_t n_variables;
    size_t state_size;                  /* bytes of model-private state */
    void (*release)(Fmi3Instance *s);   /* frees model-private allocations; NULL if none */
    int (*enter_initialization)(Fmi3Instance *s); /* 0 on success; NULL if none */
    int (*exit_initialization)(Fmi3Instance *s);
} Fmi3Model;

struct Fmi3Instance {
    FMI_CORE; /* name, phase, time, ... (fmi_common.h): s->time, and &s->core for its calls */
    Fmi3Model model;
    fmi3InstanceEnvironment environment;
    fmi3LogMessageCallback logger;
    /* One array per type, indexed by Variable3.index. */
    union {
        fmi3Float64 *f64;
        double *r;                      /* me3.h's name: value reference = index */
    };
    fmi3Float32 *f32;
    fmi3Int8 *i8;
    fmi3UInt8 *u8;
    fmi3Int16 *i16;
    fmi3UInt16 *u16;
    fmi3Int32 *i32;
    fmi3UInt32 *u32;
    fmi3Int64 *i64;
    fmi3UInt64 *u64;
    fmi3Boolean *b;
    char **str;                         /* owned copies */
    size_t count[V3_N_STORED];          /* length of each array */
    const Variable3 **by_vr;            /* the model's table sorted by value reference */
    Variable3 *own_variables;           /* a table the layer built (me3.c), freed with the instance */
    void *state;                        /* model-private, state_size bytes, zeroed on reset */
};

/* The core of an instance, which fmi_common.h's calls take; NULL for none. */
static inline FmiCore *fmi3_core(fmi3Instance c) { return c ? &((Fmi3Instance *)c)->core : NULL; }

/* Reports through the importer's logger; printf-style.  slave3_log and me3_log name it too. */
void fmi3_log(Fmi3Instance *s, fmi3Status status, const char *category, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));

/* ---- for the interface files ------------------------------------------ */

/* A new instance at its start values, or NULL after telling the importer why
 * (`refusal` if not NULL, else a wrong instantiation token, a mistake in the
 * model's table, or no memory); with no instance yet, a refusal goes to the
 * logger callback directly.  With a refusal, model may be NULL. */
Fmi3Instance *fmi3_instantiate(fmi3String name, fmi3String token, const char *model_token,
                               const char *refusal, fmi3Boolean logging_on,
                               fmi3InstanceEnvironment environment, fmi3LogMessageCallback logger,
                               const Fmi3Model *model);

/* fmi_common.h's guard and failures, on an FMI 3.0 instance. */
#define fmi3_allowed(s, function, phases) fmi_allowed(fmi3_core(s), function, phases)
#define fmi3_fail(s) ((fmi3Status)fmi_fail(fmi3_core(s)))

/* Defines an fmi3* function the FMU does not have, with the standard's
 * signature (fmi3Functions.h checks it): it logs and returns fmi3Error. */
#define FMI3_UNSUPPORTED(function, ...)                                                            \
    _Pragma("GCC diagnostic push") _Pragma("GCC diagnostic ignored \"-Wunused-parameter\"")      \
    fmi3Status function(fmi3Instance c, __VA_ARGS__) {                                                  \
        return (fmi3Status)fmi_unsupported(fmi3_core(c), #function);                         \
    }                                                                                           \
    _Pragma("GCC diagnostic pop")

/* The same for an fmi3* function whose only argument is the instance. */
#define FMI3_UNSUPPORTED_CALL(function) \
    fmi3Status function(fmi3Instance c) { return (fmi3Status)fmi_unsupported(fmi3_core(c), #function); }

/* Each interface file defines these two. */

/* fmi3InstantiateCoSimulation's (co_simulation 1) or fmi3InstantiateModelExchange's
 * (0) work: the interface's model through fmi3_instantiate, or a refusal. */
Fmi3Instance *fmi3_create(int co_simulation, fmi3String name, fmi3String token, fmi3Boolean event_mode_used,
                          fmi3Boolean logging_on, fmi3InstanceEnvironment environment,
                          fmi3LogMessageCallback logger);

/* Brings every computed value up to date before a read; returns 0 on
 * failure, after logging. */
int fmi3_refresh(Fmi3Instance *s);

#endif
