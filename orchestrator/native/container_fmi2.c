/* SPDX-License-Identifier: BSD-2-Clause */
/* The scenario container's FMI 2.0 Co-Simulation API (container.h): each function checks the
   container's state, then calls the core (core.c) or serves the container's own variables. */

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "container.h"

EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }

EXPORT const char *fmi2GetVersion(void) { return "2.0"; }


EXPORT fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                                     fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                                     fmi2Boolean visible, fmi2Boolean loggingOn) {
    (void)fmuResourceLocation, (void)visible;
    struct container *x = calloc(1, sizeof *x);
    if (!x) return NULL;
    snprintf(x->name, sizeof x->name, "%s", instanceName ? instanceName : "container");
    if (functions) x->host = *functions;
    x->logging = loggingOn;
    x->inner.allocateMemory = functions ? functions->allocateMemory : NULL;
    x->inner.freeMemory = functions ? functions->freeMemory : NULL;
    if (fmuType != fmi2CoSimulation) {
        say(x, fmi2Error, "fmi2Instantiate: this FMU is Co-Simulation only");
        free(x);
        return NULL;
    }
    return create(x, "fmi2Instantiate", fmuGUID);
}

EXPORT void fmi2FreeInstance(fmi2Component c) {
    if (c) release(c);
}

/* Whether the arrays of a getter or setter of `n` values can be read: neither NULL when values are
   asked for, and `n` not beyond the container's variables (arrays that long cannot exist); else
   fmi2Error (latched) with one message. */
int container_arrays(struct container *x, const char *function, size_t n, const void *vr, const void *values) {
    if (n > 0 && (!vr || !values))
        say(x, fmi2Error, "%s: %zu values asked for, but the %s array is NULL", function, n,
            !vr ? "value reference" : "value");
    else if (n > x->plan.nexposed)
        say(x, fmi2Error, "%s: %zu value references, more than the container's %zu variables", function, n,
            x->plan.nexposed);
    else return 1;
    return 0;
}

#define ARRAYS(n, vr, values)                                                                                \
    if (!container_arrays(x, __func__, n, vr, values)) return fmi2Error

EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String categories[]) {
    CONTAINER(c, ANY);
    const char *function = x->serving ? x->serving : __func__;
    if (n > 0 && !categories) {
        say(x, fmi2Error, "%s: %zu categories given, but the categories array is NULL", function, n);
        return fmi2Error;
    }
    for (size_t k = 0; k < n; k++)
        if (!categories[k]) {
            say(x, fmi2Error, "%s: categories[%zu] is NULL, not a category name", function, k);
            return fmi2Error;
        }
    x->logging = on;
    int worst = fmi2OK;
    for (size_t i = 0; i < x->plan.ncomponents; i++) {
        int s = fmu_set_debug_logging(&x->core.fmus[i], on, n, categories);
        if (s > worst) worst = s;
    }
    return worst > fmi2Warning ? fmi2Warning : (fmi2Status)worst;
}

EXPORT fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                                      fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    CONTAINER(c, 1 << INSTANTIATED);
    const char *function = x->serving ? x->serving : __func__;
    double ns = startTime * 1e9;
    if (!(fabs(ns) < 9e18)) {
        say(x, fmi2Error, "%s: start time %g s is not a finite time", function, startTime);
        return fmi2Error;
    }
    /* Values not defined are ignored, as the standard says. */
    if (stopTimeDefined && !(isfinite(stopTime) && stopTime >= startTime)) {
        say(x, fmi2Error, "%s: the stop time %g s is not a finite time at or after the start time %g s", function,
            stopTime, startTime);
        return fmi2Error;
    }
    if (toleranceDefined && !(isfinite(tolerance) && tolerance > 0.0)) {
        say(x, fmi2Error, "%s: the tolerance %g is not a positive finite number", function, tolerance);
        return fmi2Error;
    }
    x->plan.t0 = llround(ns);
    x->stop_defined = stopTimeDefined;
    x->stop = stopTime;
    return fmi2OK;
}

EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    CONTAINER(c, 1 << INSTANTIATED);
    double t0 = plan_time(&x->plan, 0);
    fmi2Status s = CORE(x, core_enter_initialization(&x->core, t0, x->stop_defined, x->stop));
    if (s == fmi2OK) s = apply_inputs(x, t0);
    if (s != fmi2OK) return s;
    x->state = INITIALIZATION;
    x->dirty = 1;
    return fmi2OK;
}

EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    CONTAINER(c, 1 << INITIALIZATION);
    double t0 = plan_time(&x->plan, 0);
    fmi2Status s = CORE(x, core_ask_clocks(&x->core, t0) || core_exit_initialization(&x->core, t0));
    if (s != fmi2OK) return s;
    x->dirty = 0;
    x->state = STEPPING;
    x->k = 0;
    return fmi2OK;
}

/* Whether the host's step [t, t + H] ends on the grid after the container's time; the target count. */
static int on_grid(const struct container *x, double t, double H, int64_t *target) {
    const struct plan *p = &x->plan;
    double now = (double)(p->t0 + p->h * x->k);
    double start = t * 1e9, end = (t + H) * 1e9;
    *target = llround((end - (double)p->t0) / (double)p->h);
    /* The host's time may be a sum of steps: within a thousandth of a step of the grid counts as on it. */
    double slack = 1e-3 * (double)p->h;
    return fabs(start - now) <= slack && fabs(end - (double)(p->t0 + p->h * *target)) <= slack && *target > x->k;
}

EXPORT fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                             fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    CONTAINER(c, 1 << STEPPING);
    (void)noSetFMUStatePriorToCurrentPoint;
    const struct plan *p = &x->plan;
    int64_t target;
    if (!on_grid(x, currentCommunicationPoint, communicationStepSize, &target)) {
        say(x, fmi2Error,
            "fmi2DoStep(t=%.17g s, h=%.17g s): the container steps on its scenario's grid t0 + k*%.9g s and is at "
            "t=%.17g s: the communication points must be on that grid and the step a positive multiple of %.9g s",
            currentCommunicationPoint, communicationStepSize, (double)p->h / 1e9, plan_time(p, x->k),
            (double)p->h / 1e9);
        return fmi2Error;
    }
    if (!p->jacobi && x->dirty) { /* an input set since the last propagation feeds other inputs */
        fmi2Status s = propagate(x, plan_time(p, x->k));
        if (s != fmi2OK) return s;
    }
    for (; x->k < target; x->k++)
        if (core_step(&x->core, x->k, NULL)) return failed(x);
    x->dirty = 0;
    return fmi2OK;
}

static struct exposed *find(struct container *x, fmi2ValueReference vr, char type) {
    for (size_t j = 0; j < x->plan.nexposed; j++)
        if (x->plan.exposed[j].vr == vr && x->plan.exposed[j].type == type) return &x->plan.exposed[j];
    return NULL;
}

EXPORT fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real value[]) {
    CONTAINER(c, ANY);
    ARRAYS(n, vr, value);
    if (!x->plan.jacobi && x->dirty && (x->state == INITIALIZATION || x->state == STEPPING)) {
        fmi2Status s = propagate(x, plan_time(&x->plan, x->k));
        if (s != fmi2OK) return s;
    }
    for (size_t j = 0; j < n; j++) {
        struct exposed *e = find(x, vr[j], 'r');
        if (!e) {
            say(x, fmi2Error, "fmi2GetReal: no Real variable with value reference %u", vr[j]);
            return fmi2Error;
        }
        value[j] = e->kind == 'p' ? x->plan.starts[e->call].reals[e->position] : x->values[e->slot];
    }
    return fmi2OK;
}

