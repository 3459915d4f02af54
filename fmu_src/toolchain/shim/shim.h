/* SPDX-License-Identifier: BSD-2-Clause */
/* The shim's shared declarations: read this first.

   FMI 2.0 Co-Simulation shim in front of pythonfmu's binary: the FMU runs in any FMI host, with
   or without Python on the machine.

   pythonfmu 0.7.0's binaries/linux64/<model>.so does not link libpython: a host without Python
   in its process cannot dlopen it (undefined symbol: _Py_NoneStruct). The build installs this
   shim as binaries/linux64/<model>.so, keeps pythonfmu's binary beside it as
   <model>_pythonfmu.so, and bundles a CPython runtime in binaries/linux64/python/ (libpython,
   the two libraries it links, a zipped subset of the standard library; fmu_src/toolchain/runtime.py).
   libpython is carried xz-compressed, lib/libpython3.11.so.1.0.xz (1.9 MB instead of 2.6 MB
   deflated; python311.dll.xz likewise on Windows), and decoded only where it is loaded.
   At the first fmi2Instantiate the shim:

   1. looks for Python in the process: dlsym(RTLD_DEFAULT, "Py_IsInitialized"). A Python host
      (fmpy, libcosimpy, OMSimulator's Python API, any version) keeps its own interpreter: the
      FMU's code is plain Python that runs on 3.10 and later, and nothing is decoded;
   2. if there is none, loads zlib and expat (which libpython links) by soname, the machine's or
      else the runtime's fallback/ copies, then libpython with RTLD_NOW | RTLD_GLOBAL (so
      pythonfmu's undefined Python symbols resolve): one another FMU's shim loaded already, found
      by its soname (one process holds one libpython whatever the number of FMUs), else
      lib/libpython3.11.so.1.0.xz decoded (unpack.c, XZ Embedded in xz/: CRC64 checked, at most
      64 MiB) into the user's cache once, $XDG_CACHE_HOME/fixed-time-cosim/runtime/<hash of the
      .xz>/ (else ~/.cache/...; platform.c, ftc_decoded_file: written under a temporary name and
      linked into place, so racing processes all succeed and none loads half a file) and loaded
      by that path; where there is no usable cache (no HOME, a read-only or full disk) into a
      private folder of TMPDIR, removed once Python has started (Linux keeps the mapping). A
      lock shared by the process's shims (ftc_process_lock) makes FMUs instantiated at once in
      several threads decode and load it once. On Windows the runtime's copy in the user's cache
      (ftc_cached_copy_decoded) holds python311.dll decoded, else a copy in %TEMP%;
   3. if Python is not initialized, starts it isolated (start_python.c: PyConfig isolated mode,
      home and module search path inside this FMU's runtime folder, also for a decoded libpython;
      no site, no environment variable, no signal handler, no bytecode written) and releases the
      GIL. pythonfmu then finds Python
      initialized, so it neither initializes nor finalizes it, and takes the GIL with
      PyGILState_Ensure as it does in a Python host. A lock on the libpython file keeps FMUs
      instantiated in parallel threads from starting Python twice;
   4. opens <model>_pythonfmu.so with RTLD_NOW | RTLD_LOCAL and forwards the FMI calls to it
      (fmi2GetTypesPlatform and fmi2GetVersion it answers itself, "default" and "2.0", so that
      a host may call them before anything is loaded), except the calls of every communication
      step to the project's own slaves, which it makes itself on the same Python objects (see
      "Direct calls" below).

   When something is missing, fmi2Instantiate logs one message naming the model and what failed
   (host logger and stderr) and returns NULL. At unload and at exit the shim works around a
   double free in pythonfmu's binary (see unload()).

   The guard (section "Guard" below; docs/fmus/host-safety.md): pythonfmu trusts its host, and a
   host's mistake crashed the host (a resource location that does not exist, a call after a fatal
   error, a NULL logger). So before a call reaches pythonfmu the shim checks it, as the Modelica
   Reference FMUs do (one table of allowed states per function): the instance's FMI state, every
   value reference against the model description (type, causality, variability), the step size,
   the GUID; a refused call returns fmi2Error with one message naming the function and the reason
   and is not forwarded. After fmi2Error the instance is latched (only getters, fmi2Reset and
   fmi2FreeInstance go on), after fmi2Fatal only fmi2FreeInstance, which then leaves pythonfmu's
   half-destroyed component alone. pythonfmu gets the shim's own callbacks: its messages reach the
   host with a category and a format-safe text, and never a NULL logger. pythonfmu's components
   are kept for reuse after fmi2FreeInstance (section "Pool"): constructing one leaks 16-34 KB in
   pythonfmu 0.7.0, resetting one nothing.

   Operating-system calls go through platform.h, the lower C layer shared with the engine
   (fmu_src/cbase: platform.c, the official FMI headers).

   Files (as the Modelica Reference FMUs lay theirs out; docs/fmus/standalone.md, "Reading the
   shim"): fmi2_functions.c the FMI 2.0 API boundary (each exported function: the guard, then the
   call); guard.c the state machine and the arguments' checks; cosimulation.c the behaviour (the
   direct path into the slave's Python objects, else pythonfmu); loader.c Python and pythonfmu's
   binary, loaded once; pool.c pythonfmu's components kept for reuse; log.c messages to the host;
   resources.c the FMU's folder and resources; description.h the variable table the build
   generates (description.c, from the FMU's final modelDescription.xml); fmi3.h and fmi3_*.c the
   FMI 3.0 layer on top; start_python.c the bundled interpreter's isolated start; unpack.c the
   decoder of the runtime's .xz files, on XZ Embedded (xz/, 0BSD, unmodified).

   Needs a C compiler, libc and the pinned runtime's headers (for start_python.c only): the
   Python C-API functions are looked up with dlsym, so the shim links no libpython. */

