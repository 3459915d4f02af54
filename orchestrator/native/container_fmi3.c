/* SPDX-License-Identifier: BSD-2-Clause */
/* The scenario container's FMI 3.0 Co-Simulation API (container.h). */

#include <stdio.h>
#include <stdlib.h>

#include "container.h"

/* ---- FMI 3.0 ------------------------------------------------------------------------------------

   The same container behind the FMI 3.0 Co-Simulation API (an FMU exported with --fmi 3 declares
   fmiVersion 3.0; the FMUs inside are FMI 2.0 or 3.0 as the scenario has them): each function maps
   onto its FMI 2.0 counterpart above (fmi3EnterInitializationMode = fmi2SetupExperiment +
   fmi2EnterInitializationMode, Float64 = Real, Int32 = Integer), scalar variables only, no event
   mode. Compiled against the official FMI 3.0 headers (fmi/), so every signature is the standard's. */

static fmi3Status unsupported3(fmi3Instance instance, const char *function) {
    say(instance, fmi2Error, "%s is not supported by the scenario container", function);
    return fmi3Error;
}

FMI3_Export const char *fmi3GetVersion(void) { return fmi3Version; }

FMI3_Export fmi3Instance fmi3InstantiateCoSimulation(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath, fmi3Boolean visible,
    fmi3Boolean loggingOn, fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
    const fmi3ValueReference requiredIntermediateVariables[], size_t nRequiredIntermediateVariables,
    fmi3InstanceEnvironment instanceEnvironment, fmi3LogMessageCallback logMessage,
    fmi3IntermediateUpdateCallback intermediateUpdate) {
    (void)resourcePath, (void)visible, (void)eventModeUsed, (void)earlyReturnAllowed;
    (void)requiredIntermediateVariables, (void)nRequiredIntermediateVariables, (void)intermediateUpdate;
    struct container *x = calloc(1, sizeof *x);
    if (!x) return NULL;
    snprintf(x->name, sizeof x->name, "%s", instanceName ? instanceName : "container");
    x->logging = loggingOn;
    x->log3 = (void (*)(void *, int, const char *, const char *))logMessage;
    x->env3 = instanceEnvironment;
    return create(x, "fmi3InstantiateCoSimulation", instantiationToken);
}

FMI3_Export fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                                      fmi3String resourcePath, fmi3Boolean visible,
                                                      fmi3Boolean loggingOn,
                                                      fmi3InstanceEnvironment instanceEnvironment,
                                                      fmi3LogMessageCallback logMessage) {
    (void)instanceName, (void)instantiationToken, (void)resourcePath, (void)visible, (void)loggingOn;
    if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError", "Co-Simulation only");
    return NULL;
}

FMI3_Export fmi3Instance fmi3InstantiateScheduledExecution(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath, fmi3Boolean visible,
    fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment, fmi3LogMessageCallback logMessage,
    fmi3ClockUpdateCallback clockUpdate, fmi3LockPreemptionCallback lockPreemption,
    fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instanceName, (void)instantiationToken, (void)resourcePath, (void)visible, (void)loggingOn;
    (void)clockUpdate, (void)lockPreemption, (void)unlockPreemption;
    if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError", "Co-Simulation only");
    return NULL;
}

FMI3_Export void fmi3FreeInstance(fmi3Instance instance) { fmi2FreeInstance(instance); }

/* The FMI 2.0 function's messages name the FMI 3.0 one it serves. */
static void serving(fmi3Instance instance, const char *function) {
    if (instance) ((struct container *)instance)->serving = function;
}

FMI3_Export fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                                           const fmi3String categories[]) {
    serving(instance, __func__);
    fmi2Status s = fmi2SetDebugLogging(instance, loggingOn, nCategories, categories);
    serving(instance, NULL);
    return (fmi3Status)s;
}

