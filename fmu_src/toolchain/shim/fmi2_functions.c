/* SPDX-License-Identifier: BSD-2-Clause */
/* The FMI 2.0 API (shim.h): every exported fmi2* function, its state and arguments checked by the
   guard, then served by the direct path (cosimulation.c) or pythonfmu's binary. */

#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "shim.h"

/* call_<name>(c, ...): the pythonfmu function on the instance's own component. */
#define INNER_CALL(name, params, args)                                                                       \
    static fmi2Status call_##name params {                                                                   \
        c = ((struct instance *)c)->inner;                                                                   \
        return inner_##name args;                                                                            \
    }
FMI2_PLAIN(INNER_CALL)

/* ---- The FMI 2.0 functions: guard, then the direct path or pythonfmu ---------------------------- */

EXPORT fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    GUARD("fmi2GetReal", GET_STATES, 1);
    if (check_references(i, "fmi2GetReal", vr, n, v, 0, 0)) return fmi2Error;
    return settle(i, get_real(i, vr, n, v));
}

EXPORT fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
    GUARD("fmi2SetReal", SET_STATES, 0);
    if (check_references(i, "fmi2SetReal", vr, n, v, 0, 1)) return fmi2Error;
    return settle(i, set_real(i, vr, n, v));
}

EXPORT fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior) {
    GUARD("fmi2DoStep", STEP_COMPLETE, 0);
    if (!isfinite(h) || h <= 0.0 || !isfinite(t)) {
        char reason[160];
        snprintf(reason, sizeof reason, "the step from %g by %g: the step size must be a positive finite number, "
                 "the time finite", t, h);
        return refuse(i, "fmi2DoStep", reason);
    }
    fmi2Status status = do_step(i, t, h, noSetPrior);
    if (status == fmi2Discard) i->state = STEP_FAILED;
    return settle(i, status);
}

EXPORT fmi2Status fmi2Reset(fmi2Component c) {
    GUARD("fmi2Reset", ANY_STATE, 1);
    release_binding(i);
    fmi2Status status = inner_fmi2Reset(i->inner); /* pythonfmu constructs a new slave */
    i->last_successful_time = 0.0;
    i->wants_to_terminate = 0;
    if (status < fmi2Error) {
        bind_direct(i);
        i->state = INSTANTIATED;
    }
    return settle(i, status);
}

/* Once the direct path has made a step, pythonfmu's record of the last step is not current. */
EXPORT fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    GUARD("fmi2GetRealStatus", STEP_COMPLETE | STEP_FAILED | TERMINATED, 1);
    if (!value) return refuse(i, "fmi2GetRealStatus", "value is NULL");
    if (i->direct && s == fmi2LastSuccessfulTime) {
        *value = i->last_successful_time;
        return fmi2OK;
    }
    return settle(i, inner_fmi2GetRealStatus(i->inner, s, value));
}

EXPORT fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    GUARD("fmi2GetBooleanStatus", STEP_COMPLETE | STEP_FAILED | TERMINATED, 1);
    if (!value) return refuse(i, "fmi2GetBooleanStatus", "value is NULL");
    if (i->direct && s == fmi2Terminated) {
        *value = i->wants_to_terminate;
        return fmi2OK;
    }
    return settle(i, inner_fmi2GetBooleanStatus(i->inner, s, value));
}

EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }

EXPORT const char *fmi2GetVersion(void) { return "2.0"; }

/* fmi2Instantiate, and fmi3InstantiateCoSimulation for the FMI 3.0 layer (`function` names the
   host's call in messages). */
