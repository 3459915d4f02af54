/* SPDX-License-Identifier: BSD-2-Clause */
/* The FMI 3.0 getters and setters (fmi3.h): value references translated to the FMI 2.0 layer's,
   the independent variable `time` served here. */

#include <stdarg.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3.h"

/* ---- Getting and setting variable values ------------------------------------------------- */

static fmi3Status count_matches(struct instance3 *i, const char *function, size_t nValueReferences,
                                size_t nValues) {
    if (nValueReferences == nValues) return fmi3OK;
    char reason[160];
    snprintf(reason, sizeof reason, "nValues = %zu but %zu scalar variables were named (no arrays here)",
             nValues, nValueReferences);
    return refuse3(i, function, reason);
}

/* FMI 3.0 value references translated to the FMI 2.0 layer's, `time` left out (counted in `time`). */
struct references {
    fmi2ValueReference *vr;
    size_t n, time;
    fmi2ValueReference small[VR_BUFFER];
};

static void release(struct references *t) {
    if (t->vr != t->small) free(t->vr);
}

/* The arrays of a getter or setter: as many values as value references, neither array NULL when
   values are asked for, not more than the model's variables (arrays that long cannot exist). */
static int check_arrays(struct instance3 *i, const char *function, const fmi3ValueReference vr[], size_t n,
                        const void *values, size_t nValues) {
    char reason[160];
    if (count_matches(i, function, n, nValues)) return -1;
    if (n > 0 && (!vr || !values))
        snprintf(reason, sizeof reason, "%zu values asked for, but the %s array is NULL", n,
                 !vr ? "valueReferences" : "values");
    else if (n > ftc_variable_count())
        snprintf(reason, sizeof reason, "%zu value references, more than the model's %zu variables", n,
                 ftc_variable_count());
    else return 0;
    refuse3(i, function, reason);
    return -1;
}

static int translate(struct instance3 *i, const char *function, struct references *t,
                     const fmi3ValueReference vr[], size_t n) {
    t->vr = n <= VR_BUFFER ? t->small : malloc(n * sizeof *t->vr);
    t->n = t->time = 0;
    if (!t->vr) {
        refuse3(i, function, "out of memory");
        return -1;
    }
    for (size_t k = 0; k < n; k++) {
        if (vr[k] < FTC_VR_OFFSET || vr[k] > FTC_TIME_VR) { /* pythonfmu would fail with fmi2Fatal */
            char reason[96];
            snprintf(reason, sizeof reason, "no variable has the value reference %u", (unsigned)vr[k]);
            release(t);
            refuse3(i, function, reason);
            return -1;
        }
        if (vr[k] == FTC_TIME_VR) t->time++;
        else t->vr[t->n++] = vr[k] - FTC_VR_OFFSET;
    }
    return 0;
}

/* Translates the references of a call that cannot name `time` (any but fmi3GetFloat64). */
static int translate_settable(struct instance3 *i, const char *function, struct references *t,
                              const fmi3ValueReference vr[], size_t n, const void *values, size_t nValues) {
    if (check_arrays(i, function, vr, n, values, nValues) || translate(i, function, t, vr, n)) return -1;
    if (t->time) {
        release(t);
        refuse3(i, function, "the independent variable time is a read-only Float64");
        return -1;
    }
    return 0;
}

EXPORT3 fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, fmi3Float64 values[], size_t nValues) {
    struct instance3 *i = instance;
    SERVE(i, "fmi3GetFloat64");
    struct references t;
    if (!i || check_arrays(i, "fmi3GetFloat64", valueReferences, nValueReferences, values, nValues) ||
        translate(i, "fmi3GetFloat64", &t, valueReferences, nValueReferences))
        return fmi3Error;
    fmi2Status status = fmi2OK;
#ifdef FTC_CLOCK_VR
    if (!t.time && ftc_clock_get(i, t.vr, t.n, values)) { /* clocked outputs: held since the activation */
        release(&t);
        return fmi3OK;
    }
#endif
    if (!t.time) /* the common case: straight into the caller's array */
        status = fmi2GetReal(i->c, t.vr, t.n, values);
    else {
        fmi2Real *found = malloc((t.n + 1) * sizeof *found);
        if (!found) status = fmi2Error;
        else if (t.n) status = fmi2GetReal(i->c, t.vr, t.n, found);
        for (size_t k = 0, j = 0; found && k < nValueReferences && status < fmi2Discard; k++)
            values[k] = valueReferences[k] == FTC_TIME_VR ? i->time : found[j++];
        free(found);
    }
    release(&t);
    return (fmi3Status)status;
}

