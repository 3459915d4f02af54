/* SPDX-License-Identifier: BSD-2-Clause */
/* The core of the C executors (see core.h): the plan's steps on embedded FMI 2.0 and 3.0 FMUs,
   the same calls with the same arguments in the same order as orchestrator/master.py:

   * gauss-seidel, each step: every FMU's doStep(t_k, t_k+1 - t_k); time t_k+1; the driven inputs
     at t_k+1; the propagation at t_k+1 (read a component's outputs; transfer connections into
     some of its inputs, value = factor * source + offset, and write them);
   * jacobi (libcosim's algorithm), each step: per FMU write its connected inputs, doStep, read
     its outputs; time t_k+1; transfer every connection; the driven inputs at t_k+1;
   * initialization: per FMU start values, setup, initialization mode, start values again; then
     gauss-seidel propagates, every FMU leaves initialization mode, and it propagates again; jacobi
     makes N sweeps of (write, read, transfer), then per FMU write, leave, read, and transfers.

   The arithmetic of a transfer is compiled without contraction (-ffp-contract=off), so it rounds
   as the Python master's does. */

#define _GNU_SOURCE
#include "core.h"
#include "platform.h"

#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *const NAMES2[FUNCTIONS] = {
    "fmi2DoStep", "fmi2GetReal", "fmi2SetReal", "fmi2SetInteger", "fmi2GetInteger", "fmi2SetBoolean", "fmi2SetString",
    "fmi2SetupExperiment", "fmi2EnterInitializationMode", "fmi2ExitInitializationMode", "fmi2Terminate",
    "fmi2Reset", "fmi2Instantiate"};
static const char *const NAMES3[FUNCTIONS] = {
    "fmi3DoStep", "fmi3GetFloat64", "fmi3SetFloat64", "fmi3SetInt32", "fmi3GetInt32", "fmi3SetBoolean", "fmi3SetString",
    "fmi3EnterInitializationMode", "fmi3EnterInitializationMode", "fmi3ExitInitializationMode",
    "fmi3Terminate", "fmi3Reset", "fmi3InstantiateCoSimulation"};
static const char *const STATUS2[] = {"fmi2OK", "fmi2Warning", "fmi2Discard", "fmi2Error", "fmi2Fatal",
                                      "fmi2Pending"};
static const char *const STATUS3[] = {"fmi3OK", "fmi3Warning", "fmi3Discard", "fmi3Error", "fmi3Fatal"};

const char *fmu_function(int version, int function) {
    if (function < 0 || function >= FUNCTIONS) return "?";
    return (version == 3 ? NAMES3 : NAMES2)[function];
}

const char *fmu_status(int version, int status) {
    if (status < 0) return "NULL";
    if (version == 3) return status < 5 ? STATUS3[status] : "fmi3 status ?";
    return status < 6 ? STATUS2[status] : "fmi2 status ?";
}

/* ---- binding ------------------------------------------------------------------------------------ */

struct symbol {
    const char *name;
    size_t offset; /* of the function pointer in struct fmu */
    int lifecycle; /* needed only where the caller instantiates (the container) */
};

#define S(field, name, lifecycle) {name, offsetof(struct fmu, field), lifecycle}
static const struct symbol SYMBOLS2[] = {
    S(do_step2, "fmi2DoStep", 0),        S(get_real2, "fmi2GetReal", 0),
    S(set_real2, "fmi2SetReal", 0),      S(set_integer2, "fmi2SetInteger", 0),
    S(get_integer2, "fmi2GetInteger", 0),
    S(set_boolean2, "fmi2SetBoolean", 1), S(set_string2, "fmi2SetString", 1),
    S(setup2, "fmi2SetupExperiment", 1), S(enter2, "fmi2EnterInitializationMode", 1),
    S(exit2, "fmi2ExitInitializationMode", 1), S(terminate2, "fmi2Terminate", 1),
    S(reset2, "fmi2Reset", 1),           S(instantiate2, "fmi2Instantiate", 1),
    S(free2, "fmi2FreeInstance", 1),     S(debug2, "fmi2SetDebugLogging", 1)};
