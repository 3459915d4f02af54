/* SPDX-License-Identifier: BSD-2-Clause */
/* The FMI 3.0 API (fmi3.h): instantiation, the modes, FMU states and the step, mapped on the FMI
   2.0 layer of the same shared object. */

#include <stdarg.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3.h"

static const char *const MODE_NAMES[] = {"Instantiated", "Initialization Mode", "Event Mode", "Step Mode",
                                         "Terminated"};


/* One message to the instance's logger (if any) and to stderr. */
void say3(fmi3InstanceEnvironment environment, fmi3LogMessageCallback log, fmi3Status status,
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
fmi3Status refuse3(struct instance3 *i, const char *function, const char *reason) {
    if (!i) {
        fprintf(stderr, "%s: %s (no instance)\n", function, reason);
        return fmi3Error;
    }
    say3(i->environment, i->log, fmi3Error, "%s: %s: %s", i->name, function, reason);
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

fmi3Status check_mode(struct instance3 *i, const char *function, int allowed) {
    if (!i) return fmi3Error;
    SERVE(i, function);
    if (ftc_allowed(i->c, function, 0) != fmi2OK) return fmi3Error; /* after an error, said why */
    if (allowed & (1 << i->mode)) return fmi3OK;
    char reason[128];
    snprintf(reason, sizeof reason, "not allowed in %s", MODE_NAMES[i->mode]);
    return refuse3(i, function, reason);
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
    say3(instanceEnvironment, logMessage, fmi3Error,
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
    say3(instanceEnvironment, logMessage, fmi3Error,
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
        say3(instanceEnvironment, logMessage, fmi3Error,
            "%s: fmi3InstantiateCoSimulation: this FMU provides no intermediate update "
            "(providesIntermediateUpdate=\"false\"), %zu intermediate variables were required",
            name, nRequiredIntermediateVariables);
        return NULL;
    }
#ifdef FTC_CLOCK_VR
    if (!eventModeUsed) {
        say3(instanceEnvironment, logMessage, fmi3Error,
             "%s: fmi3InstantiateCoSimulation: this clocked FMU is activated by its input clock in Event Mode: "
             "instantiate it with eventModeUsed = true (an importer without Event Mode runs the FMU's plain "
             "FMI 3.0 or 2.0 variant)", name);
        return NULL;
    }
#endif
    struct instance3 *i = calloc(1, sizeof *i);
    if (!i) {
        say3(instanceEnvironment, logMessage, fmi3Error, "%s: fmi3InstantiateCoSimulation: out of memory", name);
        return NULL;
    }
#ifdef FTC_CLOCK_VR
    if (!(i->clock = ftc_clock_new())) {
        free(i);
        say3(instanceEnvironment, logMessage, fmi3Error, "%s: fmi3InstantiateCoSimulation: out of memory", name);
        return NULL;
    }
#endif
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
#ifdef FTC_CLOCK_VR
        ftc_clock_free(i->clock);
#endif
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
#ifdef FTC_CLOCK_VR
    ftc_clock_free(i->clock);
#endif
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
#ifdef FTC_CLOCK_VR
    if (status < fmi2Discard) { /* the outputs of Initialization Mode, held until the first activation */
        fmi2Status held = ftc_clock_initialized(i);
        status = held > status ? held : status;
    }
#endif
    if (status < fmi2Discard) i->mode = i->event_mode_used ? EVENT : STEP;
    return (fmi3Status)status;
}

EXPORT3 fmi3Status fmi3EnterEventMode(fmi3Instance instance) {
    struct instance3 *i = instance;
    SERVE(i, "fmi3EnterEventMode");
    if (check_mode(i, "fmi3EnterEventMode", 1 << STEP | 1 << EVENT)) return fmi3Error;
    if (!i->event_mode_used) return refuse3(i, "fmi3EnterEventMode", "instantiated with eventModeUsed = false");
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

/* ---- FMU state ------------------------------------------------------------------------------ */

EXPORT3 fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    struct instance3 *i = instance;
    SERVE(i, "fmi3GetFMUState");
    if (!i || !FMUState) return refuse3(i, "fmi3GetFMUState", "no place for the state (FMUState is NULL)");
    struct state3 *s = *FMUState; /* non-NULL: update that state */
    int fresh = s == NULL;
    if (fresh && !(s = calloc(1, sizeof *s))) return refuse3(i, "fmi3GetFMUState", "out of memory");
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
    if (!i || !s) return refuse3(i, "fmi3SetFMUState", "no state given (FMUState is NULL)");
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
    if (!i || !s || !size) return refuse3(i, "fmi3SerializedFMUStateSize", "no state or size given");
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
        return refuse3(i, "fmi3SerializeFMUState", "no state, or a buffer smaller than the serialized size");
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
        return refuse3(i, "fmi3DeserializeFMUState", "no state bytes, too few of them, or no place for the state");
    memcpy(&time, serializedState, sizeof time);
    struct state3 *s = *FMUState;
    int fresh = s == NULL;
    if (fresh && !(s = calloc(1, sizeof *s))) return refuse3(i, "fmi3DeserializeFMUState", "out of memory");
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
#ifdef FTC_CLOCK_VR
    fmi2Status activation = ftc_clock_update(i); /* the clock active: the law, once */
    if (activation >= fmi2Discard) return activation > fmi2Fatal ? fmi3Error : (fmi3Status)activation;
#endif
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
#ifdef FTC_CLOCK_VR
    ftc_clock_leave(i);
#endif
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
#ifdef FTC_CLOCK_VR
    else if (!(communicationStepSize >= 0.0)) { /* negative or NaN: what the FMI 2.0 guard would refuse */
        refuse3(i, "fmi3DoStep", "communicationStepSize is negative or NaN");
        status = fmi2Error;
    }
    else { /* the law runs at activations only (fmi3_clocks.c): a step advances time */
        (void)noSetFMUStatePriorToCurrentPoint;
        status = fmi2OK;
        reached = t + communicationStepSize;
        i->time = reached;
        ftc_clock_step(i, communicationStepSize);
    }
#else
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
#endif
    if (eventHandlingNeeded) *eventHandlingNeeded = false;
    if (terminateSimulation) *terminateSimulation = terminate != 0;
    if (earlyReturn) *earlyReturn = false;
    if (lastSuccessfulTime) *lastSuccessfulTime = reached;
    return status > fmi2Fatal ? fmi3Error : (fmi3Status)status;
}
