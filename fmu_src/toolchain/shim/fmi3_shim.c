/* SPDX-License-Identifier: BSD-2-Clause */
/* FMI 3.0 Co-Simulation layer on the FMI 2.0 shim: the same pythonfmu slave, runtime and direct
   calls, behind the FMI 3.0 functions.

   The FMI 3.0 variant of an FMU is compiled from fmi2_shim.c, start_python.c and this file into
   binaries/x86_64-linux/<model>.so, beside the same pythonfmu binary <model>_pythonfmu.so and the
   same python/ runtime. The FMI 2.0 functions are internal there (EXPORT defined empty, the build
   passes -DEXPORT=): only fmi3* symbols are exported. Every FMI 3.0 function is either mapped on
   the FMI 2.0 one of the same meaning or refuses with fmi3Error and one message naming the
   function and the reason (through the instance's logger when there is an instance, and on
   stderr); nothing aborts the host.

   * Types: Float64 <-> Real, Int32 <-> Integer, Boolean (bool) <-> Boolean (int, converted),
     String <-> String. The model description the build writes uses only these. Float32, Int8 to
     UInt64, Binary and Clock variables do not exist: a call naming any returns fmi3Error (a call
     with no value reference returns fmi3OK, as for any type).
   * Value references: the FMI 2.0 one plus FTC_VR_OFFSET (1). The FMI 2.0 FMU numbers its
     variables 0, 1, ... in the order of ModelVariables, so in FMI 3.0 every value reference is
     also the variable's 1-based index: the dependencies in ModelStructure mean the same to an
     importer that reads them as value references (the standard) and to one that reads them as
     indices, as FMI 2.0 had it (OMSimulator 3's FMI 3.0 import does).
   * The independent variable `time` (FMI 3.0 requires one; value reference FTC_TIME_VR, after
     the model's last, listed last) is the instance's time: the start time of
     fmi3EnterInitializationMode, then the end of each accepted step; read-only; kept in FMU states.
   * fmi3DoStep writes all four output arguments, always: eventHandlingNeeded = false and
     earlyReturn = false (the FMU has no events and never returns early), terminateSimulation
     (the slave's wish after a discarded step, fmi2Terminated), lastSuccessfulTime (t + h, or
     fmi2LastSuccessfulTime after a discarded step, t after an error).
   * Event Mode: hasEventMode="false", so the FMU never asks for it. An importer that instantiates
     with eventModeUsed = true may still enter it (after fmi3ExitInitializationMode, or with
     fmi3EnterEventMode from Step Mode): nothing happens there, fmi3UpdateDiscreteStates reports
     no further iteration and no next event, fmi3EnterStepMode returns to Step Mode.
   * Refused: Model Exchange and Scheduled Execution (fmi3Instantiate* return NULL), intermediate
     variables (providesIntermediateUpdate="false"), clocks, configuration mode, per-element
     dependencies, directional and adjoint derivatives, output derivatives, every Model Exchange
     function. */

#include <stdarg.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2_types.h"
#include "platform.h"

#if !defined FTC_TIME_VR || !defined FTC_VR_OFFSET
#error "compile with -DFTC_TIME_VR=<value reference of time> -DFTC_VR_OFFSET=<FMI 3.0 - FMI 2.0 references>"
#endif
#define VR_BUFFER 64 /* value references translated on the stack; more are allocated */

#define EXPORT3 FTC_EXPORT
#define TEXT 4096