static const struct symbol SYMBOLS3[] = {
    S(do_step3, "fmi3DoStep", 0),        S(get_real3, "fmi3GetFloat64", 0),
    S(set_real3, "fmi3SetFloat64", 0),   S(set_integer3, "fmi3SetInt32", 1),
    S(set_boolean3, "fmi3SetBoolean", 1), S(set_string3, "fmi3SetString", 1),
    S(enter3, "fmi3EnterInitializationMode", 1), S(exit3, "fmi3ExitInitializationMode", 1),
    S(terminate3, "fmi3Terminate", 1),   S(reset3, "fmi3Reset", 1),
    S(instantiate3, "fmi3InstantiateCoSimulation", 1), S(free3, "fmi3FreeInstance", 1),
    S(debug3, "fmi3SetDebugLogging", 1)};
#undef S

int fmu_bind(struct fmu *f, void *library, int version, int lifecycle, char *why, size_t size) {
    const struct symbol *symbols = version == 3 ? SYMBOLS3 : SYMBOLS2;
    size_t n = version == 3 ? sizeof SYMBOLS3 / sizeof *SYMBOLS3 : sizeof SYMBOLS2 / sizeof *SYMBOLS2;
    f->version = version;
    for (size_t j = 0; j < n; j++) {
        if (symbols[j].lifecycle && !lifecycle) continue;
        void *found = ftc_library_symbol(library, symbols[j].name);
        if (!found) {
            snprintf(why, size, "the FMU's library has no %s (FMI %d.0 Co-Simulation)", symbols[j].name, version);
            return -1;
        }
        memcpy((char *)f + symbols[j].offset, &found, sizeof found);
    }
    return 0;
}

/* ---- the calls, whatever the version --------------------------------------------------------- */

static int do_step(struct fmu *f, double t, double h) {
    if (f->version == 2) return f->do_step2(f->instance, t, h, fmi2True);
    bool event = false, terminate = false, early = false;
    double last = t;
    return f->do_step3(f->instance, t, h, true, &event, &terminate, &early, &last);
}

static int get_real(struct fmu *f, const unsigned int *vr, size_t n, double *v) {
    return f->version == 2 ? f->get_real2(f->instance, vr, n, v) : f->get_real3(f->instance, vr, n, v, n);
}

static int set_real(struct fmu *f, const unsigned int *vr, size_t n, const double *v) {
    return f->version == 2 ? f->set_real2(f->instance, vr, n, v) : f->set_real3(f->instance, vr, n, v, n);
}

static int set_booleans3(struct fmu *f, const struct starts *s) {
    bool *values = calloc(s->n ? s->n : 1, sizeof *values);
    if (!values) return fmi2Error;
    for (size_t j = 0; j < s->n; j++) values[j] = s->ints[j] != 0;
    int status = f->set_boolean3(f->instance, s->vr, s->n, values, s->n);
    free(values);
    return status;
}

static int set_starts(struct fmu *f, const struct starts *s, int *function) {
    int three = f->version == 3;
    switch (s->type) {
    case 'r':
        *function = SET_REAL;
        return set_real(f, s->vr, s->n, s->reals);
    case 'i':
        *function = SET_INTEGER;
        return three ? f->set_integer3(f->instance, s->vr, s->n, s->ints, s->n)
                     : f->set_integer2(f->instance, s->vr, s->n, s->ints);
    case 'b':
        *function = SET_BOOLEAN;
        return three ? set_booleans3(f, s) : (int)f->set_boolean2(f->instance, s->vr, s->n, s->ints);
    default:
        *function = SET_STRING;
        return three ? f->set_string3(f->instance, s->vr, s->n, (const char *const *)s->strings, s->n)
                     : f->set_string2(f->instance, s->vr, s->n, (const char *const *)s->strings);
    }
}

int fmu_set_debug_logging(struct fmu *f, int on, size_t n, const char *const categories[]) {
    return f->version == 2 ? f->debug2(f->instance, on, n, categories)
                           : f->debug3(f->instance, on != 0, n, categories);
}

int fmu_reset(struct fmu *f) { return f->version == 2 ? f->reset2(f->instance) : f->reset3(f->instance); }

void fmu_free(struct fmu *f) {
    if (!f->instance || f->broken) return;
    if (f->version == 2) f->free2(f->instance);
    else f->free3(f->instance);
    f->instance = NULL;
}

/* ---- the plan on them ------------------------------------------------------------------------ */