fmi2Component ftc_instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn, const char *function) {
    const char *failure;
    if (ftc_load(&failure) != 0) {
        report(functions, instanceName, fmi2Error, failure);
        return NULL;
    }
    char message[3 * TEXT], resources[TEXT], note[2 * TEXT];
    const char *problem = NULL;
    if (!instanceName) problem = "instanceName is NULL";
    else if (fmuType != fmi2CoSimulation) problem = "this FMU is a Co-Simulation FMU only";
    else if (!fmuGUID) problem = "the GUID (instantiation token) is NULL";
    else if (strcmp(fmuGUID, ftc_description.token) != 0) {
        snprintf(note, sizeof note, "the GUID (instantiation token) %s is not this FMU's %s (modelDescription.xml)",
                 fmuGUID, ftc_description.token);
        problem = note;
    }
    int found = 0;
    if (!problem)
        found = ftc_resources(&ftc_description, fmu_root, fmuResourceLocation, resources, sizeof resources, note,
                              sizeof note);
    if (found < 0) problem = note;
#ifdef _WIN32
    /* pythonfmu's Python imports the model from the resources folder and keeps its extension
       modules (.pyd) loaded: it gets a copy in the user's cache (see ftc_cached_copy), so that
       the host can delete what it unpacked; the same files, so the same model (the identity was
       checked on the folder given). Where there is no cache, the folder itself. */
    if (!problem) ftc_cached_copy(resources, NULL, resources, sizeof resources);
#endif
    char readable[TEXT]; /* what pythonfmu's binary can open: the same folder (see ftc_ascii_path) */
    if (!problem && ftc_ascii_path(resources, readable, sizeof readable) != 0) {
        snprintf(note, sizeof note, "the resources folder %s has no ASCII (8.3) name, which pythonfmu's binary "
                 "needs: unpack the FMU to a path of ASCII characters, or enable short names on its volume", resources);
        problem = note;
    }
    if (problem) {
        snprintf(message, sizeof message, "%s: %s: %s", model, function, problem);
        report(functions, instanceName, fmi2Error, message);
        return NULL;
    }
    struct instance *i = calloc(1, sizeof *i);
    if (!i) {
        report(functions, instanceName, fmi2Error, "fmi2 shim: out of memory");
        return NULL;
    }
    snprintf(i->name, sizeof i->name, "%s", instanceName);
    if (functions) i->host = *functions;
    if (found == 1) say(i, fmi2Warning, function, "%s", note);
    i->pooled = component_for(i, fmuType, fmuGUID, readable, visible, loggingOn);
    if (!i->pooled) {
        snprintf(message, sizeof message, "%s: pythonfmu could not instantiate %s in %s; instantiate with "
                 "logging on for its reason", model, instanceName, python_info);
        report(functions, instanceName, fmi2Error, message);
        free(i);
        return NULL;
    }
    i->inner = i->pooled->c;
    i->state = INSTANTIATED;
    const char *setting = getenv("FTC_FMU_DIRECT");
    i->direct_allowed = !(setting && strcmp(setting, "0") == 0);
    bind_direct(i);
    return i;
}

EXPORT fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                                     fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                                     fmi2Boolean visible, fmi2Boolean loggingOn) {
    return ftc_instantiate(instanceName, fmuType, fmuGUID, fmuResourceLocation, functions, visible, loggingOn,
                           "fmi2Instantiate");
}

EXPORT void fmi2FreeInstance(fmi2Component c) {
    struct instance *i = c;
    if (!i) return;
    release_binding(i);
    /* After fmi2Fatal pythonfmu has released its slave's objects already (and would release them
       again when deleting its component): the component is left as it is. */
    if (i->state == FATAL) i->pooled->owner = NULL;
    else give_back(i->pooled);
    free(i);
}

/* The FMI2_PLAIN functions: guarded, then pythonfmu's, called with its own component. */
#define MASK_fmi2SetDebugLogging ANY_STATE
#define MASK_fmi2SetupExperiment INSTANTIATED
#define MASK_fmi2EnterInitializationMode INSTANTIATED
#define MASK_fmi2ExitInitializationMode INITIALIZATION
/* Also in Initialization Mode, which the standard does not list: hosts terminate every instance
   when the initialization of another failed (the orchestrator does), and pythonfmu handles it. */
#define MASK_fmi2Terminate (INITIALIZATION | STEP_COMPLETE | STEP_FAILED)
#define MASK_fmi2GetFMUstate ANY_STATE
#define MASK_fmi2SetFMUstate ANY_STATE
#define MASK_fmi2FreeFMUstate ANY_STATE
#define MASK_fmi2SerializedFMUstateSize ANY_STATE
#define MASK_fmi2SerializeFMUstate ANY_STATE
#define MASK_fmi2DeSerializeFMUstate ANY_STATE
#define MASK_fmi2GetDirectionalDerivative GET_STATES
#define MASK_fmi2SetRealInputDerivatives SET_STATES
#define MASK_fmi2GetRealOutputDerivatives (STEP_COMPLETE | STEP_FAILED | TERMINATED)
#define MASK_fmi2CancelStep 0 /* fmi2DoStep never returns fmi2Pending */
#define MASK_fmi2GetStatus (STEP_COMPLETE | STEP_FAILED | TERMINATED)
#define MASK_fmi2GetIntegerStatus MASK_fmi2GetStatus
#define MASK_fmi2GetStringStatus MASK_fmi2GetStatus
/* Also allowed after fmi2Error: the getters (for the host's diagnosis) and logging. */
#define ERROR_fmi2SetDebugLogging 1
#define ERROR_fmi2GetDirectionalDerivative 1
#define ERROR_fmi2GetRealOutputDerivatives 1
#define ERROR_fmi2GetStatus 1
#define ERROR_fmi2GetIntegerStatus 1
#define ERROR_fmi2GetStringStatus 1
#define ERROR_fmi2SetupExperiment 0
#define ERROR_fmi2EnterInitializationMode 0
#define ERROR_fmi2ExitInitializationMode 0
#define ERROR_fmi2Terminate 0
#define ERROR_fmi2GetFMUstate 0
#define ERROR_fmi2SetFMUstate 0
#define ERROR_fmi2FreeFMUstate 0
#define ERROR_fmi2SerializedFMUstateSize 0
#define ERROR_fmi2SerializeFMUstate 0
#define ERROR_fmi2DeSerializeFMUstate 0
#define ERROR_fmi2SetRealInputDerivatives 0
#define ERROR_fmi2CancelStep 0
/* The state after a successful call (0: unchanged). */
#define NEXT_fmi2EnterInitializationMode INITIALIZATION
#define NEXT_fmi2ExitInitializationMode STEP_COMPLETE
#define NEXT_fmi2Terminate TERMINATED
#define NEXT_fmi2SetFMUstate (i->state == STEP_FAILED ? STEP_COMPLETE : 0)

