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
     makes N sweeps of (write, read, transfer), then per FMU write, leave, read, and transfers;
   * FMI 3.0 clocks (periodic input clocks, orchestrator/clocks.py): a step that holds a tick of
     any clock is cut there (the pieces step as above, time and driven inputs at each piece's
     end); after each piece every FMU with a clock due there, or whose last fmi3DoStep asked for
     an event, gets its event with the inputs it holds (gauss-seidel: those propagated at the
     tick; jacobi: those of the previous communication point, as for any output at the tick):
     fmi3EnterEventMode, fmi3SetClock of the clocks due, fmi3UpdateDiscreteStates until it needs
     no more, fmi3EnterStepMode; then gauss-seidel propagates at the tick, jacobi reads those FMUs'
     outputs and transfers every connection. Ticks are integer nanoseconds from t0.

   The arithmetic of a transfer is compiled without contraction (-ffp-contract=off), so it rounds
   as the Python master's does. */

#define _GNU_SOURCE
#include "core.h"
#include "platform.h"

#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *const NAMES2[FUNCTIONS] = {
    "fmi2DoStep", "fmi2GetReal", "fmi2SetReal", "fmi2SetInteger", "fmi2GetInteger", "fmi2SetBoolean", "fmi2SetString",
    "fmi2SetupExperiment", "fmi2EnterInitializationMode", "fmi2ExitInitializationMode", "fmi2Terminate",
    "fmi2Reset", "fmi2Instantiate", "fmi3EnterEventMode", "fmi3SetClock", "fmi3UpdateDiscreteStates",
    "fmi3EnterStepMode", "fmi3GetIntervalDecimal", "fmi3GetShiftDecimal"};
static const char *const NAMES3[FUNCTIONS] = {
    "fmi3DoStep", "fmi3GetFloat64", "fmi3SetFloat64", "fmi3SetInt32", "fmi3GetInt32", "fmi3SetBoolean", "fmi3SetString",
    "fmi3EnterInitializationMode", "fmi3EnterInitializationMode", "fmi3ExitInitializationMode",
    "fmi3Terminate", "fmi3Reset", "fmi3InstantiateCoSimulation", "fmi3EnterEventMode", "fmi3SetClock",
    "fmi3UpdateDiscreteStates", "fmi3EnterStepMode", "fmi3GetIntervalDecimal", "fmi3GetShiftDecimal"};
static const char *const STATUS2[] = {"fmi2OK", "fmi2Warning", "fmi2Discard", "fmi2Error", "fmi2Fatal",
                                      "fmi2Pending"};
static const char *const STATUS3[] = {"fmi3OK", "fmi3Warning", "fmi3Discard", "fmi3Error", "fmi3Fatal"};

const char *fmu_function(int version, int function) {
    if (function < 0 || function >= FUNCTIONS) return "?";
    return (version == 3 ? NAMES3 : NAMES2)[function];
}