EXPORT fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real value[]) {
    CONTAINER(c, ANY);
    ARRAYS(n, vr, value);
    for (size_t j = 0; j < n; j++) {
        struct exposed *e = find(x, vr[j], 'r');
        if (!e || e->kind == 'o' || (e->kind == 'p' && x->state != INSTANTIATED && x->state != INITIALIZATION)) {
            say(x, fmi2Error, "fmi2SetReal: value reference %u is not a Real input or a parameter that can be "
                "set now", vr[j]);
            return fmi2Error;
        }
        if (e->kind == 'p') {
            x->plan.starts[e->call].reals[e->position] = value[j];
            continue;
        }
        x->values[e->slot] = value[j];
        x->input_set[e - x->plan.exposed] = 1;
        x->dirty |= e->feedthrough;
        if ((x->state == INITIALIZATION || x->state == STEPPING) &&
            core_set_input(&x->core, e->component, e->inner, &value[j], plan_time(&x->plan, x->k)))
            return failed(x);
    }
    return fmi2OK;
}

static fmi2Status get_ints(struct container *x, const fmi2ValueReference vr[], size_t n, int value[], char type) {
    for (size_t j = 0; j < n; j++) {
        struct exposed *e = find(x, vr[j], type);
        if (!e) {
            say(x, fmi2Error, "no %s variable with value reference %u", type == 'i' ? "Integer" : "Boolean", vr[j]);
            return fmi2Error;
        }
        value[j] = x->plan.starts[e->call].ints[e->position];
    }
    return fmi2OK;
}

static fmi2Status set_ints(struct container *x, const fmi2ValueReference vr[], size_t n, const int value[],
                           char type) {
    for (size_t j = 0; j < n; j++) {
        struct exposed *e = find(x, vr[j], type);
        if (!e || (x->state != INSTANTIATED && x->state != INITIALIZATION)) {
            say(x, fmi2Error, "value reference %u is not an %s parameter that can be set now", vr[j],
                type == 'i' ? "Integer" : "Boolean");
            return fmi2Error;
        }
        x->plan.starts[e->call].ints[e->position] = value[j];
    }
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer value[]) {
    CONTAINER(c, ANY);
    ARRAYS(n, vr, value);
    return get_ints(x, vr, n, value, 'i');
}

EXPORT fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean value[]) {
    CONTAINER(c, ANY);
    ARRAYS(n, vr, value);
    return get_ints(x, vr, n, value, 'b');
}

EXPORT fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                 const fmi2Integer value[]) {
    CONTAINER(c, ANY);
    ARRAYS(n, vr, value);
    return set_ints(x, vr, n, value, 'i');
}

EXPORT fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                 const fmi2Boolean value[]) {
    CONTAINER(c, ANY);
    ARRAYS(n, vr, value);
    return set_ints(x, vr, n, value, 'b');
}

EXPORT fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String value[]) {
    CONTAINER(c, ANY);
    (void)vr, (void)value;
    if (!n) return fmi2OK;
    say(x, fmi2Error, "fmi2GetString: the container exposes no String variable");
    return fmi2Error;
}

EXPORT fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                const fmi2String value[]) {
    CONTAINER(c, ANY);
    (void)vr, (void)value;
    if (!n) return fmi2OK;
    say(x, fmi2Error, "fmi2SetString: the container exposes no String variable");
    return fmi2Error;
}

EXPORT fmi2Status fmi2Terminate(fmi2Component c) {
    CONTAINER(c, 1 << STEPPING | 1 << INITIALIZATION);
    fmi2Status s = CORE(x, core_terminate(&x->core, plan_time(&x->plan, x->k)));
    if (s == fmi2OK) x->state = TERMINATED;
    return s;
}

