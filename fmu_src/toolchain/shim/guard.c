/* SPDX-License-Identifier: BSD-2-Clause */
/* The guard (shim.h; docs/fmus/host-safety.md): the FMI state machine of an instance and the
   checks of every argument, made before a call reaches pythonfmu, as the Modelica Reference FMUs
   make them (one table of allowed states per function, in fmi2_functions.c). */

#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "shim.h"

/* ---- Guard ------------------------------------------------------------------------------------- */

const char *state_name(enum state s) {
    switch (s) {
    case INSTANTIATED: return "Instantiated";
    case INITIALIZATION: return "Initialization Mode";
    case STEP_COMPLETE: return "Step Complete";
    case STEP_FAILED: return "Step Failed (after fmi2Discard)";
    case TERMINATED: return "Terminated";
    case ERROR: return "Error";
    default: return "Fatal";
    }
}

/* The state after a call that returned `status`: fmi2Error and fmi2Fatal latch the instance. */
fmi2Status settle(struct instance *i, fmi2Status status) {
    if (status == fmi2Fatal) i->state = FATAL;
    else if (status >= fmi2Error && i->state != FATAL) i->state = ERROR;
    return status;
}

/* fmi2Error with one message, and the instance latched (the standard's Error state). */
fmi2Status refuse(struct instance *i, const char *function, const char *reason) {
    say(i, fmi2Error, function, "%s", reason);
    return settle(i, fmi2Error);
}

/* fmi2OK if `function` may be called in the instance's state (`allowed`; `in_error`: also after
   fmi2Error), else fmi2Error and a message; a call after fmi2Fatal is never allowed. */
fmi2Status allowed_in(struct instance *i, const char *function, int allowed, int in_error) {
    if (i->state == FATAL) {
        say(i, fmi2Error, function, "not allowed after a fatal error: only fmi2FreeInstance is");
        return fmi2Error;
    }
    if (i->state == ERROR) {
        if (in_error) return fmi2OK;
        say(i, fmi2Error, function, "not allowed after an error: only getters, fmi2Reset and fmi2FreeInstance are");
        return fmi2Error;
    }
    if (allowed & (int)i->state) return fmi2OK;
    char reason[128];
    snprintf(reason, sizeof reason, "not allowed in %s", state_name(i->state));
    return refuse(i, function, reason);
}

static const char *TYPE_NAMES[] = {"Real", "Integer", "Boolean", "String"};
static const char TYPE_CODES[] = "ribs";

/* Whether variable `v` may be set in state `s`; NULL, or the reason it may not. */
static const char *unsettable(const struct ftc_variable *v, enum state s) {
    if (v->variability == 'c') return "is a constant";
    switch (v->causality) {
    case 'o': return "is an output";
    case 'c': return "is a calculated parameter";
    case 't': return "is the independent variable";
    case 'l':
        if ((s & (INSTANTIATED | INITIALIZATION)) && (v->initial == 'e' || v->initial == 'a')) return NULL;
        return "is a local variable";
    case 'i': return NULL;
    default: /* parameters */
        if (s & (INSTANTIATED | INITIALIZATION)) return NULL;
        return v->variability == 't' ? NULL : "is a fixed parameter";
    }
}

/* fmi2OK if every value reference names a variable of type `type` (an index into TYPE_NAMES) that
   may be read (`set` 0) or set in the current state; else fmi2Error and one message. */
fmi2Status check_references(struct instance *i, const char *function, const fmi2ValueReference vr[],
                                   size_t n, const void *values, int type, int set) {
    char reason[TEXT];
    if (n > 0 && (!vr || !values)) {
        snprintf(reason, sizeof reason, "%zu values asked for, but the %s array is NULL", n,
                 !vr ? "value reference" : "value");
        return refuse(i, function, reason);
    }
    if (n > ftc_description.n) { /* the arrays cannot be that long: not read */
        snprintf(reason, sizeof reason, "%zu value references, more than the model's %zu variables", n,
                 ftc_description.n);
        return refuse(i, function, reason);
    }
    if (set && type == 3) /* a NULL string would reach pythonfmu's std::string */
        for (size_t k = 0; k < n; k++)
            if (!((const fmi2String *)values)[k]) {
                snprintf(reason, sizeof reason, "value[%zu] is NULL, not a string", k);
                return refuse(i, function, reason);
            }
    for (size_t k = 0; k < n; k++) {
        const struct ftc_variable *v = ftc_variable(&ftc_description, vr[k] + FTC_VR_OFFSET);
        const char *problem = NULL;
        if (!v) {
            snprintf(reason, sizeof reason, "no variable has the value reference %u", vr[k] + FTC_VR_OFFSET);
            return refuse(i, function, reason);
        }
        if (v->type != TYPE_CODES[type]) {
            const char *actual = strchr(TYPE_CODES, v->type) ? TYPE_NAMES[strchr(TYPE_CODES, v->type) - TYPE_CODES]
                                                             : "variable of another type";
            snprintf(reason, sizeof reason, "%s (value reference %u) is a%s %s, not a%s %s", v->name,
                     vr[k] + FTC_VR_OFFSET, actual[0] == 'I' ? "n" : "", actual, type == 1 ? "n" : "",
                     TYPE_NAMES[type]);
            return refuse(i, function, reason);
        }
        if (set && (problem = unsettable(v, i->state))) {
            snprintf(reason, sizeof reason, "%s (value reference %u) %s: it cannot be set in %s", v->name,
                     vr[k] + FTC_VR_OFFSET, problem, state_name(i->state));
            return refuse(i, function, reason);
        }
    }
    return fmi2OK;
}

