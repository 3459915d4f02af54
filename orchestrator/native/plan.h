/* SPDX-License-Identifier: BSD-2-Clause */
/* The plan of a run as the C executors hold it (read by plan.c from the text that
   orchestrator/plan.py writes: Plan.text). Indices only: every batch is a contiguous slice of the
   value buffer [time, inputs..., outputs...]. */

#ifndef FTC_PLAN_H
#define FTC_PLAN_H

#include <stddef.h>
#include <stdint.h>

#define PLAN_VERSION "4"
#define PLAN_TEXT 4096
#define MAX_CLOCKS 1024 /* per plan: the core keeps each step's clocks on its stack */

/* One batched get or set of a component: value references vr <-> values[start .. start + n); the
   last `ints` are FMI 2.0 Integer or Enumeration variables (fmi2GetInteger/fmi2SetInteger). */
struct batch {
    int component;
    size_t start, n, ints;
    unsigned int *vr;
};

/* A connection: values[dst] = factor * values[src] + offset (a copy when factor 1, offset 0). */
struct transfer {
    size_t dst, src;
    double factor, offset;
};

/* One operation of the gauss-seidel propagation: read a component's outputs, or apply the
   transfers and write some of its inputs. */
struct call {
    int is_set;
    struct batch io;
    size_t ntransfers;
    struct transfer *transfers;
};

/* One call setting start values of one type ('r', 'i', 'b', 's') on one component. */
struct starts {
    int component;
    char type;
    size_t n;
    unsigned int *vr;
    double *reals;  /* 'r' */
    int *ints;      /* 'i', 'b' */
    char **strings; /* 's' */
};

/* An embedded FMU: where it is (folder under the container's resources/fmus; empty where the
   caller binds an instance it made), its FMI major version and its batches. */
struct part {
    char *name, *folder, *identifier, *guid;
    int version; /* 2 or 3 */
    struct batch inputs, outputs, driven; /* connected inputs (jacobi), every output, driven inputs */
};

/* A variable of the exported container: the host's value reference -> a buffer slot (outputs,
   inputs) and, for inputs, the component's input; for parameters, a start value (call, position). */
struct exposed {
    unsigned int vr;
    char kind; /* 'o' output, 'i' input, 'p' parameter */
    char type; /* 'r', 'i', 'b' */
    size_t slot;
    int component;
    unsigned int inner;
    int feedthrough; /* 'i': an exposed output depends on it (gauss-seidel propagates again) */
    size_t call, position;
};

/* A periodic input clock of an FMI 3.0 component (event mode used): ticks at t0 + shift + j interval
   (nanoseconds); interval 0: a fixed clock whose interval and shift the FMU gives in Initialization
   Mode (core_ask_clocks). */
struct clock {
    int component;
    unsigned int vr;
    int64_t interval, shift;
};

struct plan {
    char guid[256];
    int jacobi;
    int64_t t0, h, n; /* nanoseconds; n steps */
    size_t nvalues, ncomponents, nstarts, ncalls, nexposed, ntransfers, ndriven;
    double *initial;
    struct part *components;
    struct starts *starts;
    struct call *calls;
    struct transfer *transfers; /* every connection (jacobi) */
    struct exposed *exposed;
    size_t nclocks;
    struct clock *clocks; /* in component order */
};

/* Reads the plan text (NUL-terminated); 0, or -1 with `why` filled (naming `label` and the line). */
int plan_read(const char *text, const char *label, struct plan *p, char *why, size_t size);

/* Reads the plan file `path`; as plan_read. */
int plan_load(const char *path, struct plan *p, char *why, size_t size);

void plan_free(struct plan *p);

/* Whether component i has clocks (it is driven in event mode). */
int plan_clocked(const struct plan *p, int i);

/* t_k in seconds, rounded once from integer nanoseconds. */
double plan_time(const struct plan *p, int64_t k);

#endif
