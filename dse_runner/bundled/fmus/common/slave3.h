/*
 * slave3.h: the small FMI 3.0 co-simulation layer, the FMI 3 twin of slave.h.
 *
 * slave3.c implements every fmi3* function once: the state machine, value
 * access by value reference, logging and memory.  A model (model.c of each
 * FMU) describes its variables and supplies the same callbacks as with
 * slave.h.
 *
 * FMI 3.0 value references are unique across all types (unlike FMI 2.0), so
 * the model gives one table: for each variable its value reference, its type
 * and its index into the instance's array of that type (s->f64, s->i32, ...).
 * Indices of one type run 0..n-1; the model's own enums name them, so model
 * code reads s->f64[LEVEL] whatever the value references are.  The table also
 * holds the start values, which Reset restores.
 *
 * Only scalar variables: arrays, Binary and Clock variables, event mode,
 * early return and FMU state are not supported (those calls return
 * fmi3Error with a log message).
 */
#ifndef DSE_SLAVE3_H
#define DSE_SLAVE3_H

#include <stddef.h>
#include "fmi3Functions.h"

typedef struct Slave3 Slave3;

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
    V3_N_STORED,            /* the types above each have an array in Slave3 */
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

struct Slave3 {
    const ModelInfo3 *info;
    fmi3InstanceEnvironment environment;
    fmi3LogMessageCallback logger;
    char *instance_name;
    int logging_on;
    int phase;                          /* see slave3.c */
    double time;
    /* One array per type, indexed by Variable3.index. */
    fmi3Float64 *f64;
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
    void *state;                        /* model-private, state_size bytes, zeroed on reset */
};

/* Every FMI 3 FMU defines exactly one of these in its model.c. */
extern const ModelInfo3 MODEL;

/* Reports through the importer's logger; printf-style. */
void slave3_log(Slave3 *s, fmi3Status status, const char *category, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));

#endif
