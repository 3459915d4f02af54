/* SPDX-License-Identifier: BSD-2-Clause */
/* The hostile host's nonsense calls (fmu_hostile_host.h): each a call that is an error of the host
   by the standard's text, made on an instance of its own; the FMU must answer Error and log one
   message, and read nothing it was not given. */

#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmu_hostile_host.h"

/* The nonsense scenarios: a NULL array or entry, a count beyond any array, a time that cannot be, a
   capability the model description does not declare. */
static const char *const NONSENSE[] = {
    "debug-null-categories", "debug-null-entry", "debug-categories-beyond", "setup-stop-before-start",
    "setup-start-nan", "setup-start-inf", "setup-stop-inf", "setup-tolerance-nan", "setup-tolerance-negative", "get-null-vr", "get-null-values",
    "set-null-values", "get-count-beyond", "get-integer-null-vr", "get-boolean-null-values",
    "set-string-null-entry", "get-state-null", "set-state-null", "get-state-undeclared-size", "deserialize-null",
    "directional-null", "output-derivatives-null", "input-derivatives-null", "status-null", "real-status-null"};

/* ---- nonsense arguments: each call on an instance of its own, one message expected ------------- */

/* The counters start again for the call under test (pythonfmu logs at instantiation). */
static void under_test(void) { messages = null_categories = 0, first[0] = '\0'; }

#define F2(name, type) ((type)fn(name)) /* an FMI function by name, as a pointer of `type` */
typedef int (*vr_call)(component, const unsigned *, size_t, void *, size_t);

#define NOT_THIS 1000 /* the scenario is another function's */

/* The nonsense calls made before initialization: logging categories, the experiment's times. */
static int before_init_call(component c, const char *name) {
    static const char *categories[] = {"logAll", NULL};
    int (*debug)(component, int, size_t, const char **) =
        fn(version == 2 ? "fmi2SetDebugLogging" : "fmi3SetDebugLogging");
    if (!strcmp(name, "debug-null-categories")) return debug(c, 1, 2, NULL);
    if (!strcmp(name, "debug-null-entry")) return debug(c, 1, 2, categories);
    /* 2^40 names in an array of 2: none may be read */
    if (!strcmp(name, "debug-categories-beyond")) return debug(c, 1, (size_t)1 << 40, categories);
    if (strncmp(name, "setup-", 6)) return NOT_THIS;
    double start = 0, stop = 1, tolerance = 1e-6; /* start, stop, tolerance */
    int stop_defined = 1, tolerance_defined = 1;
    if (!strcmp(name, "setup-stop-before-start")) start = 1, stop = 0.5;
    else if (!strcmp(name, "setup-start-nan")) start = NAN;
    else if (!strcmp(name, "setup-start-inf")) start = INFINITY;
    else if (!strcmp(name, "setup-stop-inf")) stop = INFINITY;
    else if (!strcmp(name, "setup-tolerance-nan")) tolerance = NAN;
    else if (!strcmp(name, "setup-tolerance-negative")) tolerance = -1e-6;
    if (version == 2)
        return F2("fmi2SetupExperiment", int (*)(component, int, double, double, int, double))(
            c, tolerance_defined, tolerance, start, stop_defined, stop);
    return F2("fmi3EnterInitializationMode", int (*)(component, bool, double, double, bool, double))(
        c, tolerance_defined, tolerance, start, stop_defined, stop);
}

/* The nonsense getters and setters: NULL arrays and entries, a count beyond any array. */
static int values_call(component c, const char *name) {
    unsigned vr[2] = {(unsigned)out_vr, (unsigned)out_vr};
    double values[2] = {0, 0};
    int ints[2] = {0, 0};
    const char *strings[1] = {NULL};
    const char *real_get = version == 2 ? "fmi2GetReal" : "fmi3GetFloat64";
    if (!strcmp(name, "get-null-vr")) return F2(real_get, vr_call)(c, NULL, 1, values, 1);
    if (!strcmp(name, "get-null-values")) return F2(real_get, vr_call)(c, vr, 1, NULL, 1);
    if (!strcmp(name, "set-null-values"))
        return F2(version == 2 ? "fmi2SetReal" : "fmi3SetFloat64", vr_call)(c, vr, 1, NULL, 1);
    if (!strcmp(name, "get-count-beyond")) /* far more than the arrays hold */
        return F2(real_get, vr_call)(c, vr, (size_t)1 << 40, values, (size_t)1 << 40);
    if (!strcmp(name, "get-integer-null-vr"))
        return F2(version == 2 ? "fmi2GetInteger" : "fmi3GetInt32", vr_call)(c, NULL, 1, ints, 1);
    if (!strcmp(name, "get-boolean-null-values"))
        return F2(version == 2 ? "fmi2GetBoolean" : "fmi3GetBoolean", vr_call)(c, vr, 1, NULL, 1);
    if (!strcmp(name, "set-string-null-entry"))
        return F2(version == 2 ? "fmi2SetString" : "fmi3SetString", vr_call)(c, vr, 1, (void *)strings, 1);
    return NOT_THIS;
}