/* Records a failed call (status >= fmi2Discard) and returns its status; 0 for one that did not fail. */
static int check(struct core *x, int component, int function, int status, double t) {
    if (status < fmi2Discard) return 0;
    if (status >= fmi2Fatal) x->fmus[component].broken = 1;
    x->failure = (struct failure){component, function, status, t};
    return status;
}

static void transfer(double *v, const struct transfer *t, size_t n) {
    for (size_t j = 0; j < n; j++) v[t[j].dst] = t[j].factor * v[t[j].src] + t[j].offset;
}

static void transfer_plain_first(double *v, const struct transfer *t, size_t n) {
    /* the plan lists the copies first; a copy is exact (1 * v + 0 is v, also for -0.0 and nan:
       it is still written as a copy so that no arithmetic touches the value) */
    for (size_t j = 0; j < n; j++) {
        if (t[j].factor == 1.0 && t[j].offset == 0.0) v[t[j].dst] = v[t[j].src];
        else transfer(v, &t[j], 1);
    }
}

/* The integer tail of a batch (FMI 2.0 Integer and Enumeration variables, which the plan allows
   only there): fmi2GetInteger/fmi2SetInteger through an int buffer, in chunks; a 32-bit int is
   exact in the float64 value buffer. */
#define CHUNK 64
static int integers(struct core *x, const struct batch *b, int set, double t) {
    struct fmu *f = &x->fmus[b->component];
    size_t first = b->n - b->ints;
    int buffer[CHUNK];
    if (!f->get_integer2 || !f->set_integer2) return check(x, b->component, set ? SET_INTEGER : GET_INTEGER,
                                                           fmi2Error, t); /* FMI 3.0: not in a plan */
    for (size_t j = 0; j < b->ints; j += CHUNK) {
        size_t m = b->ints - j < CHUNK ? b->ints - j : CHUNK;
        const unsigned int *vr = b->vr + first + j;
        double *v = x->values + b->start + first + j;
        int s;
        if (set) {
            for (size_t i = 0; i < m; i++) buffer[i] = (int)v[i];
            s = check(x, b->component, SET_INTEGER, f->set_integer2(f->instance, vr, m, buffer), t);
        } else {
            s = check(x, b->component, GET_INTEGER, f->get_integer2(f->instance, vr, m, buffer), t);
            for (size_t i = 0; !s && i < m; i++) v[i] = buffer[i];
        }
        if (s) return s;
    }
    return 0;
}

static int get_batch(struct core *x, const struct batch *b, double t) {
    size_t n = b->n - b->ints;
    struct fmu *f = &x->fmus[b->component];
    int s = n ? check(x, b->component, GET_REAL, get_real(f, b->vr, n, x->values + b->start), t) : 0;
    return s || !b->ints ? s : integers(x, b, 0, t);
}

static int set_batch(struct core *x, const struct batch *b, double t) {
    size_t n = b->n - b->ints;
    struct fmu *f = &x->fmus[b->component];
    int s = n ? check(x, b->component, SET_REAL, set_real(f, b->vr, n, x->values + b->start), t) : 0;
    return s || !b->ints ? s : integers(x, b, 1, t);
}

int core_propagate(struct core *x, double t) {
    const struct plan *p = x->plan;
    for (size_t j = 0; j < p->ncalls; j++) {
        const struct call *c = &p->calls[j];
        int s;
        if (c->is_set) {
            transfer_plain_first(x->values, c->transfers, c->ntransfers);
            s = set_batch(x, &c->io, t);
        } else {
            s = get_batch(x, &c->io, t);
        }
        if (s) return s;
    }
    return 0;
}

static int drive(struct core *x, const double *row, double t) {
    const struct plan *p = x->plan;
    if (!row) return 0;
    for (size_t i = 0; i < p->ncomponents; i++) {
        const struct batch *b = &p->components[i].driven;
        memcpy(x->values + b->start, row, b->n * sizeof *row);
        row += b->n;
        int s = set_batch(x, b, t);
        if (s) return s;
    }
    return 0;
}

static int step_jacobi(struct core *x, double t, double h, double t_next, const double *driven) {
    const struct plan *p = x->plan;
    for (size_t i = 0; i < p->ncomponents; i++) {
        const struct part *c = &p->components[i];
        int s = set_batch(x, &c->inputs, t);
        if (!s) s = check(x, (int)i, DO_STEP, do_step(&x->fmus[i], t, h), t);
        if (!s) s = get_batch(x, &c->outputs, t);
        if (s) return s;
    }
    x->values[0] = t_next;
    transfer_plain_first(x->values, p->transfers, p->ntransfers);
    return drive(x, driven, t_next);
}