/* The arguments' checks (see "Arguments"); `function` is the function's name. */
#define CHECK(call)                                                                                          \
    if ((call) != fmi2OK) return fmi2Error
#define ARGS_fmi2SetDebugLogging CHECK(check_categories(i, function, n, categories))
#define ARGS_fmi2SetupExperiment CHECK(check_experiment(i, function, tolDefined, tol, start, stopDefined, stop))
#define ARGS_fmi2EnterInitializationMode (void)function
#define ARGS_fmi2ExitInitializationMode (void)function
#define ARGS_fmi2Terminate (void)function
#ifdef FTC_TIME_VR /* the FMI 3.0 build: its model description's spelling */
#define FMU_STATE "FMUState"
#else
#define FMU_STATE "FMUstate"
#endif
#define CAN_GET_AND_SET                                                                                      \
    CHECK(check_capability(i, function, ftc_description.can_get_and_set_state, "canGetAndSet" FMU_STATE "=\"false\""))
#define CAN_SERIALIZE                                                                                        \
    CHECK(check_capability(i, function, ftc_description.can_get_and_set_state && ftc_description.can_serialize_state,  \
                           "canSerialize" FMU_STATE "=\"false\""))
#define ARGS_fmi2GetFMUstate CAN_GET_AND_SET; CHECK(check_pointer(i, function, state, "the FMUstate pointer"))
#define ARGS_fmi2SetFMUstate CAN_GET_AND_SET; CHECK(check_pointer(i, function, state, "the FMUstate"))
#define ARGS_fmi2FreeFMUstate                                                                                \
    CAN_GET_AND_SET;                                                                                         \
    CHECK(check_pointer(i, function, state, "the FMUstate pointer"));                                        \
    if (!*state) return fmi2OK /* the standard: a NULL state is ignored */
#define ARGS_fmi2SerializedFMUstateSize                                                                      \
    CAN_SERIALIZE;                                                                                           \
    CHECK(check_pointer(i, function, state, "the FMUstate"));                                                \
    CHECK(check_pointer(i, function, size, "the size pointer"))
#define ARGS_fmi2SerializeFMUstate                                                                           \
    CAN_SERIALIZE;                                                                                           \
    CHECK(check_pointer(i, function, state, "the FMUstate"));                                                \
    CHECK(check_pointer(i, function, bytes, "the byte array"))
#define ARGS_fmi2DeSerializeFMUstate                                                                         \
    CAN_SERIALIZE;                                                                                           \
    CHECK(check_pointer(i, function, bytes, "the byte array"));                                              \
    CHECK(check_pointer(i, function, state, "the FMUstate pointer"))
#define ARGS_fmi2GetDirectionalDerivative                                                                    \
    CHECK(check_capability(i, function, ftc_description.directional_derivatives,                                 \
                           "providesDirectionalDerivative=\"false\""));                                     \
    CHECK(check_array(i, function, nUnknown, unknown, dvUnknown, "unknowns"));                               \
    CHECK(check_array(i, function, nKnown, known, dvKnown, "knowns"))
#define ARGS_fmi2SetRealInputDerivatives                                                                     \
    CHECK(check_capability(i, function, ftc_description.interpolate_inputs, "canInterpolateInputs=\"false\""));  \
    CHECK(check_array(i, function, n, vr, order && value ? value : NULL, "input derivatives"))
#define ARGS_fmi2GetRealOutputDerivatives                                                                    \
    CHECK(check_capability(i, function, ftc_description.output_derivative_order > 0,                             \
                           "maxOutputDerivativeOrder=\"0\""));                                              \
    CHECK(check_array(i, function, n, vr, order && value ? value : NULL, "output derivatives"))
#define ARGS_fmi2CancelStep (void)function
#define ARGS_fmi2GetStatus CHECK(check_pointer(i, function, value, "value"))
#define ARGS_fmi2GetIntegerStatus ARGS_fmi2GetStatus
#define ARGS_fmi2GetStringStatus ARGS_fmi2GetStatus