/* The nonsense FMU-state calls; `state`: one got before the call under test, or NULL. */
static int state_call(component c, const char *name, void *state) {
    size_t size = 0;
    if (!strcmp(name, "get-state-null"))
        return F2(version == 2 ? "fmi2GetFMUstate" : "fmi3GetFMUState", int (*)(component, void **))(c, NULL);
    if (!strcmp(name, "set-state-null"))
        return F2(version == 2 ? "fmi2SetFMUstate" : "fmi3SetFMUState", int (*)(component, void *))(c, NULL);
    if (!strcmp(name, "get-state-undeclared-size")) {
        int r = F2(version == 2 ? "fmi2SerializedFMUstateSize" : "fmi3SerializedFMUStateSize",
                   int (*)(component, void *, size_t *))(c, state, &size);
        messages_of_call = messages;
        if (state) F2(version == 2 ? "fmi2FreeFMUstate" : "fmi3FreeFMUState", int (*)(component, void **))(c, &state);
        return r;
    }
    if (!strcmp(name, "deserialize-null"))
        return F2(version == 2 ? "fmi2DeSerializeFMUstate" : "fmi3DeserializeFMUState",
                  int (*)(component, const void *, size_t, void **))(c, NULL, 16, &state);
    return NOT_THIS;
}

/* The nonsense derivative and status calls (the last three FMI 2.0 only: -2 for FMI 3.0). */
static int derivative_call(component c, const char *name) {
    if (!strcmp(name, "directional-null")) {
        if (version == 2)
            return F2("fmi2GetDirectionalDerivative", int (*)(component, const unsigned *, size_t, const unsigned *,
                                                                size_t, const double *, double *))(
                c, NULL, 1, NULL, 1, NULL, NULL);
        return F2("fmi3GetDirectionalDerivative", int (*)(component, const unsigned *, size_t, const unsigned *,
                                                            size_t, const double *, size_t, double *, size_t))(
            c, NULL, 1, NULL, 1, NULL, 1, NULL, 1);
    }
    if (!strcmp(name, "output-derivatives-null")) {
        if (version == 2)
            return F2("fmi2GetRealOutputDerivatives",
                      int (*)(component, const unsigned *, size_t, const int *, double *))(c, NULL, 1, NULL, NULL);
        return F2("fmi3GetOutputDerivatives",
                  int (*)(component, const unsigned *, size_t, const int *, double *, size_t))(c, NULL, 1, NULL,
                                                                                               NULL, 1);
    }
    if (version == 3) return -2; /* FMI 2.0 only below */
    if (!strcmp(name, "input-derivatives-null"))
        return F2("fmi2SetRealInputDerivatives",
                  int (*)(component, const unsigned *, size_t, const int *, const double *))(c, NULL, 1, NULL, NULL);
    if (!strcmp(name, "status-null"))
        return F2("fmi2GetStatus", int (*)(component, int, int *))(c, 0 /* fmi2DoStepStatus */, NULL);
    if (!strcmp(name, "real-status-null"))
        return F2("fmi2GetRealStatus", int (*)(component, int, double *))(c, 2 /* LastSuccessfulTime */, NULL);
    return NOT_THIS;
}

static int nonsense_call(component c, const char *name) {
    int r = before_init_call(c, name);
    if (r != NOT_THIS) return r;
    /* the rest after initialization */
    int s = initialize(c);
    if (s > WARNING) return 100 + s; /* not the call under test: the test fails on it */
    void *state = NULL;
    if (!strcmp(name, "get-state-undeclared-size")) { /* a state got, then its serialized size */
        int (*get)(component, void **) = fn(version == 2 ? "fmi2GetFMUstate" : "fmi3GetFMUState");
        if (get(c, &state) > WARNING) state = NULL;
    }
    under_test();
    if ((r = values_call(c, name)) != NOT_THIS || (r = state_call(c, name, state)) != NOT_THIS ||
        (r = derivative_call(c, name)) != NOT_THIS)
        return r;
    printf("unknown scenario %s\n", name);
    exit(2);
}

/* One nonsense call on a fresh instance; extra: the messages the call logged. */
struct result nonsense(const char *name) {
    component c = fresh("nonsense");
    if (!c) return (struct result){ERROR, 0, 0};
    under_test();
    messages_of_call = -1;
    int s = nonsense_call(c, name);
    int logged = messages_of_call >= 0 ? messages_of_call : messages;
    free_instance(c);
    return (struct result){s, 1, logged};
}

int is_nonsense(const char *name) {
    for (size_t k = 0; k < sizeof NONSENSE / sizeof NONSENSE[0]; k++)
        if (!strcmp(name, NONSENSE[k])) return 1;
    return 0;
}