int core_step(struct core *x, int64_t k, const double *driven) {
    const struct plan *p = x->plan;
    double t = plan_time(p, k), t_next = plan_time(p, k + 1), h = t_next - t;
    if (p->jacobi) return step_jacobi(x, t, h, t_next, driven);
    for (size_t i = 0; i < p->ncomponents; i++) {
        int s = check(x, (int)i, DO_STEP, do_step(&x->fmus[i], t, h), t);
        if (s) return s;
    }
    x->values[0] = t_next;
    int s = drive(x, driven, t_next);
    return s ? s : core_propagate(x, t_next);
}

static int apply_starts(struct core *x, size_t i, double t) {
    const struct plan *p = x->plan;
    for (size_t j = 0; j < p->nstarts; j++) {
        const struct starts *s = &p->starts[j];
        if (s->component != (int)i) continue;
        int function = SET_REAL;
        int status = set_starts(&x->fmus[i], s, &function);
        if (check(x, (int)i, function, status, t)) return status;
    }
    return 0;
}

static int setup(struct core *x, size_t i, double t0, int stop_defined, double stop) {
    struct fmu *f = &x->fmus[i];
    if (f->version == 3)
        return check(x, (int)i, ENTER_INITIALIZATION,
                     f->enter3(f->instance, false, 0.0, t0, stop_defined != 0, stop), t0);
    int s = check(x, (int)i, SETUP_EXPERIMENT, f->setup2(f->instance, fmi2False, 0.0, t0, stop_defined, stop), t0);
    return s ? s : check(x, (int)i, ENTER_INITIALIZATION, f->enter2(f->instance), t0);
}

int core_enter_initialization(struct core *x, double t0, int stop_defined, double stop) {
    x->values[0] = t0;
    for (size_t i = 0; i < x->plan->ncomponents; i++) {
        int s = apply_starts(x, i, t0);
        if (!s) s = setup(x, i, t0, stop_defined, stop);
        if (!s) s = apply_starts(x, i, t0);
        if (s) return s;
    }
    return 0;
}

static int leave(struct core *x, size_t i, double t0) {
    struct fmu *f = &x->fmus[i];
    int status = f->version == 2 ? f->exit2(f->instance) : f->exit3(f->instance);
    return check(x, (int)i, EXIT_INITIALIZATION, status, t0);
}

static int exit_jacobi(struct core *x, double t0) {
    const struct plan *p = x->plan;
    for (size_t sweep = 0; sweep < p->ncomponents; sweep++) {
        for (size_t i = 0; i < p->ncomponents; i++) {
            int s = sweep ? set_batch(x, &p->components[i].inputs, t0) : 0;
            if (!s) s = get_batch(x, &p->components[i].outputs, t0);
            if (s) return s;
        }
        transfer_plain_first(x->values, p->transfers, p->ntransfers);
    }
    for (size_t i = 0; i < p->ncomponents; i++) {
        int s = set_batch(x, &p->components[i].inputs, t0);
        if (!s) s = leave(x, i, t0);
        if (!s) s = get_batch(x, &p->components[i].outputs, t0);
        if (s) return s;
    }
    transfer_plain_first(x->values, p->transfers, p->ntransfers);
    return 0;
}

int core_exit_initialization(struct core *x, double t0) {
    if (x->plan->jacobi) return exit_jacobi(x, t0);
    int s = core_propagate(x, t0);
    for (size_t i = 0; !s && i < x->plan->ncomponents; i++) s = leave(x, i, t0);
    return s ? s : core_propagate(x, t0);
}

int core_terminate(struct core *x, double t) {
    int worst = 0;
    for (size_t i = 0; i < x->plan->ncomponents; i++) {
        struct fmu *f = &x->fmus[i];
        int status = f->version == 2 ? f->terminate2(f->instance) : f->terminate3(f->instance);
        if (status >= fmi2Discard && !worst) worst = check(x, (int)i, TERMINATE, status, t);
        else if (status >= fmi2Fatal) f->broken = 1;
    }
    return worst;
}

int core_set_input(struct core *x, int i, unsigned int vr, const double *value, double t) {
    return check(x, i, SET_REAL, set_real(&x->fmus[i], &vr, 1, value), t);
}