/* FMI 3.0 types (fmi3PlatformTypes.h, fmi3FunctionTypes.h), so that no header is needed. */
typedef void *fmi3Instance;
typedef void *fmi3InstanceEnvironment;
typedef void *fmi3FMUState;
typedef uint32_t fmi3ValueReference;
typedef float fmi3Float32;
typedef double fmi3Float64;
typedef int8_t fmi3Int8;
typedef uint8_t fmi3UInt8;
typedef int16_t fmi3Int16;
typedef uint16_t fmi3UInt16;
typedef int32_t fmi3Int32;
typedef uint32_t fmi3UInt32;
typedef int64_t fmi3Int64;
typedef uint64_t fmi3UInt64;
typedef bool fmi3Boolean;
typedef char fmi3Char;
typedef const fmi3Char *fmi3String;
typedef uint8_t fmi3Byte;
typedef const fmi3Byte *fmi3Binary;
typedef bool fmi3Clock;
typedef enum { fmi3OK, fmi3Warning, fmi3Discard, fmi3Error, fmi3Fatal } fmi3Status;
typedef enum { fmi3Independent, fmi3Constant, fmi3Fixed, fmi3Tunable, fmi3Discrete, fmi3Dependent } fmi3DependencyKind;
typedef enum { fmi3IntervalNotYetKnown, fmi3IntervalUnchanged, fmi3IntervalChanged } fmi3IntervalQualifier;
typedef void (*fmi3LogMessageCallback)(fmi3InstanceEnvironment, fmi3Status, fmi3String, fmi3String);
typedef void (*fmi3ClockUpdateCallback)(fmi3InstanceEnvironment);
typedef void (*fmi3IntermediateUpdateCallback)(fmi3InstanceEnvironment, fmi3Float64, fmi3Boolean, fmi3Boolean,
                                               fmi3Boolean, fmi3Boolean, fmi3Boolean *, fmi3Float64 *);
typedef void (*fmi3LockPreemptionCallback)(void);
typedef void (*fmi3UnlockPreemptionCallback)(void);

/* The FMI 2.0 functions of this shared object (fmi2_shim.c), internal in the FMI 3.0 build. */
#define PROTOTYPE(name, params, args) fmi2Status name params;
FMI2_FORWARDED(PROTOTYPE)
void fmi2FreeInstance(fmi2Component);
/* The FMI 2.0 layer's guard (fmi2_shim.c, "Guard"): instantiate naming the FMI 3.0 function;
   name the function being served in its messages; latch the
   instance after a refusal of this layer; whether a call is allowed at all (after an error). */
fmi2Component ftc_instantiate(fmi2String, fmi2Type, fmi2String, fmi2String, const fmi2CallbackFunctions *,
                              fmi2Boolean, fmi2Boolean, const char *);
void ftc_serving(fmi2Component, const char *);
fmi2Status ftc_latch(fmi2Component, fmi2Status);
fmi2Status ftc_allowed(fmi2Component, const char *, int);
size_t ftc_variable_count(void);
#define SERVE(i, function)                                                                                    \
    if (i) ftc_serving((i)->c, function)

enum mode { INSTANTIATED, INITIALIZATION, EVENT, STEP, TERMINATED };
static const char *const MODE_NAMES[] = {"Instantiated", "Initialization Mode", "Event Mode", "Step Mode",
                                         "Terminated"};

struct instance3 {
    fmi2Component c;                /* the FMI 2.0 shim's instance */
    fmi2CallbackFunctions functions; /* given to fmi2Instantiate: lives as long as the instance */
    fmi3InstanceEnvironment environment;
    fmi3LogMessageCallback log;
    enum mode mode;
    int event_mode_used;
    double time;                    /* the independent variable */
    char name[256];
};

/* An FMU state: the FMI 2.0 state and the time. */
struct state3 {
    fmi2FMUstate inner;
    double time;
};

static void say(fmi3InstanceEnvironment environment, fmi3LogMessageCallback log, fmi3Status status,
                const char *format, ...) __attribute__((format(printf, 4, 5)));

/* One message to the instance's logger (if any) and to stderr. */
static void say(fmi3InstanceEnvironment environment, fmi3LogMessageCallback log, fmi3Status status,
                const char *format, ...) {
    char text[TEXT];
    va_list args;
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    fprintf(stderr, "%s\n", text);
    if (log) log(environment, status, status == fmi3Warning ? "logStatusWarning" : "logStatusError", text);
}

/* fmi3Error with a message naming the instance and function. */
static fmi3Status refuse(struct instance3 *i, const char *function, const char *reason) {
    if (!i) {
        fprintf(stderr, "%s: %s (no instance)\n", function, reason);
        return fmi3Error;
    }
    say(i->environment, i->log, fmi3Error, "%s: %s: %s", i->name, function, reason);
    ftc_latch(i->c, fmi2Error); /* the standard's Error state, as for the FMI 2.0 layer's refusals */
    return fmi3Error;
}