EXPORT3 fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, const fmi3Float64 values[], size_t nValues) {
    struct instance3 *i = instance;
    SERVE(i, "fmi3SetFloat64");
    struct references t;
    if (!i || translate_settable(i, "fmi3SetFloat64", &t, valueReferences, nValueReferences, values, nValues))
        return fmi3Error;
    fmi2Status status = fmi2SetReal(i->c, t.vr, t.n, values);
    release(&t);
    return (fmi3Status)status;
}



/* Types passed through unchanged (Int32 is fmi2Integer, a String is a char pointer in both). */
#define SAME_TYPE(Name, ctype, get2, set2)                                                                     \
    EXPORT3 fmi3Status fmi3Get##Name(fmi3Instance instance, const fmi3ValueReference valueReferences[],        \
                                     size_t nValueReferences, ctype values[], size_t nValues) {                \
        struct instance3 *i = instance;                                                                       \
        struct references t;                                                                                  \
        SERVE(i, "fmi3Get" #Name);                                                                            \
        if (!i || translate_settable(i, "fmi3Get" #Name, &t, valueReferences, nValueReferences, values, nValues))    \
            return fmi3Error;                                                                                 \
        fmi2Status status = get2(i->c, t.vr, t.n, values);                                                    \
        release(&t);                                                                                          \
        return (fmi3Status)status;                                                                            \
    }                                                                                                         \
    EXPORT3 fmi3Status fmi3Set##Name(fmi3Instance instance, const fmi3ValueReference valueReferences[],        \
                                     size_t nValueReferences, const ctype values[], size_t nValues) {          \
        struct instance3 *i = instance;                                                                       \
        struct references t;                                                                                  \
        SERVE(i, "fmi3Set" #Name);                                                                            \
        if (!i || translate_settable(i, "fmi3Set" #Name, &t, valueReferences, nValueReferences, values, nValues))    \
            return fmi3Error;                                                                                 \
        fmi2Status status = set2(i->c, t.vr, t.n, values);                                                    \
        release(&t);                                                                                          \
        return (fmi3Status)status;                                                                            \
    }
SAME_TYPE(Int32, fmi3Int32, fmi2GetInteger, fmi2SetInteger)
SAME_TYPE(String, fmi3String, fmi2GetString, fmi2SetString)

EXPORT3 fmi3Status fmi3GetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, fmi3Boolean values[], size_t nValues) {
    struct instance3 *i = instance;
    SERVE(i, "fmi3GetBoolean");
    struct references t;
    if (!i || translate_settable(i, "fmi3GetBoolean", &t, valueReferences, nValueReferences, values, nValues))
        return fmi3Error;
    fmi2Boolean *found = malloc((t.n + 1) * sizeof *found);
    fmi2Status status = found ? fmi2GetBoolean(i->c, t.vr, t.n, found) : fmi2Error;
    for (size_t k = 0; found && k < t.n && status < fmi2Discard; k++) values[k] = found[k] != 0;
    free(found);
    release(&t);
    return (fmi3Status)status;
}

EXPORT3 fmi3Status fmi3SetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, const fmi3Boolean values[], size_t nValues) {
    struct instance3 *i = instance;
    SERVE(i, "fmi3SetBoolean");
    struct references t;
    if (!i || translate_settable(i, "fmi3SetBoolean", &t, valueReferences, nValueReferences, values, nValues))
        return fmi3Error;
    fmi2Boolean *given = malloc((t.n + 1) * sizeof *given);
    for (size_t k = 0; given && k < t.n; k++) given[k] = values[k] ? 1 : 0;
    fmi2Status status = given ? fmi2SetBoolean(i->c, t.vr, t.n, given) : fmi2Error;
    free(given);
    release(&t);
    return (fmi3Status)status;
}