#ifndef FTC_SHIM_H
#define FTC_SHIM_H

#include <stddef.h>

#include "fmi2_calls.h"
#include "description.h"
#include "platform.h"
#include "start_python.h"

#ifndef EXPORT /* the FMI 3.0 build defines it empty: its FMI 2.0 functions are internal */
#define EXPORT FTC_EXPORT
#endif
#ifndef FTC_VR_OFFSET /* the FMI 3.0 build: its value references are the FMI 2.0 ones plus this */
#define FTC_VR_OFFSET 0
#endif
#define RUNTIME_DIR "python"
#ifdef _WIN32
#define INNER_SUFFIX "_pythonfmu.dll"
#define SHIM_SUFFIX ".dll"
#else
#define INNER_SUFFIX "_pythonfmu.so"
#define SHIM_SUFFIX ".so"
#endif
#define TEXT 4096

/* pythonfmu's functions, resolved once by the loader (loader.c) before the first instance exists. */
#define DECLARE_POINTER(name, params, args) extern fmi2Status(*inner_##name) params;
FMI2_FORWARDED(DECLARE_POINTER)
#undef DECLARE_POINTER
extern fmi2Component (*inner_fmi2Instantiate)(fmi2String, fmi2Type, fmi2String, fmi2String,
                                              const fmi2CallbackFunctions *, fmi2Boolean, fmi2Boolean);
extern void (*inner_fmi2FreeInstance)(fmi2Component);

/* The FMI states an instance can be in (one bit each, so that a set of them is a mask). */
enum state {
    INSTANTIATED = 1,
    INITIALIZATION = 2,
    STEP_COMPLETE = 4,
    STEP_FAILED = 8, /* after fmi2Discard */
    TERMINATED = 16,
    ERROR = 32,      /* after fmi2Error: getters, fmi2Reset and fmi2FreeInstance only */
    FATAL = 64,      /* after fmi2Fatal: fmi2FreeInstance only */
};
#define ANY_STATE (INSTANTIATED | INITIALIZATION | STEP_COMPLETE | STEP_FAILED | TERMINATED)

/* A pythonfmu component and the callbacks it was given (it keeps a pointer to them), kept for
   reuse after its instance is freed (see "Pool"). */
struct instance;
struct pooled {
    fmi2Component c;
    fmi2CallbackFunctions callbacks; /* relay() with this entry as environment */
    struct instance *owner;          /* NULL while in the pool */
    char name[256];                  /* what pythonfmu was instantiated with (it keeps it) */
    char resources[TEXT];
    fmi2Boolean visible;
    int renamable;                   /* its slave is the project's: the shim renames it (bind_direct) */
    struct pooled *next;
};

/* What the shim hands the host as fmi2Component: pythonfmu's component, the guard's state and
   the direct path. */
