/*
 * fmi_common.h: what all four FMI layers share, whatever the FMI version; no FMI types.
 *
 * The layers' own files include it (a model's model.c does not): one list of
 * the phases an instance goes through, so that co-simulation and model
 * exchange, FMI 2.0 and 3.0, guard their calls and word their refusals alike;
 * and the few helpers that need no FMI type.
 */
#ifndef DSE_FMI_COMMON_H
#define DSE_FMI_COMMON_H

#include <stddef.h>

/* Co-simulation: instantiated -> initialization -> step mode -> terminated.
 * Model exchange: instantiated -> initialization -> event mode <-> continuous-time mode -> terminated.
 * A call outside its phases, or a failed one, leaves the instance in FAILED until a reset. */
enum { INSTANTIATED, INITIALIZATION, STEP_MODE, EVENT_MODE, CONTINUOUS_TIME_MODE, TERMINATED, FAILED,
       N_PHASES };

#define BIT(phase) (1u << (phase))
#define ANY_PHASE (BIT(N_PHASES) - 1u)
#define RUNNING (BIT(INITIALIZATION) | BIT(STEP_MODE) | BIT(EVENT_MODE) | BIT(CONTINUOUS_TIME_MODE))
#define SETTABLE (BIT(INSTANTIATED) | RUNNING)
#define READABLE (RUNNING | BIT(TERMINATED))

/* For messages: "fmi2SetReal is not allowed in terminated". */
extern const char *const fmi_phase_names[N_PHASES];

/* A copy the caller frees; NULL text copies as "". NULL only when out of memory. */
char *fmi_copy_text(const char *text);

/* calloc that never asks for 0 bytes, so NULL always means out of memory. */
void *fmi_zeroed(size_t n, size_t size);

/* Why a co-simulation instance at time `now` cannot step from t by h (steps
 * are forward only and there is no rollback): writes the reason into why and
 * returns 1, or returns 0. */
int fmi_step_refused(char *why, size_t size, const char *function, double now, double t, double h);

#endif