/* The FMI 2.0 logger given to the FMI 2.0 layer: formats the message and passes it on. */
static void forward_log(fmi2ComponentEnvironment environment, fmi2String instanceName, fmi2Status status,
                        fmi2String category, fmi2String message, ...) {
    struct instance3 *i = environment;
    (void)instanceName;
    if (!i || !i->log) return;
    char text[TEXT];
    va_list args;
    va_start(args, message);
    vsnprintf(text, sizeof text, message ? message : "", args);
    va_end(args);
    i->log(i->environment, status > fmi2Fatal ? fmi3Error : (fmi3Status)status, category ? category : "", text);
}

static void *allocate(size_t n, size_t size) { return calloc(n, size); }

static fmi3Status check_mode(struct instance3 *i, const char *function, int allowed) {
    if (!i) return fmi3Error;
    SERVE(i, function);
    if (ftc_allowed(i->c, function, 0) != fmi2OK) return fmi3Error; /* after an error, said why */
    if (allowed & (1 << i->mode)) return fmi3OK;
    char reason[128];
    snprintf(reason, sizeof reason, "not allowed in %s", MODE_NAMES[i->mode]);
    return refuse(i, function, reason);
}

/* ---- Common functions -------------------------------------------------------------------- */

EXPORT3 const char *fmi3GetVersion(void) { return "3.0"; }

EXPORT3 fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                                       const fmi3String categories[]) {
    struct instance3 *i = instance;
    SERVE(i, "fmi3SetDebugLogging");
    if (!i) return fmi3Error;
    return (fmi3Status)fmi2SetDebugLogging(i->c, loggingOn, nCategories, categories);
}

EXPORT3 fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                                  fmi3String resourcePath, fmi3Boolean visible,
                                                  fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
                                                  fmi3LogMessageCallback logMessage) {
    (void)instantiationToken, (void)resourcePath, (void)visible, (void)loggingOn;
    say(instanceEnvironment, logMessage, fmi3Error,
        "%s: fmi3InstantiateModelExchange: this FMU is a Co-Simulation FMU only", instanceName ? instanceName : "?");
    return NULL;
}

EXPORT3 fmi3Instance fmi3InstantiateScheduledExecution(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath, fmi3Boolean visible,
    fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment, fmi3LogMessageCallback logMessage,
    fmi3ClockUpdateCallback clockUpdate, fmi3LockPreemptionCallback lockPreemption,
    fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instantiationToken, (void)resourcePath, (void)visible, (void)loggingOn, (void)clockUpdate;
    (void)lockPreemption, (void)unlockPreemption;
    say(instanceEnvironment, logMessage, fmi3Error,
        "%s: fmi3InstantiateScheduledExecution: this FMU is a Co-Simulation FMU only",
        instanceName ? instanceName : "?");
    return NULL;
}

EXPORT3 fmi3Instance fmi3InstantiateCoSimulation(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath, fmi3Boolean visible,
    fmi3Boolean loggingOn, fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
    const fmi3ValueReference requiredIntermediateVariables[], size_t nRequiredIntermediateVariables,
    fmi3InstanceEnvironment instanceEnvironment, fmi3LogMessageCallback logMessage,
    fmi3IntermediateUpdateCallback intermediateUpdate) {
    const char *name = instanceName ? instanceName : "?";
    (void)earlyReturnAllowed, (void)requiredIntermediateVariables, (void)intermediateUpdate;
    if (nRequiredIntermediateVariables > 0) {
        say(instanceEnvironment, logMessage, fmi3Error,
            "%s: fmi3InstantiateCoSimulation: this FMU provides no intermediate update "
            "(providesIntermediateUpdate=\"false\"), %zu intermediate variables were required",
            name, nRequiredIntermediateVariables);
        return NULL;
    }
    struct instance3 *i = calloc(1, sizeof *i);
    if (!i) {
        say(instanceEnvironment, logMessage, fmi3Error, "%s: fmi3InstantiateCoSimulation: out of memory", name);
        return NULL;
    }
    i->environment = instanceEnvironment;
    i->log = logMessage;
    i->event_mode_used = eventModeUsed;
    snprintf(i->name, sizeof i->name, "%s", name);
    i->functions.logger = forward_log;
    i->functions.allocateMemory = allocate;
    i->functions.freeMemory = free;
    i->functions.componentEnvironment = i;
    /* a native path (FMI 3.0's resourcePath) is taken as well as a file:// URI */
    i->c = ftc_instantiate(instanceName, fmi2CoSimulation, instantiationToken, resourcePath, &i->functions,
                           visible, loggingOn, "fmi3InstantiateCoSimulation");
    if (!i->c) { /* the FMI 2.0 layer has said why */
        free(i);
        return NULL;
    }
    return i;
}