/* Served by the FMI 3.0 layer of this shared object (fmi3_shim.c): messages name its function;
   and its own refusals latch the instance too. */
void ftc_serving(fmi2Component c, const char *function) {
    if (c) ((struct instance *)c)->serving = function;
}

fmi2Status ftc_latch(fmi2Component c, fmi2Status status) { return c ? settle(c, status) : status; }

fmi2Status ftc_allowed(fmi2Component c, const char *function, int in_error) {
    return c ? allowed_in(c, function, ANY_STATE, in_error) : fmi2Error;
}

size_t ftc_variable_count(void) { return ftc_description.n; }

/* ---- Arguments ---------------------------------------------------------------------------------

   Each function's pointers, counts and times, checked after its state (ARGS_<name> in the
   FORWARD macros below): 0, or fmi2Error with one message (the call is then not forwarded). */

#define REFUSE_IF(condition, ...)                                                                             \
    do {                                                                                                      \
        if (condition) {                                                                                      \
            char reason_[TEXT];                                                                               \
            snprintf(reason_, sizeof reason_, __VA_ARGS__);                                                   \
            return refuse(i, function, reason_);                                                              \
        }                                                                                                     \
    } while (0)

fmi2Status check_categories(struct instance *i, const char *function, size_t n,
                                   const fmi2String categories[]) {
    REFUSE_IF(n > 0 && !categories, "%zu categories given, but the categories array is NULL", n);
    REFUSE_IF(n > ftc_description.log_categories, "%zu categories given, more than the model's %zu log categories", n,
              ftc_description.log_categories);
    for (size_t k = 0; k < n; k++) REFUSE_IF(!categories[k], "categories[%zu] is NULL, not a category name", k);
    return fmi2OK;
}

/* The experiment's times: the start finite; the stop (if defined) finite and not before the start;
   the tolerance (if defined) positive and finite. Values not defined are ignored, as the standard says. */
fmi2Status check_experiment(struct instance *i, const char *function, fmi2Boolean tolerance_defined,
                                   fmi2Real tolerance, fmi2Real start, fmi2Boolean stop_defined, fmi2Real stop) {
    REFUSE_IF(!isfinite(start), "the start time %g is not a finite number", start);
    REFUSE_IF(stop_defined && !isfinite(stop), "the stop time %g is not a finite number", stop);
    REFUSE_IF(stop_defined && stop < start, "the stop time %g is before the start time %g", stop, start);
    REFUSE_IF(tolerance_defined && !(isfinite(tolerance) && tolerance > 0.0),
              "the tolerance %g is not a positive finite number", tolerance);
    return fmi2OK;
}

/* A capability the model description declares false: the standard says the function must not be called. */
fmi2Status check_capability(struct instance *i, const char *function, int declared, const char *what) {
    REFUSE_IF(!declared, "not provided: the model description declares %s", what);
    return fmi2OK;
}

fmi2Status check_pointer(struct instance *i, const char *function, const void *pointer, const char *what) {
    REFUSE_IF(!pointer, "%s is NULL", what);
    return fmi2OK;
}

/* Arrays of `n` value references (and values): not NULL when n > 0, n not beyond the variables. */
fmi2Status check_array(struct instance *i, const char *function, size_t n, const void *references,
                              const void *values, const char *what) {
    REFUSE_IF(n > 0 && (!references || !values), "%zu %s asked for, but an array is NULL", n, what);
    REFUSE_IF(n > ftc_description.n, "%zu %s, more than the model's %zu variables", n, what, ftc_description.n);
    return fmi2OK;
}