FMI3_Export fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
                                                   fmi3Float64 tolerance, fmi3Float64 startTime,
                                                   fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    serving(instance, __func__);
    fmi2Status s =
        fmi2SetupExperiment(instance, toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime);
    serving(instance, NULL);
    return (fmi3Status)(s == fmi2OK ? fmi2EnterInitializationMode(instance) : s);
}

FMI3_Export fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    return (fmi3Status)fmi2ExitInitializationMode(instance);
}

FMI3_Export fmi3Status fmi3Terminate(fmi3Instance instance) { return (fmi3Status)fmi2Terminate(instance); }

FMI3_Export fmi3Status fmi3Reset(fmi3Instance instance) { return (fmi3Status)fmi2Reset(instance); }

FMI3_Export fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                                  fmi3Float64 communicationStepSize,
                                  fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                  fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                                  fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    fmi2Status s = fmi2DoStep(instance, currentCommunicationPoint, communicationStepSize,
                              noSetFMUStatePriorToCurrentPoint);
    if (eventHandlingNeeded) *eventHandlingNeeded = fmi3False;
    if (terminateSimulation) *terminateSimulation = fmi3False;
    if (earlyReturn) *earlyReturn = fmi3False;
    if (lastSuccessfulTime && instance) {
        const struct container *x = instance;
        *lastSuccessfulTime = plan_time(&x->plan, x->k);
    }
    return (fmi3Status)s;
}

/* Scalar variables only: one value per value reference; the arrays readable (container_arrays). */
static int scalars(fmi3Instance instance, const char *function, const fmi3ValueReference valueReferences[],
                   size_t nValueReferences, const void *values, size_t nValues) {
    if (!instance) return 0;
    if (nValues != nValueReferences) {
        say(instance, fmi2Error, "%s: the container's variables are scalars: %zu values for %zu value references",
            function, nValues, nValueReferences);
        return 0;
    }
    return container_arrays(instance, function, nValueReferences, valueReferences, values);
}


FMI3_Export fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                      size_t nValueReferences, fmi3Float64 values[], size_t nValues) {
    if (!scalars(instance, __func__, valueReferences, nValueReferences, values, nValues)) return fmi3Error;
    return (fmi3Status)fmi2GetReal(instance, valueReferences, nValueReferences, values);
}

FMI3_Export fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                      size_t nValueReferences, const fmi3Float64 values[], size_t nValues) {
    if (!scalars(instance, __func__, valueReferences, nValueReferences, values, nValues)) return fmi3Error;
    return (fmi3Status)fmi2SetReal(instance, valueReferences, nValueReferences, values);
}

FMI3_Export fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                    size_t nValueReferences, fmi3Int32 values[], size_t nValues) {
    if (!scalars(instance, __func__, valueReferences, nValueReferences, values, nValues)) return fmi3Error;
    return (fmi3Status)fmi2GetInteger(instance, valueReferences, nValueReferences, values);
}

FMI3_Export fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                    size_t nValueReferences, const fmi3Int32 values[], size_t nValues) {
    if (!scalars(instance, __func__, valueReferences, nValueReferences, values, nValues)) return fmi3Error;
    return (fmi3Status)fmi2SetInteger(instance, valueReferences, nValueReferences, values);
}

FMI3_Export fmi3Status fmi3GetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                      size_t nValueReferences, fmi3Boolean values[], size_t nValues) {
    if (!scalars(instance, __func__, valueReferences, nValueReferences, values, nValues)) return fmi3Error;
    for (size_t j = 0; j < nValueReferences; j++) {
        fmi2Boolean value;
        fmi2Status s = fmi2GetBoolean(instance, &valueReferences[j], 1, &value);
        if (s != fmi2OK) return (fmi3Status)s;
        values[j] = value != 0;
    }
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3SetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                      size_t nValueReferences, const fmi3Boolean values[], size_t nValues) {
    if (!scalars(instance, __func__, valueReferences, nValueReferences, values, nValues)) return fmi3Error;
    for (size_t j = 0; j < nValueReferences; j++) {
        fmi2Boolean value = values[j] ? 1 : 0;
        fmi2Status s = fmi2SetBoolean(instance, &valueReferences[j], 1, &value);
        if (s != fmi2OK) return (fmi3Status)s;
    }
    return fmi3OK;
}