EXPORT3 void fmi3FreeInstance(fmi3Instance instance) {
    struct instance3 *i = instance;
    SERVE(i, "fmi3FreeInstance");
    if (!i) return;
    fmi2FreeInstance(i->c);
    free(i);
}

EXPORT3 fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
                                               fmi3Float64 tolerance, fmi3Float64 startTime,
                                               fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    struct instance3 *i = instance;
    SERVE(i, "fmi3EnterInitializationMode");
    if (check_mode(i, "fmi3EnterInitializationMode", 1 << INSTANTIATED)) return fmi3Error;
    fmi2Status status = fmi2SetupExperiment(i->c, toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime);
    if (status < fmi2Discard) {
        fmi2Status entered = fmi2EnterInitializationMode(i->c);
        status = entered > status ? entered : status;
    }
    if (status < fmi2Discard) {
        i->mode = INITIALIZATION;
        i->time = startTime;
    }
    return (fmi3Status)status;
}

EXPORT3 fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    struct instance3 *i = instance;
    SERVE(i, "fmi3ExitInitializationMode");
    if (check_mode(i, "fmi3ExitInitializationMode", 1 << INITIALIZATION)) return fmi3Error;
    fmi2Status status = fmi2ExitInitializationMode(i->c);
    if (status < fmi2Discard) i->mode = i->event_mode_used ? EVENT : STEP;
    return (fmi3Status)status;
}

EXPORT3 fmi3Status fmi3EnterEventMode(fmi3Instance instance) {
    struct instance3 *i = instance;
    SERVE(i, "fmi3EnterEventMode");
    if (check_mode(i, "fmi3EnterEventMode", 1 << STEP | 1 << EVENT)) return fmi3Error;
    if (!i->event_mode_used) return refuse(i, "fmi3EnterEventMode", "instantiated with eventModeUsed = false");
    i->mode = EVENT;
    return fmi3OK;
}

EXPORT3 fmi3Status fmi3Terminate(fmi3Instance instance) {
    struct instance3 *i = instance;
    SERVE(i, "fmi3Terminate");
    if (!i) return fmi3Error;
    fmi2Status status = fmi2Terminate(i->c);
    if (status < fmi2Discard) i->mode = TERMINATED;
    return (fmi3Status)status;
}

EXPORT3 fmi3Status fmi3Reset(fmi3Instance instance) {
    struct instance3 *i = instance;
    SERVE(i, "fmi3Reset");
    if (!i) return fmi3Error;
    fmi2Status status = fmi2Reset(i->c);
    if (status < fmi2Discard) {
        i->mode = INSTANTIATED;
        i->time = 0.0;
    }
    return (fmi3Status)status;
}

/* ---- Getting and setting variable values ------------------------------------------------- */

static fmi3Status count_matches(struct instance3 *i, const char *function, size_t nValueReferences,
                                size_t nValues) {
    if (nValueReferences == nValues) return fmi3OK;
    char reason[160];
    snprintf(reason, sizeof reason, "nValues = %zu but %zu scalar variables were named (no arrays here)",
             nValues, nValueReferences);
    return refuse(i, function, reason);
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
    refuse(i, function, reason);
    return -1;
}

