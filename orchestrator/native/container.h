/* SPDX-License-Identifier: BSD-2-Clause */
/* The scenario container's state, shared by its parts: container.c (the plan read, the embedded FMUs
   loaded and instantiated, messages, the host's inputs), container_fmi2.c (the FMI 2.0 API) and
   container_fmi3.c (the FMI 3.0 API, mapped onto the FMI 2.0 functions). The FMI types come from the
   official headers in fmi/ alone. Functions declared here are the library's own (hidden, compiled
   with -fvisibility=hidden): only the fmi2* and fmi3* functions are exported. */

#ifndef FTC_CONTAINER_H
#define FTC_CONTAINER_H

#include <stdint.h>

#include "core.h"
#include "fmi2Functions.h"
#include "fmi3Functions.h"
#include "plan.h"

#define EXPORT FMI2_Export
#define TEXT 4096

/* What an embedded FMI 3.0 FMU's logMessage needs (FMI 3.0 passes no instance name). */
struct relay3 {
    struct container *x;
    const char *name;
};

enum state { INSTANTIATED, INITIALIZATION, STEPPING, TERMINATED, FAILED };

struct container {
    struct plan plan;
    struct core core;
    void **libraries;       /* dlopen handles, per component */
    struct relay3 *relays;  /* per component */
    char name[256];
    const char *serving;    /* the FMI 3.0 function served by an FMI 2.0 one (its messages name it) */
    char resources[TEXT];
    fmi2CallbackFunctions host;
    /* FMI 3.0 host (fmi3InstantiateCoSimulation): its logMessage and instance environment */
    void (*log3)(void *, int, const char *, const char *);
    void *env3;
    fmi2CallbackFunctions inner;
    int logging;
    enum state state;
    double *values;
    int64_t k;          /* internal steps done */
    int dirty;          /* gauss-seidel: an exposed input changed since the last propagation */
    int *input_set;     /* per exposed variable: the host set it (inputs are applied after start values) */
    double stop;
    int stop_defined;
};

/* One message to the host's logger (FMI 2.0 or 3.0) under the container's name; an error latches
   the FAILED state. */
void say(struct container *x, fmi2Status status, const char *format, ...);
/* The core's failure: one line as `orchestrate run` reports it; the container's status. */
fmi2Status failed(struct container *x);
/* A new container: the plan read, every FMU loaded and instantiated; NULL after one message. */
struct container *create(struct container *x, const char *function, const char *token);
/* Every FMU freed, the plan and the container's memory released. */
void release(struct container *x);
/* The host's inputs set so far, passed on (after the start values, which they override). */
fmi2Status apply_inputs(struct container *x, double t);
/* gauss-seidel: the outputs that depend on inputs set since, propagated again. */
fmi2Status propagate(struct container *x, double t);

/* Whether a getter's or setter's arrays can be read (container_fmi2.c); else fmi2Error said. */
int container_arrays(struct container *x, const char *function, size_t n, const void *vr, const void *values);

/* The core's result as the container's status. */
#define CORE(x, call) ((call) ? failed(x) : fmi2OK)

#define CONTAINER(c, allowed)                                                                                \
    struct container *x = (c);                                                                               \
    if (!x) return fmi2Error;                                                                                \
    if (x->state == FAILED && strcmp(__func__, "fmi2Reset") != 0) {                                         \
        say(x, fmi2Error, "%s: called after a failure (only fmi2Reset and fmi2FreeInstance are allowed)",    \
            __func__);                                                                                       \
        return fmi2Error;                                                                                    \
    }                                                                                                        \
    if (!((allowed) & (1 << x->state))) {                                                                    \
        say(x, fmi2Error, "%s: not allowed in this state", __func__);                                        \
        return fmi2Error;                                                                                    \
    }

#define ANY (1 << INSTANTIATED | 1 << INITIALIZATION | 1 << STEPPING | 1 << TERMINATED)
#define ANY_OR_FAILED (ANY | 1 << FAILED)

#endif
