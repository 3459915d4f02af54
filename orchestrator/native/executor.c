/* SPDX-License-Identifier: BSD-2-Clause */
/* The compiled executor: the core (core.c) as a library the engine calls through ctypes
   (orchestrator/native/__init__.py). Python instantiates and initializes the FMUs (fmpy, the FMU
   cache, the message log) and binds each instance here; then it hands over blocks of steps: this
   code runs them, copies every row into the recorder's buffer, and returns at the end of the block,
   at the first row holding a value that is not finite (the recorder names it), at a failed call
   (its component, function, status and time in `failure`) or when `*stop` is set (the engine's
   signal handlers and wall-clock limit set it). Progress, signals, the wall-clock limit, input
   files and recording stay in Python between blocks. */

#define _GNU_SOURCE
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core.h"

#define EXPORT __attribute__((visibility("default")))

struct executor {
    struct plan plan;
    struct core core;
};

EXPORT void ftc_executor_close(struct executor *x) {
    if (!x) return;
    plan_free(&x->plan);
    free(x->core.fmus);
    free(x);
}

/* A new executor of the plan `text`; NULL with `why` filled. */
EXPORT struct executor *ftc_executor_open(const char *text, char *why, size_t size) {
    struct executor *x = calloc(1, sizeof *x);
    if (!x) {
        snprintf(why, size, "out of memory");
        return NULL;
    }
    if (plan_read(text, "the engine's plan", &x->plan, why, size) != 0) {
        ftc_executor_close(x);
        return NULL;
    }
    x->core.plan = &x->plan;
    x->core.clocks = x->plan.clocks; /* the engine gives their intervals (asked in Initialization Mode) */
    x->core.fmus = calloc(x->plan.ncomponents ? x->plan.ncomponents : 1, sizeof *x->core.fmus);
    if (!x->core.fmus) {
        snprintf(why, size, "out of memory");
        ftc_executor_close(x);
        return NULL;
    }
    return x;
}

/* Binds component i to `instance` of the FMU loaded as `library` (a dlopen handle); 0, or -1. */
EXPORT int ftc_executor_bind(struct executor *x, int i, void *library, void *instance, char *why, size_t size) {
    if (i < 0 || (size_t)i >= x->plan.ncomponents) {
        snprintf(why, size, "no component %d in the plan", i);
        return -1;
    }
    struct fmu *f = &x->core.fmus[i];
    if (fmu_bind(f, library, x->plan.components[i].version, 0, why, size) != 0) return -1;
    if (plan_clocked(&x->plan, i) && fmu_bind_clocks(f, library, why, size) != 0) return -1;
    f->instance = instance;
    return 0;
}

static int all_finite(const double *row, size_t n) {
    for (size_t j = 0; j < n; j++)
        if (!isfinite(row[j])) return 0;
    return 1;
}

/* Steps k .. k + count - 1 on `values` (the engine's value buffer); row j (t_k+j+1) is copied to
   rows[j]; the driven inputs come from `driven` (NULL: none), one row per piece of a step in order
   (one per step without clocks; with clocks, one per piece a tick cuts: orchestrator/clocks.py's
   pieces). Returns the rows made; failure->status is 0 unless a call failed after them. */
EXPORT long ftc_executor_run(struct executor *x, double *values, int64_t k, long count, double *rows,
                             const double *driven, const volatile int *stop, struct failure *failure) {
    size_t width = x->plan.nvalues;
    x->core.values = values;
    failure->status = 0;
    const double *cursor = driven;
    for (long j = 0; j < count; j++) {
        if (core_step(&x->core, k + j, &cursor) != 0) {
            *failure = x->core.failure;
            return j;
        }
        memcpy(rows + (size_t)j * width, values, width * sizeof *values);
        if (!all_finite(values, width) || *stop) return j + 1;
    }
    return count;
}