#define FORWARD(name, params, args)                                                                          \
    EXPORT fmi2Status name params {                                                                          \
        const char *function = #name;                                                                        \
        GUARD(#name, MASK_##name, ERROR_##name);                                                             \
        ARGS_##name;                                                                                         \
        return settle(i, call_##name args);                                                                  \
    }
#define FORWARD_NEXT(name, params, args)                                                                     \
    EXPORT fmi2Status name params {                                                                          \
        const char *function = #name;                                                                        \
        GUARD(#name, MASK_##name, ERROR_##name);                                                             \
        ARGS_##name;                                                                                         \
        fmi2Status status = call_##name args;                                                                \
        int next = NEXT_##name;                                                                              \
        if (status < fmi2Discard && next) i->state = (enum state)next;                                       \
        return settle(i, status);                                                                            \
    }
/* Typed getters and setters: each value reference checked first. */
#define FORWARD_VALUES(name, params, args, type, set)                                                        \
    EXPORT fmi2Status name params {                                                                          \
        GUARD(#name, set ? SET_STATES : GET_STATES, !set);                                                   \
        if (check_references(i, #name, vr, n, v, type, set)) return fmi2Error;                               \
        return settle(i, call_##name args);                                                                  \
    }

FORWARD(fmi2SetDebugLogging, (fmi2Component c, fmi2Boolean on, size_t n, const fmi2String categories[]),
        (c, on, n, categories))
FORWARD(fmi2SetupExperiment,
        (fmi2Component c, fmi2Boolean tolDefined, fmi2Real tol, fmi2Real start, fmi2Boolean stopDefined,
         fmi2Real stop),
        (c, tolDefined, tol, start, stopDefined, stop))
FORWARD_NEXT(fmi2EnterInitializationMode, (fmi2Component c), (c))
FORWARD_NEXT(fmi2ExitInitializationMode, (fmi2Component c), (c))
FORWARD_NEXT(fmi2Terminate, (fmi2Component c), (c))
FORWARD_VALUES(fmi2GetInteger, (fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]),
               (c, vr, n, v), 1, 0)
FORWARD_VALUES(fmi2GetBoolean, (fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]),
               (c, vr, n, v), 2, 0)
FORWARD_VALUES(fmi2GetString, (fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[]),
               (c, vr, n, v), 3, 0)
FORWARD_VALUES(fmi2SetInteger, (fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[]),
               (c, vr, n, v), 1, 1)
FORWARD_VALUES(fmi2SetBoolean, (fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[]),
               (c, vr, n, v), 2, 1)
FORWARD_VALUES(fmi2SetString, (fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[]),
               (c, vr, n, v), 3, 1)
FORWARD(fmi2GetFMUstate, (fmi2Component c, fmi2FMUstate * state), (c, state))
FORWARD_NEXT(fmi2SetFMUstate, (fmi2Component c, fmi2FMUstate state), (c, state))
FORWARD(fmi2FreeFMUstate, (fmi2Component c, fmi2FMUstate * state), (c, state))
FORWARD(fmi2SerializedFMUstateSize, (fmi2Component c, fmi2FMUstate state, size_t * size), (c, state, size))
FORWARD(fmi2SerializeFMUstate, (fmi2Component c, fmi2FMUstate state, fmi2Byte bytes[], size_t size),
        (c, state, bytes, size))
FORWARD(fmi2DeSerializeFMUstate, (fmi2Component c, const fmi2Byte bytes[], size_t size, fmi2FMUstate * state),
        (c, bytes, size, state))
FORWARD(fmi2GetDirectionalDerivative,
        (fmi2Component c, const fmi2ValueReference unknown[], size_t nUnknown, const fmi2ValueReference known[],
         size_t nKnown, const fmi2Real dvKnown[], fmi2Real dvUnknown[]),
        (c, unknown, nUnknown, known, nKnown, dvKnown, dvUnknown))
FORWARD(fmi2SetRealInputDerivatives,
        (fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer order[], const fmi2Real value[]),
        (c, vr, n, order, value))
FORWARD(fmi2GetRealOutputDerivatives,
        (fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer order[], fmi2Real value[]),
        (c, vr, n, order, value))
FORWARD(fmi2CancelStep, (fmi2Component c), (c))
FORWARD(fmi2GetStatus, (fmi2Component c, const fmi2StatusKind s, fmi2Status * value), (c, s, value))
FORWARD(fmi2GetIntegerStatus, (fmi2Component c, const fmi2StatusKind s, fmi2Integer * value), (c, s, value))
FORWARD(fmi2GetStringStatus, (fmi2Component c, const fmi2StatusKind s, fmi2String * value), (c, s, value))