/* Everything else of the FMI 3.0 API (Model Exchange, Scheduled Execution, clocks, event mode,
   other types, states, derivatives): one message and fmi3Error. */
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-parameter"
#define UNSUPPORTED(name, params)                                                                             \
    FMI3_Export fmi3Status name params { return unsupported3(instance, #name); }
UNSUPPORTED(fmi3EnterEventMode, (fmi3Instance instance))
UNSUPPORTED(fmi3GetFloat32, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3Float32 values[], size_t nValues))
UNSUPPORTED(fmi3GetInt8, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3Int8 values[], size_t nValues))
UNSUPPORTED(fmi3GetUInt8, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3UInt8 values[], size_t nValues))
UNSUPPORTED(fmi3GetInt16, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3Int16 values[], size_t nValues))
UNSUPPORTED(fmi3GetUInt16, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3UInt16 values[], size_t nValues))
UNSUPPORTED(fmi3GetUInt32, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3UInt32 values[], size_t nValues))
UNSUPPORTED(fmi3GetInt64, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3Int64 values[], size_t nValues))
UNSUPPORTED(fmi3GetUInt64, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3UInt64 values[], size_t nValues))
UNSUPPORTED(fmi3GetString, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3String values[], size_t nValues))
UNSUPPORTED(fmi3GetBinary, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, size_t valueSizes[], fmi3Binary values[], size_t nValues))
UNSUPPORTED(fmi3GetClock, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3Clock values[]))
UNSUPPORTED(fmi3SetFloat32, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3Float32 values[], size_t nValues))
UNSUPPORTED(fmi3SetInt8, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3Int8 values[], size_t nValues))
UNSUPPORTED(fmi3SetUInt8, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3UInt8 values[], size_t nValues))
UNSUPPORTED(fmi3SetInt16, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3Int16 values[], size_t nValues))
UNSUPPORTED(fmi3SetUInt16, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3UInt16 values[], size_t nValues))
UNSUPPORTED(fmi3SetUInt32, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3UInt32 values[], size_t nValues))
UNSUPPORTED(fmi3SetInt64, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3Int64 values[], size_t nValues))
UNSUPPORTED(fmi3SetUInt64, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3UInt64 values[], size_t nValues))
UNSUPPORTED(fmi3SetString, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3String values[], size_t nValues))
UNSUPPORTED(fmi3SetBinary, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const size_t valueSizes[], const fmi3Binary values[], size_t nValues))
UNSUPPORTED(fmi3SetClock, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3Clock values[]))
UNSUPPORTED(fmi3GetNumberOfVariableDependencies, (fmi3Instance instance, fmi3ValueReference valueReference,
            size_t* nDependencies))
UNSUPPORTED(fmi3GetVariableDependencies, (fmi3Instance instance, fmi3ValueReference dependent,
            size_t elementIndicesOfDependent[], fmi3ValueReference independents[],
            size_t elementIndicesOfIndependents[], fmi3DependencyKind dependencyKinds[],
            size_t nDependencies))
UNSUPPORTED(fmi3GetFMUState, (fmi3Instance instance, fmi3FMUState* FMUState))
UNSUPPORTED(fmi3SetFMUState, (fmi3Instance instance, fmi3FMUState FMUState))
UNSUPPORTED(fmi3FreeFMUState, (fmi3Instance instance, fmi3FMUState* FMUState))
UNSUPPORTED(fmi3SerializedFMUStateSize, (fmi3Instance instance, fmi3FMUState FMUState, size_t* size))
UNSUPPORTED(fmi3SerializeFMUState, (fmi3Instance instance, fmi3FMUState FMUState, fmi3Byte serializedState[],
            size_t size))