struct direct;
struct instance {
    fmi2Component inner;        /* pythonfmu's component */
    struct pooled *pooled;      /* its pool entry */
    struct direct *direct;      /* NULL: every call forwarded (see "Direct calls") */
    int direct_allowed;         /* FTC_FMU_DIRECT is not "0" */
    char name[256];             /* instance name */
    fmi2Real last_successful_time; /* what pythonfmu's fmi2DoStep would record */
    fmi2Boolean wants_to_terminate;
    enum state state;
    fmi2CallbackFunctions host; /* the host's callbacks (all NULL if it gave none) */
    const char *serving;        /* the FMI 3.0 function being served, if any (messages name it) */
};

#ifdef FTC_TIME_VR /* the FMI 3.0 build: FMI 3.0 allows the getters in Instantiated too */
#define GET_STATES (INSTANTIATED | INITIALIZATION | STEP_COMPLETE | STEP_FAILED | TERMINATED)
#else
#define GET_STATES (INITIALIZATION | STEP_COMPLETE | STEP_FAILED | TERMINATED)
#endif
#define SET_STATES (INSTANTIATED | INITIALIZATION | STEP_COMPLETE)

/* ---- loader.c: Python and pythonfmu's binary, loaded once */
extern char model[256];        /* model identifier: the shim's file name without .so */
extern char python_info[TEXT]; /* "Python X.Y.Z bundled with the FMU" or "of the host process" */
extern char fmu_root[TEXT];    /* the unpacked FMU: <root>/binaries/<platform>/<model>.so */
/* Loads Python and pythonfmu's binary at the first call (once per process, under a lock); 0 when
   they are ready, else -1 and `why` points at the one message of the failed load. */
int ftc_load(const char **why);

/* ---- log.c: messages to the host */
void deliver(const fmi2CallbackFunctions *host, fmi2String instanceName, fmi2Status status, const char *category,
             const char *message);
void report(const fmi2CallbackFunctions *functions, fmi2String instanceName, fmi2Status status, const char *message);
void relay(fmi2ComponentEnvironment environment, fmi2String instanceName, fmi2Status status, fmi2String category,
           fmi2String message, ...);
void say(struct instance *i, fmi2Status status, const char *function, const char *format, ...)
    __attribute__((format(printf, 4, 5)));

/* ---- guard.c: the FMI state machine and the arguments' checks */
const char *state_name(enum state s);
fmi2Status settle(struct instance *i, fmi2Status status);
fmi2Status refuse(struct instance *i, const char *function, const char *reason);
fmi2Status allowed_in(struct instance *i, const char *function, int allowed, int in_error);
fmi2Status check_references(struct instance *i, const char *function, const fmi2ValueReference vr[], size_t n,
                            const void *values, int type, int set);
fmi2Status check_categories(struct instance *i, const char *function, size_t n, const fmi2String categories[]);
fmi2Status check_experiment(struct instance *i, const char *function, fmi2Boolean tolerance_defined,
                            fmi2Real tolerance, fmi2Real start, fmi2Boolean stop_defined, fmi2Real stop);
fmi2Status check_capability(struct instance *i, const char *function, int declared, const char *what);
fmi2Status check_pointer(struct instance *i, const char *function, const void *pointer, const char *what);
fmi2Status check_array(struct instance *i, const char *function, size_t n, const void *references,
                       const void *values, const char *what);

#define GUARD(function, allowed, in_error)                                                                   \
    struct instance *i = c;                                                                                  \
    if (!i) return fmi2Error;                                                                                \
    if (allowed_in(i, function, allowed, in_error) != fmi2OK) return fmi2Error

/* ---- pool.c: pythonfmu's components kept for reuse */
struct pooled *component_for(struct instance *i, fmi2Type type, fmi2String guid, const char *resources,
                             fmi2Boolean visible, fmi2Boolean loggingOn);
void give_back(struct pooled *p);
void empty_pool(void);

/* ---- cosimulation.c: the calls into Python (the direct path, else pythonfmu) */
void resolve_python_api(void *python);
int python_alive(void); /* the Python API is resolved and the interpreter still runs */
void bind_direct(struct instance *i);
void release_binding(struct instance *i);
fmi2Status get_real(struct instance *i, const fmi2ValueReference vr[], size_t n, fmi2Real v[]);
fmi2Status set_real(struct instance *i, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]);
fmi2Status do_step(struct instance *i, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior);

#endif
