/* SPDX-License-Identifier: BSD-2-Clause */
/* The shim's list of FMI 2.0 functions (an X macro), shared by the FMI 2.0 files (shim.h) and the
   FMI 3.0 layer (fmi3.h); the types are the official headers' (fmu_src/cbase/fmi)
   (the FMI 3.0 layer calls the FMI 2.0 functions of the same shared object). */

#ifndef FTC_FMI2_CALLS_H
#define FTC_FMI2_CALLS_H

#include <stddef.h>

#include "fmi2FunctionTypes.h" /* the official FMI 2.0 types (fmu_src/cbase/fmi) */

/* Every FMI 2.0 function that takes a component and returns a status: name, parameters, call.
   FMI2_PLAIN ones are forwarded to pythonfmu as they are; FMI2_DIRECT ones have a direct path
   (section "Direct calls" below) and are forwarded when it does not apply. */
#define FMI2_PLAIN(X)                                                                                         \
    X(fmi2SetDebugLogging, (fmi2Component c, fmi2Boolean on, size_t n, const fmi2String categories[]),        \
      (c, on, n, categories))                                                                                 \
    X(fmi2SetupExperiment,                                                                                    \
      (fmi2Component c, fmi2Boolean tolDefined, fmi2Real tol, fmi2Real start, fmi2Boolean stopDefined,        \
       fmi2Real stop),                                                                                        \
      (c, tolDefined, tol, start, stopDefined, stop))                                                         \
    X(fmi2EnterInitializationMode, (fmi2Component c), (c))                                                    \
    X(fmi2ExitInitializationMode, (fmi2Component c), (c))                                                     \
    X(fmi2Terminate, (fmi2Component c), (c))                                                                  \
    X(fmi2GetInteger, (fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]),            \
      (c, vr, n, v))                                                                                          \
    X(fmi2GetBoolean, (fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]),            \
      (c, vr, n, v))                                                                                          \
    X(fmi2GetString, (fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[]),              \
      (c, vr, n, v))                                                                                          \
    X(fmi2SetInteger, (fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[]),      \
      (c, vr, n, v))                                                                                          \
    X(fmi2SetBoolean, (fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[]),      \
      (c, vr, n, v))                                                                                          \
    X(fmi2SetString, (fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[]),        \
      (c, vr, n, v))                                                                                          \
    X(fmi2GetFMUstate, (fmi2Component c, fmi2FMUstate * state), (c, state))                                   \
    X(fmi2SetFMUstate, (fmi2Component c, fmi2FMUstate state), (c, state))                                     \
    X(fmi2FreeFMUstate, (fmi2Component c, fmi2FMUstate * state), (c, state))                                  \
    X(fmi2SerializedFMUstateSize, (fmi2Component c, fmi2FMUstate state, size_t * size), (c, state, size))     \
    X(fmi2SerializeFMUstate, (fmi2Component c, fmi2FMUstate state, fmi2Byte bytes[], size_t size),            \
      (c, state, bytes, size))                                                                                \
    X(fmi2DeSerializeFMUstate, (fmi2Component c, const fmi2Byte bytes[], size_t size, fmi2FMUstate * state),  \
      (c, bytes, size, state))                                                                                \
    X(fmi2GetDirectionalDerivative,                                                                           \
      (fmi2Component c, const fmi2ValueReference unknown[], size_t nUnknown, const fmi2ValueReference known[],\
       size_t nKnown, const fmi2Real dvKnown[], fmi2Real dvUnknown[]),                                        \
      (c, unknown, nUnknown, known, nKnown, dvKnown, dvUnknown))                                              \
    X(fmi2SetRealInputDerivatives,                                                                            \
      (fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer order[],                   \
       const fmi2Real value[]),                                                                               \
      (c, vr, n, order, value))                                                                               \
    X(fmi2GetRealOutputDerivatives,                                                                           \
      (fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer order[], fmi2Real value[]),\
      (c, vr, n, order, value))                                                                               \
    X(fmi2CancelStep, (fmi2Component c), (c))                                                                 \
    X(fmi2GetStatus, (fmi2Component c, const fmi2StatusKind s, fmi2Status * value), (c, s, value))            \
    X(fmi2GetIntegerStatus, (fmi2Component c, const fmi2StatusKind s, fmi2Integer * value), (c, s, value))    \
    X(fmi2GetStringStatus, (fmi2Component c, const fmi2StatusKind s, fmi2String * value), (c, s, value))

#define FMI2_DIRECT(X)                                                                                        \
    X(fmi2Reset, (fmi2Component c), (c))                                                                      \
    X(fmi2GetReal, (fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]), (c, vr, n, v))   \
    X(fmi2SetReal, (fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]),            \
      (c, vr, n, v))                                                                                          \
    X(fmi2DoStep, (fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior), (c, t, h, noSetPrior))   \
    X(fmi2GetRealStatus, (fmi2Component c, const fmi2StatusKind s, fmi2Real * value), (c, s, value))          \
    X(fmi2GetBooleanStatus, (fmi2Component c, const fmi2StatusKind s, fmi2Boolean * value), (c, s, value))

#define FMI2_FORWARDED(X) FMI2_PLAIN(X) FMI2_DIRECT(X)

#endif