static int translate(struct instance3 *i, const char *function, struct references *t,
                     const fmi3ValueReference vr[], size_t n) {
    t->vr = n <= VR_BUFFER ? t->small : malloc(n * sizeof *t->vr);
    t->n = t->time = 0;
    if (!t->vr) {
        refuse(i, function, "out of memory");
        return -1;
    }
    for (size_t k = 0; k < n; k++) {
        if (vr[k] < FTC_VR_OFFSET || vr[k] > FTC_TIME_VR) { /* pythonfmu would fail with fmi2Fatal */
            char reason[96];
            snprintf(reason, sizeof reason, "no variable has the value reference %u", (unsigned)vr[k]);
            release(t);
            refuse(i, function, reason);
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
        refuse(i, function, "the independent variable time is a read-only Float64");
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



/* Types this FMU has no variable of: a call naming none is fine, any other is an error. */
static fmi3Status no_such_type(fmi3Instance instance, const char *function, const char *type,
                               size_t nValueReferences) {
    if (nValueReferences == 0) return instance ? fmi3OK : fmi3Error;
    char reason[128];
    snprintf(reason, sizeof reason, "this FMU has no %s variables", type);
    return refuse(instance, function, reason);
}

#define NO_SUCH_TYPE(Type, ctype)                                                                             \
    EXPORT3 fmi3Status fmi3Get##Type(fmi3Instance instance, const fmi3ValueReference valueReferences[],        \
                                     size_t nValueReferences, ctype values[], size_t nValues) {                \
        (void)valueReferences, (void)values, (void)nValues;                                                  \
        return no_such_type(instance, "fmi3Get" #Type, #Type, nValueReferences);                              \
    }                                                                                                         \
    EXPORT3 fmi3Status fmi3Set##Type(fmi3Instance instance, const fmi3ValueReference valueReferences[],        \
                                     size_t nValueReferences, const ctype values[], size_t nValues) {          \
        (void)valueReferences, (void)values, (void)nValues;                                                  \
        return no_such_type(instance, "fmi3Set" #Type, #Type, nValueReferences);                              \
    }
NO_SUCH_TYPE(Float32, fmi3Float32)
NO_SUCH_TYPE(Int8, fmi3Int8)
NO_SUCH_TYPE(UInt8, fmi3UInt8)
NO_SUCH_TYPE(Int16, fmi3Int16)
NO_SUCH_TYPE(UInt16, fmi3UInt16)
NO_SUCH_TYPE(UInt32, fmi3UInt32)
NO_SUCH_TYPE(Int64, fmi3Int64)
NO_SUCH_TYPE(UInt64, fmi3UInt64)

EXPORT3 fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                 size_t nValueReferences, size_t valueSizes[], fmi3Binary values[], size_t nValues) {
    (void)valueReferences, (void)valueSizes, (void)values, (void)nValues;
    return no_such_type(instance, "fmi3GetBinary", "Binary", nValueReferences);
}

EXPORT3 fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                 size_t nValueReferences, const size_t valueSizes[], const fmi3Binary values[],
                                 size_t nValues) {
    (void)valueReferences, (void)valueSizes, (void)values, (void)nValues;
    return no_such_type(instance, "fmi3SetBinary", "Binary", nValueReferences);
}

EXPORT3 fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, fmi3Clock values[]) {
    (void)valueReferences, (void)values;
    return no_such_type(instance, "fmi3GetClock", "Clock", nValueReferences);
}

EXPORT3 fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, const fmi3Clock values[]) {
    (void)valueReferences, (void)values;
    return no_such_type(instance, "fmi3SetClock", "Clock", nValueReferences);
}

/* ---- Refused features: fmi3Error and one message --------------------------------------------- */