UNSUPPORTED(fmi3DeserializeFMUState, (fmi3Instance instance, const fmi3Byte serializedState[], size_t size,
            fmi3FMUState* FMUState))
UNSUPPORTED(fmi3GetDirectionalDerivative, (fmi3Instance instance, const fmi3ValueReference unknowns[],
            size_t nUnknowns, const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
            size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity))
UNSUPPORTED(fmi3GetAdjointDerivative, (fmi3Instance instance, const fmi3ValueReference unknowns[],
            size_t nUnknowns, const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
            size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity))
UNSUPPORTED(fmi3EnterConfigurationMode, (fmi3Instance instance))
UNSUPPORTED(fmi3ExitConfigurationMode, (fmi3Instance instance))
UNSUPPORTED(fmi3GetIntervalDecimal, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[]))
UNSUPPORTED(fmi3GetIntervalFraction, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[],
            fmi3IntervalQualifier qualifiers[]))
UNSUPPORTED(fmi3GetShiftDecimal, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3Float64 shifts[]))
UNSUPPORTED(fmi3GetShiftFraction, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[]))
UNSUPPORTED(fmi3SetIntervalDecimal, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3Float64 intervals[]))
UNSUPPORTED(fmi3SetIntervalFraction, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]))
UNSUPPORTED(fmi3SetShiftDecimal, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3Float64 shifts[]))
UNSUPPORTED(fmi3SetShiftFraction, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]))
UNSUPPORTED(fmi3EvaluateDiscreteStates, (fmi3Instance instance))
UNSUPPORTED(fmi3UpdateDiscreteStates, (fmi3Instance instance, fmi3Boolean* discreteStatesNeedUpdate,
            fmi3Boolean* terminateSimulation, fmi3Boolean* nominalsOfContinuousStatesChanged,
            fmi3Boolean* valuesOfContinuousStatesChanged, fmi3Boolean* nextEventTimeDefined,
            fmi3Float64* nextEventTime))
UNSUPPORTED(fmi3EnterContinuousTimeMode, (fmi3Instance instance))
UNSUPPORTED(fmi3CompletedIntegratorStep, (fmi3Instance instance,
            fmi3Boolean noSetFMUStatePriorToCurrentPoint, fmi3Boolean* enterEventMode,
            fmi3Boolean* terminateSimulation))
UNSUPPORTED(fmi3SetTime, (fmi3Instance instance, fmi3Float64 time))
UNSUPPORTED(fmi3SetContinuousStates, (fmi3Instance instance, const fmi3Float64 continuousStates[],
            size_t nContinuousStates))
UNSUPPORTED(fmi3GetContinuousStateDerivatives, (fmi3Instance instance, fmi3Float64 derivatives[],
            size_t nContinuousStates))
UNSUPPORTED(fmi3GetEventIndicators, (fmi3Instance instance, fmi3Float64 eventIndicators[],
            size_t nEventIndicators))
UNSUPPORTED(fmi3GetContinuousStates, (fmi3Instance instance, fmi3Float64 continuousStates[],
            size_t nContinuousStates))
UNSUPPORTED(fmi3GetNominalsOfContinuousStates, (fmi3Instance instance, fmi3Float64 nominals[],
            size_t nContinuousStates))
UNSUPPORTED(fmi3GetNumberOfEventIndicators, (fmi3Instance instance, size_t* nEventIndicators))
UNSUPPORTED(fmi3GetNumberOfContinuousStates, (fmi3Instance instance, size_t* nContinuousStates))
UNSUPPORTED(fmi3EnterStepMode, (fmi3Instance instance))
UNSUPPORTED(fmi3GetOutputDerivatives, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues))
UNSUPPORTED(fmi3ActivateModelPartition, (fmi3Instance instance, fmi3ValueReference clockReference,
            fmi3Float64 activationTime))
#undef UNSUPPORTED
#pragma GCC diagnostic pop
