/* SPDX-License-Identifier: BSD-2-Clause */
/* The core of the C executors: an embedded FMU's functions (FMI 2.0 or 3.0 Co-Simulation) and the
   plan's steps on them, making the same calls with the same arguments in the same order as the
   engine's Python master (orchestrator/master.py). Failures are data (struct failure), which the
   container turns into a message and the compiled executor hands to Python. */

#ifndef FTC_CORE_H
#define FTC_CORE_H

#include <stddef.h>
#include <stdint.h>

#include "fmi2FunctionTypes.h"
#include "fmi3FunctionTypes.h"
#include "plan.h"

/* The FMI functions a failure names, as the engine's Python master names them (FMI 2.0) and as
   fmu_function names them for the FMU's own version. */
enum function {
    DO_STEP, GET_REAL, SET_REAL, SET_INTEGER, GET_INTEGER, SET_BOOLEAN, SET_STRING, SETUP_EXPERIMENT, ENTER_INITIALIZATION,
    EXIT_INITIALIZATION, TERMINATE, RESET, INSTANTIATE, ENTER_EVENT, SET_CLOCK, UPDATE_DISCRETE, ENTER_STEP,
    GET_INTERVAL, GET_SHIFT, FUNCTIONS
};

/* A failure's status that is no FMI status: fmi3UpdateDiscreteStates asked to terminate, or still
   asked for another update after UPDATES calls; fmi3GetIntervalDecimal or fmi3GetShiftDecimal gave
   an interval that is not positive or a negative shift. */
#define TERMINATE_SIMULATION (-2)
#define NEVER_SETTLES (-3)
#define UNUSABLE_INTERVAL (-4)
#define UPDATES 100

/* A failed call: which component, which function, the status it returned (or -1: NULL from an
   instantiation; TERMINATE_SIMULATION, NEVER_SETTLES) and the time it was called at. */
struct failure {
    int component;
    int function;
    int status;
    double time;
};

/* One embedded FMU instance: its version and the functions the executors call. */
struct fmu {
    int version; /* 2 or 3 */
    void *instance;
    int broken; /* returned fmi2Fatal: no further call */
    int event_mode;      /* FMI 3.0, instantiated with eventModeUsed (it has clocks) */
    int in_event;        /* in Event Mode (from fmi3ExitInitializationMode with event mode used) */
    int event_requested; /* the last fmi3DoStep's eventHandlingNeeded */
    int ticked;          /* had an event at this time (core.c's scratch) */
    fmi2DoStepTYPE *do_step2;
    fmi2GetRealTYPE *get_real2;
    fmi2SetRealTYPE *set_real2;
    fmi2SetIntegerTYPE *set_integer2;
    fmi2GetIntegerTYPE *get_integer2;
    fmi2SetBooleanTYPE *set_boolean2;
    fmi2SetStringTYPE *set_string2;
    fmi2SetupExperimentTYPE *setup2;
    fmi2EnterInitializationModeTYPE *enter2;
    fmi2ExitInitializationModeTYPE *exit2;
    fmi2TerminateTYPE *terminate2;
    fmi2ResetTYPE *reset2;
    fmi2InstantiateTYPE *instantiate2;
    fmi2FreeInstanceTYPE *free2;
    fmi2SetDebugLoggingTYPE *debug2;
    fmi3DoStepTYPE *do_step3;
    fmi3GetFloat64TYPE *get_real3;
    fmi3SetFloat64TYPE *set_real3;
    fmi3SetInt32TYPE *set_integer3;
    fmi3SetBooleanTYPE *set_boolean3;
    fmi3SetStringTYPE *set_string3;
    fmi3EnterInitializationModeTYPE *enter3;
    fmi3ExitInitializationModeTYPE *exit3;
    fmi3TerminateTYPE *terminate3;
    fmi3ResetTYPE *reset3;
    fmi3InstantiateCoSimulationTYPE *instantiate3;
    fmi3FreeInstanceTYPE *free3;
    fmi3SetDebugLoggingTYPE *debug3;
    fmi3EnterEventModeTYPE *enter_event3; /* the clock functions: bound by fmu_bind_clocks */
    fmi3SetClockTYPE *set_clock3;
    fmi3UpdateDiscreteStatesTYPE *update3;
    fmi3EnterStepModeTYPE *enter_step3;
    fmi3GetIntervalDecimalTYPE *interval3;
    fmi3GetShiftDecimalTYPE *shift3;
};

/* Looks up the functions of `library` (a dlopen handle); `lifecycle` also those the container
   needs to instantiate, initialize, terminate and free. 0, or -1 with `why` naming a missing one. */
int fmu_bind(struct fmu *f, void *library, int version, int lifecycle, char *why, size_t size);

/* Looks up the FMI 3.0 functions an FMU with clocks needs and marks it as driven in event mode; as
   fmu_bind. */
int fmu_bind_clocks(struct fmu *f, void *library, char *why, size_t size);

const char *fmu_function(int version, int function); /* "fmi2DoStep", "fmi3DoStep" ... */
const char *fmu_status(int version, int status);     /* "fmi2Error", "fmi3Error" ... */

int fmu_set_debug_logging(struct fmu *f, int on, size_t n, const char *const categories[]);
int fmu_reset(struct fmu *f);
void fmu_free(struct fmu *f);

/* The plan on its FMUs and value buffer. */
struct core {
    const struct plan *plan;
    struct fmu *fmus; /* one per component, in plan order */
    double *values;   /* [time, inputs..., outputs...] */
    struct clock *clocks; /* the plan's clocks, their intervals asked (core_ask_clocks) where 0 */
    struct failure failure;
};

/* One communication step from t_k to t_k+1 (values[0] = t_k+1 after it): with clocks, cut at every
   tick inside it, the ticks made there (see core.c). The driven inputs at the end of each piece are
   taken from *driven (the plan's driven batches in order), which advances past them (driven NULL
   or *driven NULL: none): 0, or the status of the failed call (>= fmi2Discard, or one of the
   statuses above), recorded in x->failure. */
int core_step(struct core *x, int64_t k, const double **driven);

/* The interval and shift of every clock whose plan gives none (interval 0), asked of its FMU in
   Initialization Mode (fmi3GetIntervalDecimal, fmi3GetShiftDecimal). An interval that is not
   positive or a shift below 0 is a failure of fmi3GetIntervalDecimal (UNUSABLE_INTERVAL). */
int core_ask_clocks(struct core *x, double t0);

/* gauss-seidel at a communication point: the propagation's reads and writes in dependency order. */
int core_propagate(struct core *x, double t);

/* Start values, setup and initialization mode of every FMU (start values again inside it). */
int core_enter_initialization(struct core *x, double t0, int stop_defined, double stop);

/* The master's initialization in initialization mode, then every FMU leaves it; with clocks, the
   event at t0 of every FMU that has them (still in Event Mode), every clock due there active. */
int core_exit_initialization(struct core *x, double t0);

/* fmi2Terminate of every FMU; the first failure is recorded, the others still terminated. */
int core_terminate(struct core *x, double t);

/* fmi2SetReal of one input of component i. */
int core_set_input(struct core *x, int i, unsigned int vr, const double *value, double t);

#endif