#define REFUSED(name, reason, params, unused)                                                                \
    EXPORT3 fmi3Status name params {                                                                          \
        unused;                                                                                               \
        return refuse(instance, #name, reason);                                                              \
    }

#define NO_DEPENDENCIES "per-element dependencies are not provided (providesPerElementDependencies=\"false\"); " \
                        "see ModelStructure"
REFUSED(fmi3GetNumberOfVariableDependencies, NO_DEPENDENCIES,
        (fmi3Instance instance, fmi3ValueReference valueReference, size_t *nDependencies),
        ((void)valueReference, (void)nDependencies))
REFUSED(fmi3GetVariableDependencies, NO_DEPENDENCIES,
        (fmi3Instance instance, fmi3ValueReference dependent, size_t elementIndicesOfDependent[],
         fmi3ValueReference independents[], size_t elementIndicesOfIndependents[],
         fmi3DependencyKind dependencyKinds[], size_t nDependencies),
        ((void)dependent, (void)elementIndicesOfDependent, (void)independents, (void)elementIndicesOfIndependents,
         (void)dependencyKinds, (void)nDependencies))

#define DERIVATIVE_PARAMS                                                                                      \
    (fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,                            \
     const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[], size_t nSeed,               \
     fmi3Float64 sensitivity[], size_t nSensitivity)
#define DERIVATIVE_UNUSED                                                                                      \
    ((void)unknowns, (void)nUnknowns, (void)knowns, (void)nKnowns, (void)seed, (void)nSeed, (void)sensitivity, \
     (void)nSensitivity)
REFUSED(fmi3GetDirectionalDerivative, "directional derivatives are not provided", DERIVATIVE_PARAMS,
        DERIVATIVE_UNUSED)
REFUSED(fmi3GetAdjointDerivative, "adjoint derivatives are not provided", DERIVATIVE_PARAMS, DERIVATIVE_UNUSED)

#define NO_STRUCTURAL "this FMU has no structural parameters (no Configuration Mode)"
REFUSED(fmi3EnterConfigurationMode, NO_STRUCTURAL, (fmi3Instance instance), (void)0)
REFUSED(fmi3ExitConfigurationMode, NO_STRUCTURAL, (fmi3Instance instance), (void)0)

#define NO_CLOCKS "this FMU has no clocks"
REFUSED(fmi3GetIntervalDecimal, NO_CLOCKS,
        (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
         fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[]),
        ((void)valueReferences, (void)nValueReferences, (void)intervals, (void)qualifiers))
REFUSED(fmi3GetIntervalFraction, NO_CLOCKS,
        (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
         fmi3UInt64 counters[], fmi3UInt64 resolutions[], fmi3IntervalQualifier qualifiers[]),
        ((void)valueReferences, (void)nValueReferences, (void)counters, (void)resolutions, (void)qualifiers))
REFUSED(fmi3GetShiftDecimal, NO_CLOCKS,
        (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
         fmi3Float64 shifts[]),
        ((void)valueReferences, (void)nValueReferences, (void)shifts))
REFUSED(fmi3GetShiftFraction, NO_CLOCKS,
        (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
         fmi3UInt64 counters[], fmi3UInt64 resolutions[]),
        ((void)valueReferences, (void)nValueReferences, (void)counters, (void)resolutions))
REFUSED(fmi3SetIntervalDecimal, NO_CLOCKS,
        (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
         const fmi3Float64 intervals[]),
        ((void)valueReferences, (void)nValueReferences, (void)intervals))
REFUSED(fmi3SetIntervalFraction, NO_CLOCKS,
        (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
         const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]),
        ((void)valueReferences, (void)nValueReferences, (void)counters, (void)resolutions))
REFUSED(fmi3SetShiftDecimal, NO_CLOCKS,
        (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
         const fmi3Float64 shifts[]),
        ((void)valueReferences, (void)nValueReferences, (void)shifts))
REFUSED(fmi3SetShiftFraction, NO_CLOCKS,
        (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
         const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]),
        ((void)valueReferences, (void)nValueReferences, (void)counters, (void)resolutions))
REFUSED(fmi3EvaluateDiscreteStates, NO_CLOCKS " (providesEvaluateDiscreteStates=\"false\")",
        (fmi3Instance instance), (void)0)
REFUSED(fmi3ActivateModelPartition, "this FMU is a Co-Simulation FMU only (no Scheduled Execution)",
        (fmi3Instance instance, fmi3ValueReference clockReference, fmi3Float64 activationTime),
        ((void)clockReference, (void)activationTime))

#define NOT_ME "this FMU is a Co-Simulation FMU only (no Model Exchange)"
REFUSED(fmi3EnterContinuousTimeMode, NOT_ME, (fmi3Instance instance), (void)0)
REFUSED(fmi3CompletedIntegratorStep, NOT_ME,
        (fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint, fmi3Boolean *enterEventMode,
         fmi3Boolean *terminateSimulation),
        ((void)noSetFMUStatePriorToCurrentPoint, (void)enterEventMode, (void)terminateSimulation))
