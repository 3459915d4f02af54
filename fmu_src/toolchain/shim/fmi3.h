/* SPDX-License-Identifier: BSD-2-Clause */
/* The FMI 3.0 layer's shared declarations.

   FMI 3.0 Co-Simulation layer on the FMI 2.0 shim: the same pythonfmu slave, runtime and direct
   calls, behind the FMI 3.0 functions.

   The FMI 3.0 variant of an FMU is compiled from the FMI 2.0 shim's files and fmi3_functions.c,
   fmi3_values.c, fmi3_refused.c into binaries/x86_64-linux/<model>.so, beside the same pythonfmu
   binary <model>_pythonfmu.so and the same python/ runtime. The FMI 2.0 functions are internal
   there (EXPORT defined empty, the build passes -DEXPORT=): only fmi3* symbols are exported. Every FMI 3.0 function is either mapped on
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
     variables (providesIntermediateUpdate="false"), clocks (but in the clocked twin, fmi3_clocks.c),
     configuration mode, per-element
     dependencies, directional and adjoint derivatives, output derivatives, every Model Exchange
     function. */


#ifndef FTC_FMI3_H
#define FTC_FMI3_H

#include <stdbool.h>
#include <stdint.h>

#include "fmi2_calls.h"
#include "platform.h"

#if !defined FTC_TIME_VR || !defined FTC_VR_OFFSET
#error "compile with -DFTC_TIME_VR=ftc_time_vr -DFTC_VR_OFFSET=<FMI 3.0 - FMI 2.0 references>"
#endif
/* The value references that differ between FMUs (time's; the clocked twin's clock and interval,
   -DFTC_CLOCK_VR=ftc_clock_vr -DFTC_INTERVAL_VR=ftc_interval_vr) are constants of the variable
   table's object (fmu_src/toolchain/variable_table.py), so that every other object of the shim is
   the same for every FMU and compiled once per platform. */
extern const uint32_t ftc_time_vr, ftc_clock_vr, ftc_interval_vr;
#define VR_BUFFER 64 /* value references translated on the stack; more are allocated */

#define EXPORT3 FTC_EXPORT
#define TEXT 4096

#include "fmi3FunctionTypes.h" /* the official FMI 3.0 types (fmu_src/cbase/fmi) */

/* The FMI 2.0 functions of this shared object (fmi2_functions.c), internal in the FMI 3.0 build. */
#define PROTOTYPE(name, params, args) fmi2Status name params;
FMI2_FORWARDED(PROTOTYPE)
void fmi2FreeInstance(fmi2Component);
/* The FMI 2.0 layer's guard (guard.c): instantiate naming the FMI 3.0 function;
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

struct instance3 {
    fmi2Component c;                /* the FMI 2.0 shim's instance */
    fmi2CallbackFunctions functions; /* given to fmi2Instantiate: lives as long as the instance */
    fmi3InstanceEnvironment environment;
    fmi3LogMessageCallback log;
    enum mode mode;
    int event_mode_used;
    double time;                    /* the independent variable */
    char name[256];
    struct clock3 *clock;           /* the clocked twin's clock (fmi3_clocks.c); NULL otherwise */
};

/* An FMU state: the FMI 2.0 state and the time. */
struct state3 {
    fmi2FMUstate inner;
    double time;
};
void say3(fmi3InstanceEnvironment environment, fmi3LogMessageCallback log, fmi3Status status, const char *format,
          ...) __attribute__((format(printf, 4, 5)));
/* fmi3Error with a message naming the instance and function. */
fmi3Status refuse3(struct instance3 *i, const char *function, const char *reason);
/* fmi3OK if `function` may be called in the instance's mode (`allowed`: a mask of 1 << mode). */
fmi3Status check_mode(struct instance3 *i, const char *function, int allowed);

#ifdef FTC_CLOCK_VR
/* The clocked twin (fmi3_clocks.c, compiled into it alone): its clock's state, created with the
   instance; the outputs held at Exit Initialization Mode; fmi3UpdateDiscreteStates' activation;
   leaving Event Mode; a communication step (its length counted); clocked outputs served from what is held (1: all of the `n` FMI 2.0 value
   references were, `values` written). */
struct clock3 *ftc_clock_new(void);
void ftc_clock_free(struct clock3 *k);
fmi2Status ftc_clock_initialized(struct instance3 *i);
fmi2Status ftc_clock_update(struct instance3 *i);
void ftc_clock_leave(struct instance3 *i);
void ftc_clock_step(struct instance3 *i, double h);
int ftc_clock_get(struct instance3 *i, const fmi2ValueReference vr[], size_t n, fmi3Float64 values[]);
#endif

#endif
