/* SPDX-License-Identifier: BSD-2-Clause */
/* The clocked twin's FMI 3.0 clock (fmu_src/toolchain/clocked.py writes its model description):
   one periodic input clock, FTC_CLOCK_VR, whose fixed interval is the parameter FTC_INTERVAL_VR
   (sample_time), clocking every output. Compiled only into the twin (the build passes
   -DFTC_CLOCK_VR=ftc_clock_vr -DFTC_INTERVAL_VR=ftc_interval_vr, FMI 3.0 value references that
   are constants of the variable table's object, fmi3.h); the plain FMI 3.0
   variant refuses clocks (fmi3_refused.c).

   How it maps on the FMI 2.0 slave, which steps its law over a communication step with its inputs
   held (the controller: outputs from the state and the inputs, then RK4 over the step):
   * at an activation (fmi3SetClock in Event Mode, then fmi3UpdateDiscreteStates) the slave is
     first brought from the last activation to now: one fmi2DoStep over the time elapsed (the
     communication steps since, summed) with the inputs of the last activation set again (the
     law's inputs are held between activations); then the outputs are read for the inputs set now
     and held, and those inputs kept for the next step. Stepping lazily over the time that really
     elapsed gives, where the importer steps once per interval, the very fmi2DoStep calls the
     unclocked variant gets: the same bits;
   * in Step Mode fmi3DoStep advances time only: the law is not evaluated between activations and
     the outputs keep the values of the last one (before the first: those of Initialization Mode);
   * fmi3GetIntervalDecimal gives sample_time (fmi3IntervalChanged the first time, then
     fmi3IntervalUnchanged), fmi3GetShiftDecimal 0; neither may be set (the interval is the
     parameter's: set sample_time).
   Without eventModeUsed the twin cannot be activated, so instantiation refuses, naming the plain
   variant. FMU states are not offered (canGetAndSetFMUState="false"). */

#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "description.h"
#include "fmi3.h"

#if !defined FTC_CLOCK_VR || !defined FTC_INTERVAL_VR
#error "compile the clocked twin with -DFTC_CLOCK_VR=ftc_clock_vr -DFTC_INTERVAL_VR=ftc_interval_vr"
#endif

/* Variables the clock works on: the Float64 outputs it holds, the Float64 inputs it samples. */
struct variables {
    size_t n;
    fmi2ValueReference *vr; /* FMI 2.0 value references */
    double *value;
};

struct clock3 {
    bool active;      /* fmi3SetClock(true) in this Event Mode */
    bool evaluated;   /* this activation has run (fmi3UpdateDiscreteStates) */
    bool asked;       /* the interval was given once (then: unchanged) */
    bool held_any;    /* the outputs are held (from Exit Initialization Mode on) */
    bool activated;   /* an activation has run: the slave's state is at its time */
    double last;      /* the time of the last activation */
    double elapsed;   /* the communication steps since, summed */
    struct variables outputs, inputs, now; /* held outputs; inputs sampled then; inputs now */
};

static void release_variables(struct variables *v) {
    free(v->vr);
    free(v->value);
}

void ftc_clock_free(struct clock3 *k) {
    if (!k) return;
    release_variables(&k->outputs);
    release_variables(&k->inputs);
    release_variables(&k->now);
    free(k);
}

/* The Float64 variables of causality `causality` ('o', 'i') of the table; 0, -1 out of memory. */
static int collect(struct variables *v, char causality) {
    const struct ftc_model *m = &ftc_description;
    for (size_t j = 0; j < m->n; j++) v->n += m->variables[j].causality == causality && m->variables[j].type == 'r';
    v->vr = calloc(v->n ? v->n : 1, sizeof *v->vr);
    v->value = calloc(v->n ? v->n : 1, sizeof *v->value);
    if (!v->vr || !v->value) return -1;
    size_t o = 0;
    for (size_t j = 0; j < m->n; j++)
        if (m->variables[j].causality == causality && m->variables[j].type == 'r')
            v->vr[o++] = m->variables[j].vr - FTC_VR_OFFSET;
    return 0;
}

struct clock3 *ftc_clock_new(void) {
    struct clock3 *k = calloc(1, sizeof *k);
    if (!k) return NULL;
    if (collect(&k->outputs, 'o') || collect(&k->inputs, 'i') || collect(&k->now, 'i')) {
        ftc_clock_free(k);
        return NULL;
    }
    return k;
}

static fmi2Status get(struct instance3 *i, struct variables *v) {
    return v->n ? fmi2GetReal(i->c, v->vr, v->n, v->value) : fmi2OK;
}

static fmi2Status set(struct instance3 *i, const struct variables *v) {
    return v->n ? fmi2SetReal(i->c, v->vr, v->n, v->value) : fmi2OK;
}

static fmi2Status worse(fmi2Status a, fmi2Status b) { return a > b ? a : b; }

/* The outputs read now, held until the next activation. */
static fmi2Status hold(struct instance3 *i) {
    fmi2Status status = get(i, &i->clock->outputs);
    if (status < fmi2Discard) i->clock->held_any = true;
    return status;
}

fmi2Status ftc_clock_initialized(struct instance3 *i) { return hold(i); }

void ftc_clock_step(struct instance3 *i, double h) { i->clock->elapsed += h; }

/* The position of FMI 2.0 value reference `vr` among the held outputs, or their count. */
static size_t held_at(const struct variables *v, fmi2ValueReference vr) {
    size_t o = 0;
    while (o < v->n && v->vr[o] != vr) o++;
    return o;
}