REFUSED(fmi3SetTime, NOT_ME, (fmi3Instance instance, fmi3Float64 time), (void)time)
REFUSED(fmi3SetContinuousStates, NOT_ME,
        (fmi3Instance instance, const fmi3Float64 continuousStates[], size_t nContinuousStates),
        ((void)continuousStates, (void)nContinuousStates))
REFUSED(fmi3GetContinuousStateDerivatives, NOT_ME,
        (fmi3Instance instance, fmi3Float64 derivatives[], size_t nContinuousStates),
        ((void)derivatives, (void)nContinuousStates))
REFUSED(fmi3GetEventIndicators, NOT_ME, (fmi3Instance instance, fmi3Float64 eventIndicators[], size_t n),
        ((void)eventIndicators, (void)n))
REFUSED(fmi3GetContinuousStates, NOT_ME,
        (fmi3Instance instance, fmi3Float64 continuousStates[], size_t nContinuousStates),
        ((void)continuousStates, (void)nContinuousStates))
REFUSED(fmi3GetNominalsOfContinuousStates, NOT_ME,
        (fmi3Instance instance, fmi3Float64 nominals[], size_t nContinuousStates),
        ((void)nominals, (void)nContinuousStates))
REFUSED(fmi3GetNumberOfEventIndicators, NOT_ME, (fmi3Instance instance, size_t *nEventIndicators),
        (void)nEventIndicators)
REFUSED(fmi3GetNumberOfContinuousStates, NOT_ME, (fmi3Instance instance, size_t *nContinuousStates),
        (void)nContinuousStates)

REFUSED(fmi3GetOutputDerivatives, "output derivatives are not provided (maxOutputDerivativeOrder = 0)",
        (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
         const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues),
        ((void)valueReferences, (void)nValueReferences, (void)orders, (void)values, (void)nValues))

/* ---- FMU state ------------------------------------------------------------------------------ */

EXPORT3 fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    struct instance3 *i = instance;
    SERVE(i, "fmi3GetFMUState");
    if (!i || !FMUState) return refuse(i, "fmi3GetFMUState", "no place for the state (FMUState is NULL)");
    struct state3 *s = *FMUState; /* non-NULL: update that state */
    int fresh = s == NULL;
    if (fresh && !(s = calloc(1, sizeof *s))) return refuse(i, "fmi3GetFMUState", "out of memory");
    fmi2Status status = fmi2GetFMUstate(i->c, &s->inner);
    if (status >= fmi2Discard) {
        if (fresh) free(s);
        return (fmi3Status)status;
    }
    s->time = i->time;
    *FMUState = s;
    return (fmi3Status)status;
}

EXPORT3 fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState) {
    struct instance3 *i = instance;
    SERVE(i, "fmi3SetFMUState");
    struct state3 *s = FMUState;
    if (!i || !s) return refuse(i, "fmi3SetFMUState", "no state given (FMUState is NULL)");
    fmi2Status status = fmi2SetFMUstate(i->c, s->inner);
    if (status < fmi2Discard) i->time = s->time;
    return (fmi3Status)status;
}

EXPORT3 fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    struct instance3 *i = instance;
    SERVE(i, "fmi3FreeFMUState");
    if (!i) return fmi3Error;
    if (!FMUState || !*FMUState) return fmi3OK;
    struct state3 *s = *FMUState;
    fmi2Status status = fmi2FreeFMUstate(i->c, &s->inner);
    free(s);
    *FMUState = NULL;
    return (fmi3Status)status;
}

/* Serialized: the time (8 bytes, host order), then the FMI 2.0 layer's bytes. */
EXPORT3 fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState, size_t *size) {
    struct instance3 *i = instance;
    SERVE(i, "fmi3SerializedFMUStateSize");
    struct state3 *s = FMUState;
    if (!i || !s || !size) return refuse(i, "fmi3SerializedFMUStateSize", "no state or size given");
    fmi2Status status = fmi2SerializedFMUstateSize(i->c, s->inner, size);
    if (status < fmi2Discard) *size += sizeof s->time;
    return (fmi3Status)status;
}

