/* SPDX-License-Identifier: BSD-2-Clause */
/* What the FMI 3.0 layer refuses (fmi3.h): types this FMU has no variable of, clocks,
   configuration mode, derivatives, Model Exchange and Scheduled Execution: fmi3Error and one
   message, nothing aborts the host. */

#include <stdarg.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3.h"

/* Types this FMU has no variable of: a call naming none is fine, any other is an error. */
static fmi3Status no_such_type(fmi3Instance instance, const char *function, const char *type,
                               size_t nValueReferences) {
    if (nValueReferences == 0) return instance ? fmi3OK : fmi3Error;
    char reason[128];
    snprintf(reason, sizeof reason, "this FMU has no %s variables", type);
    return refuse3(instance, function, reason);
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

#ifndef FTC_CLOCK_VR /* the clocked twin serves its clock (fmi3_clocks.c) */
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
#endif

/* ---- Refused features: fmi3Error and one message --------------------------------------------- */

#define REFUSED(name, reason, params, unused)                                                                \
    EXPORT3 fmi3Status name params {                                                                          \
        unused;                                                                                               \
        return refuse3(instance, #name, reason);                                                              \
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

#ifdef FTC_CLOCK_VR
/* the clocked twin: its clock's interval is the parameter sample_time, its shift 0 (fmi3_clocks.c) */
#define NO_CLOCKS "the clock's interval is the parameter sample_time and its shift 0: set sample_time (no fractions)"
#else
#define NO_CLOCKS "this FMU has no clocks"
REFUSED(fmi3GetIntervalDecimal, NO_CLOCKS,
        (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
         fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[]),
        ((void)valueReferences, (void)nValueReferences, (void)intervals, (void)qualifiers))
#endif
REFUSED(fmi3GetIntervalFraction, NO_CLOCKS,
        (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
         fmi3UInt64 counters[], fmi3UInt64 resolutions[], fmi3IntervalQualifier qualifiers[]),
        ((void)valueReferences, (void)nValueReferences, (void)counters, (void)resolutions, (void)qualifiers))
#ifndef FTC_CLOCK_VR
REFUSED(fmi3GetShiftDecimal, NO_CLOCKS,
        (fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
         fmi3Float64 shifts[]),
        ((void)valueReferences, (void)nValueReferences, (void)shifts))
#endif
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
REFUSED(fmi3EvaluateDiscreteStates, "discrete states are evaluated in Event Mode only "
        "(providesEvaluateDiscreteStates=\"false\")",
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