int ftc_clock_get(struct instance3 *i, const fmi2ValueReference vr[], size_t n, fmi3Float64 values[]) {
    struct clock3 *k = i->clock;
    if (!k || !k->held_any || i->mode == INITIALIZATION) return 0;
    for (size_t j = 0; j < n; j++)
        if (held_at(&k->outputs, vr[j]) == k->outputs.n) return 0; /* not a clocked output: the slave answers */
    for (size_t j = 0; j < n; j++) values[j] = k->outputs.value[held_at(&k->outputs, vr[j])];
    return 1;
}

/* The slave's state brought from the last activation to now: one step over the time elapsed, with
   the inputs of the last activation held (set again for it; the inputs of now after). */
static fmi2Status advance(struct instance3 *i) {
    struct clock3 *k = i->clock;
    fmi2Status status = get(i, &k->now);
    if (status < fmi2Discard) status = worse(status, set(i, &k->inputs));
    if (status < fmi2Discard) status = worse(status, fmi2DoStep(i->c, k->last, k->elapsed, fmi2True));
    if (status < fmi2Discard) status = worse(status, set(i, &k->now));
    return status;
}

/* fmi3UpdateDiscreteStates with the clock active: the activation, once. The state is advanced
   lazily, at the next activation, over the time that really elapsed: so where the importer steps
   once per interval the slave gets the very steps the unclocked FMU gets (the same bits). */
fmi2Status ftc_clock_update(struct instance3 *i) {
    struct clock3 *k = i->clock;
    if (!k->active || k->evaluated) return fmi2OK;
    fmi2Status status = k->activated ? advance(i) : fmi2OK;
    if (status < fmi2Discard) status = worse(status, hold(i));
    if (status < fmi2Discard) status = worse(status, get(i, &k->inputs)); /* sampled now, held for the step */
    if (status < fmi2Discard) {
        k->evaluated = k->activated = true;
        k->last = i->time;
        k->elapsed = 0.0;
    }
    return status;
}

/* Leaving Event Mode: the clock is inactive again. */
void ftc_clock_leave(struct instance3 *i) {
    i->clock->active = false;
    i->clock->evaluated = false;
}

/* Error (and one message) unless the `n` value references are the clock's, with their arrays. */
static fmi3Status only_the_clock(struct instance3 *i, const char *function, const fmi3ValueReference vr[],
                                 size_t n, const void *values) {
    char reason[160];
    if (n && (!vr || !values)) {
        snprintf(reason, sizeof reason, "%zu value references and a NULL array", n);
        return refuse3(i, function, reason);
    }
    for (size_t j = 0; j < n; j++)
        if (vr[j] != FTC_CLOCK_VR) {
            snprintf(reason, sizeof reason, "value reference %u is not a clock (the only clock: %u)", vr[j],
                     (unsigned)FTC_CLOCK_VR);
            return refuse3(i, function, reason);
        }
    return fmi3OK;
}

EXPORT3 fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, const fmi3Clock values[]) {
    struct instance3 *i = instance;
    if (check_mode(i, "fmi3SetClock", 1 << EVENT)) return fmi3Error;
    if (only_the_clock(i, "fmi3SetClock", valueReferences, nValueReferences, values))
        return fmi3Error;
    for (size_t j = 0; j < nValueReferences; j++) {
        if (values[j] && !i->clock->active) i->clock->evaluated = false;
        i->clock->active = values[j];
    }
    return fmi3OK;
}

EXPORT3 fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, fmi3Clock values[]) {
    struct instance3 *i = instance;
    if (check_mode(i, "fmi3GetClock", 1 << EVENT)) return fmi3Error;
    if (only_the_clock(i, "fmi3GetClock", valueReferences, nValueReferences, values))
        return fmi3Error;
    for (size_t j = 0; j < nValueReferences; j++) values[j] = i->clock->active;
    return fmi3OK;
}

EXPORT3 fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                          size_t nValueReferences, fmi3Float64 intervals[],
                                          fmi3IntervalQualifier qualifiers[]) {
    struct instance3 *i = instance;
    if (check_mode(i, "fmi3GetIntervalDecimal", 1 << INITIALIZATION | 1 << EVENT)) return fmi3Error;
    if (nValueReferences && !qualifiers) return refuse3(i, "fmi3GetIntervalDecimal", "qualifiers is NULL");
    if (only_the_clock(i, "fmi3GetIntervalDecimal", valueReferences, nValueReferences, intervals))
        return fmi3Error;
    fmi2ValueReference parameter = FTC_INTERVAL_VR - FTC_VR_OFFSET;
    for (size_t j = 0; j < nValueReferences; j++) {
        fmi2Status status = fmi2GetReal(i->c, &parameter, 1, &intervals[j]);
        if (status >= fmi2Discard) return (fmi3Status)status;
        qualifiers[j] = i->clock->asked ? fmi3IntervalUnchanged : fmi3IntervalChanged;
    }
    i->clock->asked = true;
    return fmi3OK;
}

EXPORT3 fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                       size_t nValueReferences, fmi3Float64 shifts[]) {
    struct instance3 *i = instance;
    if (check_mode(i, "fmi3GetShiftDecimal", 1 << INITIALIZATION | 1 << EVENT)) return fmi3Error;
    if (only_the_clock(i, "fmi3GetShiftDecimal", valueReferences, nValueReferences, shifts))
        return fmi3Error;
    for (size_t j = 0; j < nValueReferences; j++) shifts[j] = 0.0;
    return fmi3OK;
}