const char *fmu_status(int version, int status) {
    if (status == TERMINATE_SIMULATION) return "terminateSimulation";
    if (status == NEVER_SETTLES) return "discreteStatesNeedUpdate after 100 calls";
    if (status == UNUSABLE_INTERVAL) return "an unusable interval";
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
static const struct symbol CLOCKS3[] = {
    S(enter_event3, "fmi3EnterEventMode", 0), S(set_clock3, "fmi3SetClock", 0),
    S(update3, "fmi3UpdateDiscreteStates", 0), S(enter_step3, "fmi3EnterStepMode", 0),
    S(interval3, "fmi3GetIntervalDecimal", 0), S(shift3, "fmi3GetShiftDecimal", 0)};
#undef S

static int bind_symbols(struct fmu *f, void *library, const struct symbol *symbols, size_t n, int lifecycle,
                        char *why, size_t size) {
    for (size_t j = 0; j < n; j++) {
        if (symbols[j].lifecycle && !lifecycle) continue;
        void *found = ftc_library_symbol(library, symbols[j].name);
        if (!found) {
            snprintf(why, size, "the FMU's library has no %s (FMI %d.0 Co-Simulation)", symbols[j].name,
                     f->version);
            return -1;
        }
        memcpy((char *)f + symbols[j].offset, &found, sizeof found);
    }
    return 0;
}

int fmu_bind_clocks(struct fmu *f, void *library, char *why, size_t size) {
    if (f->version != 3) {
        snprintf(why, size, "clocks need an FMI 3.0 FMU");
        return -1;
    }
    f->event_mode = 1;
    return bind_symbols(f, library, CLOCKS3, sizeof CLOCKS3 / sizeof *CLOCKS3, 0, why, size);
}

int fmu_bind(struct fmu *f, void *library, int version, int lifecycle, char *why, size_t size) {
    const struct symbol *symbols = version == 3 ? SYMBOLS3 : SYMBOLS2;
    size_t n = version == 3 ? sizeof SYMBOLS3 / sizeof *SYMBOLS3 : sizeof SYMBOLS2 / sizeof *SYMBOLS2;
    f->version = version;
    return bind_symbols(f, library, symbols, n, lifecycle, why, size);
}

/* ---- the calls, whatever the version --------------------------------------------------------- */

static int do_step(struct fmu *f, double t, double h) {
    if (f->version == 2) return f->do_step2(f->instance, t, h, fmi2True);
    bool event = false, terminate = false, early = false;
    double last = t;
    int status = f->do_step3(f->instance, t, h, true, &event, &terminate, &early, &last);
    f->event_requested = event;
    return status;
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

/* One piece of a step, from `start` to `end` (ns), the driven inputs at its end from *driven. */
static int piece(struct core *x, int64_t start, int64_t end, const double **driven) {
    const struct plan *p = x->plan;
    double t = (double)start / 1e9, t_next = (double)end / 1e9, h = t_next - t;
    const double *row = driven ? *driven : NULL;
    if (row) *driven = row + p->ndriven;
    if (p->jacobi) return step_jacobi(x, t, h, t_next, row);
    for (size_t i = 0; i < p->ncomponents; i++) {
        int s = check(x, (int)i, DO_STEP, do_step(&x->fmus[i], t, h), t);
        if (s) return s;
    }
    x->values[0] = t_next;
    int s = drive(x, row, t_next);
    return s ? s : core_propagate(x, t_next);
}

/* ---- clocks ----------------------------------------------------------------------------------- */


/* The first tick of clock `c` at or after `t` (ns; a run started at `t0`); INT64_MAX for a clock
   whose interval is not known (core_ask_clocks fills every one before the first step). */
static int64_t tick_at_or_after(const struct clock *c, int64_t t, int64_t t0) {
    int64_t first = t0 + c->shift;
    if (c->interval <= 0) return INT64_MAX;
    if (t <= first) return first;
    return first + (t - first + c->interval - 1) / c->interval * c->interval; /* the ceiling */
}

static int64_t next_tick(const struct core *x, int64_t after) {
    int64_t next = INT64_MAX;
    for (size_t j = 0; j < x->plan->nclocks; j++) {
        int64_t tick = tick_at_or_after(&x->clocks[j], after + 1, x->plan->t0);
        if (tick < next) next = tick;
    }
    return next;
}

static int fail_as(struct core *x, int component, int function, int status, double t) {
    x->failure = (struct failure){component, function, status, t};
    return status;
}

/* One FMU's event at `t`: Event Mode (unless still in it), its clocks `active` set, its discrete
   states updated until it needs no more, Step Mode (as orchestrator/fmi.py's Instance.tick). */
static int tick(struct core *x, int i, double t, const fmi3ValueReference *active, size_t n) {
    struct fmu *f = &x->fmus[i];
    int s = f->in_event ? 0 : check(x, i, ENTER_EVENT, f->enter_event3(f->instance), t);
    if (s) return s;
    f->in_event = 1;
    fmi3Clock on[MAX_CLOCKS];
    for (size_t j = 0; j < n; j++) on[j] = true;
    s = n ? check(x, i, SET_CLOCK, f->set_clock3(f->instance, active, n, on), t) : 0;
    for (int u = 0; !s; u++) {
        if (u == UPDATES) return fail_as(x, i, UPDATE_DISCRETE, NEVER_SETTLES, t);
        bool again = false, terminate = false, nominals = false, values = false, defined = false;
        double next = 0.0;
        s = check(x, i, UPDATE_DISCRETE,
                  f->update3(f->instance, &again, &terminate, &nominals, &values, &defined, &next), t);
        if (!s && terminate) return fail_as(x, i, UPDATE_DISCRETE, TERMINATE_SIMULATION, t);
        if (!again) break;
    }
    if (!s) s = check(x, i, ENTER_STEP, f->enter_step3(f->instance), t);
    if (!s) f->in_event = 0;
    return s;
}

/* The events at `t_ns`: every FMU with a clock due there, whose last step asked for one, or (at
   t0, `initial`) that has clocks; then their outputs passed on. */
static int events(struct core *x, int64_t t_ns, int initial) {
    const struct plan *p = x->plan;
    double t = (double)t_ns / 1e9;
    int any = 0;
    for (size_t j = 0; j < p->nclocks;) {
        int i = x->clocks[j].component;
        fmi3ValueReference active[MAX_CLOCKS];
        size_t n = 0;
        for (; j < p->nclocks && x->clocks[j].component == i; j++)
            if (tick_at_or_after(&x->clocks[j], t_ns, p->t0) == t_ns) active[n++] = x->clocks[j].vr;
        struct fmu *f = &x->fmus[i];
        if (!n && !initial && !f->event_requested) continue;
        /* its inputs as set before: gauss-seidel's of t, jacobi's of the previous communication point */
        int s = tick(x, i, t, active, n);
        if (s) return s;
        f->ticked = p->jacobi; /* jacobi reads its outputs after */
        any = 1;
    }
    if (!any) return 0;
    if (!p->jacobi) return core_propagate(x, t);
    for (size_t i = 0; i < p->ncomponents; i++) {
        if (!x->fmus[i].ticked) continue;
        x->fmus[i].ticked = 0;
        int s = get_batch(x, &p->components[i].outputs, t);
        if (s) return s;
    }
    transfer_plain_first(x->values, p->transfers, p->ntransfers);
    return 0;
}

int core_step(struct core *x, int64_t k, const double **driven) {
    const struct plan *p = x->plan;
    int64_t start = p->t0 + p->h * k, end = start + p->h;
    if (!p->nclocks) return piece(x, start, end, driven);
    while (start < end) {
        int64_t tick = next_tick(x, start), stop = tick < end ? tick : end;
        int s = piece(x, start, stop, driven);
        if (!s) s = events(x, stop, 0);
        if (s) return s;
        start = stop;
    }
    return 0;
}

int core_ask_clocks(struct core *x, double t0) {
    for (size_t j = 0; j < x->plan->nclocks; j++) {
        struct clock *c = &x->clocks[j];
        if (c->interval) continue;
        struct fmu *f = &x->fmus[c->component];
        double interval = 0.0, shift = 0.0;
        fmi3IntervalQualifier qualifier = fmi3IntervalNotYetKnown;
        int s = check(x, c->component, GET_INTERVAL, f->interval3(f->instance, &c->vr, 1, &interval, &qualifier),
                      t0);
        if (!s) s = check(x, c->component, GET_SHIFT, f->shift3(f->instance, &c->vr, 1, &shift), t0);
        if (s) return s;
        /* as orchestrator/clocks.py's InputClock.asked: rounded to nanoseconds (half to even, as
           Python's round), at least 1 ns, a shift at least 0 */
        double ns = interval * 1e9, shifted = shift * 1e9;
        if (!(ns > 0.5 && ns < 9.2e18 && shifted >= 0.0 && shifted < 9.2e18))
            return fail_as(x, c->component, GET_INTERVAL, UNUSABLE_INTERVAL, t0);
        c->interval = (int64_t)llrint(ns);
        c->shift = (int64_t)llrint(shifted);
    }
    return 0;
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
    f->in_event = f->event_mode; /* with event mode used, the FMU is in Event Mode now */
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
    int s;
    if (x->plan->jacobi) {
        s = exit_jacobi(x, t0);
    } else {
        s = core_propagate(x, t0);
        for (size_t i = 0; !s && i < x->plan->ncomponents; i++) s = leave(x, i, t0);
        if (!s) s = core_propagate(x, t0);
    }
    return s || !x->plan->nclocks ? s : events(x, x->plan->t0, 1);
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