EXPORT3 fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState, fmi3Byte serializedState[],
                                         size_t size) {
    struct instance3 *i = instance;
    SERVE(i, "fmi3SerializeFMUState");
    struct state3 *s = FMUState;
    if (!i || !s || !serializedState || size < sizeof s->time)
        return refuse(i, "fmi3SerializeFMUState", "no state, or a buffer smaller than the serialized size");
    memcpy(serializedState, &s->time, sizeof s->time);
    return (fmi3Status)fmi2SerializeFMUstate(i->c, s->inner, (fmi2Byte *)serializedState + sizeof s->time,
                                             size - sizeof s->time);
}

EXPORT3 fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[], size_t size,
                                           fmi3FMUState *FMUState) {
    struct instance3 *i = instance;
    SERVE(i, "fmi3DeserializeFMUState");
    double time;
    if (!i || !serializedState || !FMUState || size < sizeof time)
        return refuse(i, "fmi3DeserializeFMUState", "no state bytes, too few of them, or no place for the state");
    memcpy(&time, serializedState, sizeof time);
    struct state3 *s = *FMUState;
    int fresh = s == NULL;
    if (fresh && !(s = calloc(1, sizeof *s))) return refuse(i, "fmi3DeserializeFMUState", "out of memory");
    fmi2Status status = fmi2DeSerializeFMUstate(i->c, (const fmi2Byte *)serializedState + sizeof time,
                                                size - sizeof time, &s->inner);
    if (status >= fmi2Discard) {
        if (fresh) free(s);
        return (fmi3Status)status;
    }
    s->time = time;
    *FMUState = s;
    return (fmi3Status)status;
}

/* ---- Event Mode (only with eventModeUsed; nothing happens there) ------------------------------- */

EXPORT3 fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                            fmi3Boolean *terminateSimulation,
                                            fmi3Boolean *nominalsOfContinuousStatesChanged,
                                            fmi3Boolean *valuesOfContinuousStatesChanged,
                                            fmi3Boolean *nextEventTimeDefined, fmi3Float64 *nextEventTime) {
    struct instance3 *i = instance;
    SERVE(i, "fmi3UpdateDiscreteStates");
    if (check_mode(i, "fmi3UpdateDiscreteStates", 1 << EVENT)) return fmi3Error;
    fmi3Boolean *flags[] = {discreteStatesNeedUpdate, terminateSimulation, nominalsOfContinuousStatesChanged,
                            valuesOfContinuousStatesChanged, nextEventTimeDefined};
    for (size_t k = 0; k < sizeof flags / sizeof flags[0]; k++)
        if (flags[k]) *flags[k] = false;
    if (nextEventTime) *nextEventTime = 0.0;
    return fmi3OK;
}

EXPORT3 fmi3Status fmi3EnterStepMode(fmi3Instance instance) {
    struct instance3 *i = instance;
    SERVE(i, "fmi3EnterStepMode");
    if (check_mode(i, "fmi3EnterStepMode", 1 << EVENT)) return fmi3Error;
    i->mode = STEP;
    return fmi3OK;
}

/* ---- Stepping ---------------------------------------------------------------------------------- */

EXPORT3 fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                              fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                              fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                              fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    struct instance3 *i = instance;
    SERVE(i, "fmi3DoStep");
    double t = currentCommunicationPoint, reached = currentCommunicationPoint;
    fmi2Boolean terminate = 0;
    fmi2Status status;
    if (check_mode(i, "fmi3DoStep", 1 << STEP)) status = fmi2Error;
    else {
        status = fmi2DoStep(i->c, t, communicationStepSize, noSetFMUStatePriorToCurrentPoint);
        if (status < fmi2Discard) reached = t + communicationStepSize;
        else if (status == fmi2Discard) {
            fmi2Real last;
            if (fmi2GetRealStatus(i->c, fmi2LastSuccessfulTime, &last) == fmi2OK) reached = last;
            if (fmi2GetBooleanStatus(i->c, fmi2Terminated, &terminate) != fmi2OK) terminate = 0;
        }
        if (status <= fmi2Discard) i->time = reached;
    }
    if (eventHandlingNeeded) *eventHandlingNeeded = false;
    if (terminateSimulation) *terminateSimulation = terminate != 0;
    if (earlyReturn) *earlyReturn = false;
    if (lastSuccessfulTime) *lastSuccessfulTime = reached;
    return status > fmi2Fatal ? fmi3Error : (fmi3Status)status;
}