EXPORT fmi2Status fmi2Reset(fmi2Component c) {
    CONTAINER(c, ANY_OR_FAILED);
    double t = plan_time(&x->plan, x->k);
    for (size_t i = 0; i < x->plan.ncomponents; i++) {
        int status = fmu_reset(&x->core.fmus[i]);
        if (status >= fmi2Discard) {
            x->core.failure = (struct failure){(int)i, RESET, status, t};
            return failed(x);
        }
    }
    /* Start values as exported: the plan is read again. */
    char path[TEXT + 32], why[2 * TEXT];
    struct plan fresh;
    snprintf(path, sizeof path, "%s/container.plan", x->resources);
    if (plan_load(path, &fresh, why, sizeof why) != 0) {
        plan_free(&fresh);
        say(x, fmi2Error, "fmi2Reset: %s", why);
        x->state = FAILED;
        return fmi2Error;
    }
    plan_free(&x->plan);
    x->plan = fresh;
    x->core.clocks = x->plan.clocks;
    for (size_t i = 0; i < x->plan.ncomponents; i++)
        x->core.fmus[i].in_event = x->core.fmus[i].event_requested = x->core.fmus[i].ticked = 0;
    memcpy(x->values, x->plan.initial, x->plan.nvalues * sizeof *x->values);
    memset(x->input_set, 0, (x->plan.nexposed ? x->plan.nexposed : 1) * sizeof *x->input_set);
    x->k = 0;
    x->dirty = 1;
    x->state = INSTANTIATED;
    return fmi2OK;
}

static fmi2Status unsupported(fmi2Component c, const char *function) {
    say(c, fmi2Error, "%s is not supported by the scenario container", function);
    return fmi2Error;
}

EXPORT fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state) {
    (void)state;
    return unsupported(c, "fmi2GetFMUstate");
}
EXPORT fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
    (void)state;
    return unsupported(c, "fmi2SetFMUstate");
}
EXPORT fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    (void)state;
    return unsupported(c, "fmi2FreeFMUstate");
}
EXPORT fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size) {
    (void)state, (void)size;
    return unsupported(c, "fmi2SerializedFMUstateSize");
}
EXPORT fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte bytes[], size_t size) {
    (void)state, (void)bytes, (void)size;
    return unsupported(c, "fmi2SerializeFMUstate");
}
EXPORT fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size,
                                          fmi2FMUstate *state) {
    (void)bytes, (void)size, (void)state;
    return unsupported(c, "fmi2DeSerializeFMUstate");
}
EXPORT fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference unknown[],
                                               size_t nUnknown, const fmi2ValueReference known[], size_t nKnown,
                                               const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    (void)unknown, (void)nUnknown, (void)known, (void)nKnown, (void)dvKnown, (void)dvUnknown;
    return unsupported(c, "fmi2GetDirectionalDerivative");
}
EXPORT fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                              const fmi2Integer order[], const fmi2Real value[]) {
    (void)vr, (void)n, (void)order, (void)value;
    return unsupported(c, "fmi2SetRealInputDerivatives");
}
EXPORT fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                               const fmi2Integer order[], fmi2Real value[]) {
    (void)vr, (void)n, (void)order, (void)value;
    return unsupported(c, "fmi2GetRealOutputDerivatives");
}
EXPORT fmi2Status fmi2CancelStep(fmi2Component c) { return unsupported(c, "fmi2CancelStep"); }

EXPORT fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    (void)s, (void)value;
    return unsupported(c, "fmi2GetStatus");
}
EXPORT fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    struct container *x = c;
    if (x && s == fmi2LastSuccessfulTime && value) {
        *value = plan_time(&x->plan, x->k);
        return fmi2OK;
    }
    return unsupported(c, "fmi2GetRealStatus");
}
EXPORT fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    (void)s, (void)value;
    return unsupported(c, "fmi2GetIntegerStatus");
}
EXPORT fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    struct container *x = c;
    if (x && s == fmi2Terminated && value) {
        *value = 0;
        return fmi2OK;
    }
    return unsupported(c, "fmi2GetBooleanStatus");
}
EXPORT fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)s, (void)value;
    return unsupported(c, "fmi2GetStringStatus");
}

