/* SPDX-License-Identifier: BSD-2-Clause */
/* FMI 2.0 Co-Simulation shim in front of pythonfmu's binary: the FMU runs in any FMI host, with or
   without Python on the machine.

   pythonfmu 0.7.0's binaries/linux64/<model>.so does not link libpython: a host without Python
   in its process cannot dlopen it (undefined symbol: _Py_NoneStruct). The build installs this
   shim as binaries/linux64/<model>.so, keeps pythonfmu's binary beside it as
   <model>_pythonfmu.so, and bundles a CPython runtime in binaries/linux64/python/ (libpython,
   the two libraries it links, a zipped subset of the standard library; fmu_src/toolchain/runtime.py).
   At the first fmi2Instantiate the shim:

   1. looks for Python in the process: dlsym(RTLD_DEFAULT, "Py_IsInitialized"). A Python host
      (fmpy, libcosimpy, OMSimulator's Python API, any version) keeps its own interpreter: the
      FMU's code is plain Python that runs on 3.10 and later;
   2. if there is none, loads the bundled libpython with RTLD_NOW | RTLD_GLOBAL (so pythonfmu's
      undefined Python symbols resolve) by its soname: the shim's DT_RUNPATH is
      $ORIGIN/python/lib, and a libpython3.11 another FMU's shim loaded already is found by
      soname first, so one process holds one libpython whatever the number of FMUs. zlib and
      expat, which libpython links, are loaded the same way before it;
   3. if Python is not initialized, starts it isolated (start_python.c: PyConfig isolated mode,
      home and module search path inside this FMU's folder, no site, no environment variable,
      no signal handler, no bytecode written) and releases the GIL. pythonfmu then finds Python
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

   Operating-system calls go through platform.h (POSIX today).

   Needs a C compiler, libc and the pinned runtime's headers (for start_python.c only): the
   Python C-API functions are looked up with dlsym, so the shim links no libpython. */

#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2_types.h"
#include "guard.h"
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

/* pythonfmu's functions, resolved once by load() before the first instance exists. */
#define DECLARE_POINTER(name, params, args) static fmi2Status(*inner_##name) params;
FMI2_FORWARDED(DECLARE_POINTER)
static fmi2Component (*inner_fmi2Instantiate)(fmi2String, fmi2Type, fmi2String, fmi2String,
                                              const fmi2CallbackFunctions *, fmi2Boolean, fmi2Boolean);
static void (*inner_fmi2FreeInstance)(fmi2Component);

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

/* call_<name>(c, ...): the pythonfmu function on the instance's own component. */
#define INNER_CALL(name, params, args)                                                                       \
    static fmi2Status call_##name params {                                                                   \
        c = ((struct instance *)c)->inner;                                                                   \
        return inner_##name args;                                                                            \
    }
FMI2_PLAIN(INNER_CALL)

#ifndef _WIN32
static void unload(void);
#endif
static void resolve_python_api(void *python);

static ftc_mutex load_lock = FTC_MUTEX_INIT;
static int loaded;            /* 0: not tried, 1: pythonfmu's binary is ready, -1: failed */
static void *inner;           /* handle of <model>_pythonfmu.so */
static char model[256];       /* model identifier: the shim's file name without .so */
static char failure[TEXT];    /* the one message of a failed load() */
static char python_info[TEXT]; /* "Python X.Y.Z bundled with the FMU" or "of the host process" */
static struct ftc_model description; /* the model description's token and variables */

#ifndef _WIN32
/* Loads a library of the runtime by soname, globally: one already in the process is reused, else
   the search reaches the shim's DT_RUNPATH ($ORIGIN/python/lib, holding libpython only) and then
   the system's folders; `fallback` (a path), if given, is loaded where that finds nothing. */
static void *load_runtime_library(const char *soname, const char *fallback) {
    void *handle = ftc_library_open(soname, 1);
    if (!handle && fallback) handle = ftc_library_open(fallback, 1);
    if (!handle) {
        const char *name = fallback ? fallback : soname;
        snprintf(failure, TEXT, "%s: cannot load the bundled %s: %s", model, soname, ftc_library_error(name));
    }
    return handle;
}

#endif

/* Whether `library` is an FMU's bundled libpython (<home>/lib/<libpython> beside <home>/python311.zip);
   if so, writes <home>. */
static int bundled_home(const char *library, char home[TEXT]) {
    const char *suffix = FTC_LIBPYTHON_DIR FTC_LIBPYTHON;
    size_t n = strlen(library), m = strlen(suffix);
    if (n <= m || n - m >= TEXT || strcmp(library + n - m, suffix) != 0) return 0;
    snprintf(home, TEXT, "%.*s", (int)(n - m), library);
    char zip[TEXT + 32];
    snprintf(zip, sizeof zip, "%s/python" FTC_TAG ".zip", home);
    return ftc_is_file(zip);
}

/* Makes Python available if needed, then opens pythonfmu's binary. Called once, under load_lock. */
static int load(void) {
    char self[TEXT];
    if (ftc_library_file((void *)&load, self, sizeof self) != 0) {
        snprintf(failure, TEXT, "fmi2 shim: cannot find its own file (dladdr failed)");
        return -1;
    }
    char dir[TEXT];
    snprintf(dir, sizeof dir, "%s", self);
    char *slash = strrchr(dir, '/');
    const char *base = slash ? slash + 1 : dir;
    snprintf(model, sizeof model, "%s", base);
    char *dot = strrchr(model, '.');
    if (dot && strcmp(dot, SHIM_SUFFIX) == 0) *dot = '\0';
    if (slash) *slash = '\0';
    else snprintf(dir, sizeof dir, ".");
    char why[TEXT];
    if (ftc_read_model(self, &description, why, sizeof why) != 0) {
        snprintf(failure, TEXT, "%s: %s", model, why);
        return -1;
    }

    void *python = NULL; /* NULL: every library of the process */
    int own; /* Python is an FMU's bundled runtime (this one's or another's), not the host's */
#ifdef _WIN32
    /* Windows has no global symbol namespace: the bundled python311.dll is loaded by its full
       path where no module of the process exports Python (a Python host's own serves
       otherwise); then what pythonfmu's binary imports by name and the process lacks: the
       stable-ABI forwarder python3.dll (to whichever python311.dll is loaded) and the MSVC
       runtime. A DLL of that name already in the process is the one every import binds to. */
    /* The runtime and pythonfmu's binary are loaded from copies in the user's cache (see
       ftc_cached_copy), so that the host can delete the folder it unpacked once it has freed the
       instances and this library; where there is no cache, from that folder as before. */
    char runtime[TEXT + 16], inner_dir[TEXT], file[TEXT + 64];
    snprintf(runtime, sizeof runtime, "%s/%s", dir, RUNTIME_DIR);
    snprintf(file, sizeof file, "%s%s", model, INNER_SUFFIX);
    int cached = ftc_cached_copy(runtime, NULL, runtime, sizeof runtime) == 0 &&
                 ftc_cached_copy(dir, file, inner_dir, sizeof inner_dir) == 0;
    if (!cached) {
        snprintf(runtime, sizeof runtime, "%s/%s", dir, RUNTIME_DIR);
        snprintf(inner_dir, sizeof inner_dir, "%s", dir);
    }
    if (!ftc_library_symbol(NULL, "Py_IsInitialized")) {
        snprintf(file, sizeof file, "%s/%s", runtime, FTC_LIBPYTHON);
        if (!(python = ftc_library_open(file, 1))) {
            snprintf(failure, TEXT, "%s: cannot load the bundled %s: %s", model, file, ftc_library_error(file));
            return -1;
        }
    }
    static const char *const imported[] = {"vcruntime140.dll", "vcruntime140_1.dll", "msvcp140.dll", "python3.dll"};
    for (size_t k = 0; k < sizeof imported / sizeof imported[0]; k++) {
        snprintf(file, sizeof file, "%s/%s", runtime, imported[k]);
        if (!ftc_library_loaded(imported[k]) && !ftc_library_open(file, 1)) {
            snprintf(failure, TEXT, "%s: cannot load the bundled %s: %s", model, file, ftc_library_error(file));
            return -1;
        }
    }
#else
    if (!ftc_library_symbol(NULL, "Py_IsInitialized")) {
        char zlib[TEXT + 64], expat[TEXT + 64];
        snprintf(zlib, sizeof zlib, "%s/%s/fallback/libz.so.1", dir, RUNTIME_DIR);
        snprintf(expat, sizeof expat, "%s/%s/fallback/libexpat.so.1", dir, RUNTIME_DIR);
        if (!load_runtime_library("libz.so.1", zlib) || !load_runtime_library("libexpat.so.1", expat) ||
            !(python = load_runtime_library(FTC_LIBPYTHON, NULL)))
            return -1;
    }
#endif
    int (*is_initialized)(void) = (int (*)(void))ftc_library_symbol(python, "Py_IsInitialized");
    if (!is_initialized) {
        snprintf(failure, TEXT, "%s: %s has no Py_IsInitialized: not a libpython", model, FTC_LIBPYTHON);
        return -1;
    }
    /* The shims of two FMUs may start at once in different threads: the second may find the
       libpython the first loaded before the first started it. So whether Python is an FMU's own
       runtime is decided by the file that defines it (<home>/lib/libpython... beside
       <home>/python311.zip), whoever loaded it, and a lock on that file makes the first start it
       completely before the other looks. */
    char library[TEXT];
    if (ftc_library_file((void *)is_initialized, library, sizeof library) != 0)
        snprintf(library, sizeof library, "%s", FTC_LIBPYTHON);
#ifdef _WIN32
    if (!python) python = ftc_library_loaded(library); /* the host's: symbols are per DLL */
#endif
    char home[TEXT];
    own = bundled_home(library, home);
    int lock = ftc_file_lock(library);
    int status = 0;
    if (!is_initialized()) {
        if (own) {
            char reason[TEXT];
            status = ftc_start_python(python, home, reason, sizeof reason);
            if (status != 0)
                snprintf(failure, TEXT, "%s: cannot start the bundled Python in %s: %s", model, home, reason);
        } else { /* the host loaded a libpython of its own without starting it: start that one */
            void (*initialize)(int) = (void (*)(int))ftc_library_symbol(python, "Py_InitializeEx");
            void *(*save_thread)(void) = (void *(*)(void))ftc_library_symbol(python, "PyEval_SaveThread");
            if (initialize && save_thread) {
                initialize(0); /* 0: keep the host's signal handlers */
                save_thread();
            }
            status = is_initialized() ? 0 : -1;
            if (status != 0) snprintf(failure, TEXT, "%s: cannot initialize the host's Python (%s)", model, library);
        }
    }
    ftc_file_unlock(lock);
    if (status != 0) return -1;

    char path[TEXT + 300];
#ifdef _WIN32
    snprintf(path, sizeof path, "%s/%s%s", inner_dir, model, INNER_SUFFIX);
    int first = !ftc_library_loaded(path); /* else a former load of this folder kept its files */
#else
    snprintf(path, sizeof path, "%s/%s%s", dir, model, INNER_SUFFIX);
#endif
    inner = ftc_library_open(path, 0);
    if (!inner) {
        snprintf(failure, TEXT, "%s: cannot load pythonfmu's binary %s: %s", model, path, ftc_library_error(path));
        return -1;
    }
#ifdef _WIN32
    if (first) { /* the cache's files, or those of the unpacked folder where there is no cache */
        ftc_keep_files(inner_dir);
        ftc_keep_files(runtime);
    }
    ftc_keep_own_file(self);
#endif
    inner_fmi2Instantiate = (fmi2Component(*)(fmi2String, fmi2Type, fmi2String, fmi2String,
                                               const fmi2CallbackFunctions *, fmi2Boolean, fmi2Boolean))
        ftc_library_symbol(inner, "fmi2Instantiate");
    inner_fmi2FreeInstance = (void (*)(fmi2Component))ftc_library_symbol(inner, "fmi2FreeInstance");
    if (!inner_fmi2Instantiate || !inner_fmi2FreeInstance) {
        snprintf(failure, TEXT, "%s: %s lacks fmi2Instantiate or fmi2FreeInstance", model, path);
        return -1;
    }
    int complete = 1;
#define RESOLVE(name, params, args) complete &= (*(void **)(&inner_##name) = ftc_library_symbol(inner, #name)) != NULL;
    FMI2_FORWARDED(RESOLVE)
    if (!complete) {
        snprintf(failure, TEXT, "%s: %s lacks an FMI 2.0 function", model, path);
        return -1;
    }
#ifndef _WIN32 /* the double free below is pythonfmu's on Linux (its binary cannot be unloaded there) */
    atexit(unload); /* after pythonfmu's static destructors were registered: runs before them */
#endif
    resolve_python_api(python);
    const char *(*get_version)(void) = (const char *(*)(void))ftc_library_symbol(python, "Py_GetVersion");
    snprintf(python_info, TEXT, "Python %.*s %s", get_version ? (int)strcspn(get_version(), " ") : 1,
             get_version ? get_version() : "?", own ? "bundled with the FMU" : "of the host process");
    return 0;
}

/* One message to a host's logger: its text with '%' escaped (the logger takes a printf format),
   a category always. `host` NULL or without a logger: the message goes to stderr only. */
static void deliver(const fmi2CallbackFunctions *host, fmi2String instanceName, fmi2Status status,
                    const char *category, const char *message) {
    if (!category || !category[0])
        category = status == fmi2OK ? "logAll" : status == fmi2Warning ? "logStatusWarning" : "logStatusError";
    if (!host || !host->logger) {
        if (status >= fmi2Warning) fprintf(stderr, "%s: %s\n", instanceName ? instanceName : model, message);
        return;
    }
    char escaped[2 * TEXT];
    size_t j = 0;
    for (const char *p = message; *p && j + 2 < sizeof escaped; p++) {
        if (*p == '%') escaped[j++] = '%';
        escaped[j++] = *p;
    }
    escaped[j] = '\0';
    host->logger(host->componentEnvironment, instanceName ? instanceName : model, status, category, escaped);
}

/* One message to the host's logger (if any) and to stderr. */
static void report(const fmi2CallbackFunctions *functions, fmi2String instanceName, fmi2Status status,
                   const char *message) {
    if (functions && functions->logger) fprintf(stderr, "%s\n", message);
    deliver(functions, instanceName, status, NULL, message);
}

/* The logger pythonfmu gets: its message (plain text: pythonfmu passes no arguments, and a '%' in
   it is not a format) to the current owner's host, with a category where pythonfmu gives none. */
static void relay(fmi2ComponentEnvironment environment, fmi2String instanceName, fmi2Status status,
                  fmi2String category, fmi2String message, ...) {
    struct pooled *p = environment;
    struct instance *i = p ? p->owner : NULL;
    deliver(i ? &i->host : NULL, i ? i->name : instanceName, status, category, message ? message : "");
}

/* ---- Guard ------------------------------------------------------------------------------------- */

static const char *state_name(enum state s) {
    switch (s) {
    case INSTANTIATED: return "Instantiated";
    case INITIALIZATION: return "Initialization Mode";
    case STEP_COMPLETE: return "Step Complete";
    case STEP_FAILED: return "Step Failed (after fmi2Discard)";
    case TERMINATED: return "Terminated";
    case ERROR: return "Error";
    default: return "Fatal";
    }
}

static void say(struct instance *i, fmi2Status status, const char *function, const char *format, ...)
    __attribute__((format(printf, 4, 5)));

/* One message of the guard: "<function>: <reason>", to the host's logger and stderr. */
static void say(struct instance *i, fmi2Status status, const char *function, const char *format, ...) {
    char text[TEXT], message[TEXT + 64];
    va_list args;
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    snprintf(message, sizeof message, "%s: %s", i->serving ? i->serving : function, text);
    report(&i->host, i->name, status, message);
}

/* The state after a call that returned `status`: fmi2Error and fmi2Fatal latch the instance. */
static fmi2Status settle(struct instance *i, fmi2Status status) {
    if (status == fmi2Fatal) i->state = FATAL;
    else if (status >= fmi2Error && i->state != FATAL) i->state = ERROR;
    return status;
}

/* fmi2Error with one message, and the instance latched (the standard's Error state). */
static fmi2Status refuse(struct instance *i, const char *function, const char *reason) {
    say(i, fmi2Error, function, "%s", reason);
    return settle(i, fmi2Error);
}

/* fmi2OK if `function` may be called in the instance's state (`allowed`; `in_error`: also after
   fmi2Error), else fmi2Error and a message; a call after fmi2Fatal is never allowed. */
static fmi2Status allowed_in(struct instance *i, const char *function, int allowed, int in_error) {
    if (i->state == FATAL) {
        say(i, fmi2Error, function, "not allowed after a fatal error: only fmi2FreeInstance is");
        return fmi2Error;
    }
    if (i->state == ERROR) {
        if (in_error) return fmi2OK;
        say(i, fmi2Error, function, "not allowed after an error: only getters, fmi2Reset and fmi2FreeInstance are");
        return fmi2Error;
    }
    if (allowed & (int)i->state) return fmi2OK;
    char reason[128];
    snprintf(reason, sizeof reason, "not allowed in %s", state_name(i->state));
    return refuse(i, function, reason);
}

#define GUARD(function, allowed, in_error)                                                                   \
    struct instance *i = c;                                                                                  \
    if (!i) return fmi2Error;                                                                                \
    if (allowed_in(i, function, allowed, in_error) != fmi2OK) return fmi2Error

static const char *TYPE_NAMES[] = {"Real", "Integer", "Boolean", "String"};
static const char TYPE_CODES[] = "ribs";

/* Whether variable `v` may be set in state `s`; NULL, or the reason it may not. */
static const char *unsettable(const struct ftc_variable *v, enum state s) {
    if (v->variability == 'c') return "is a constant";
    switch (v->causality) {
    case 'o': return "is an output";
    case 'c': return "is a calculated parameter";
    case 't': return "is the independent variable";
    case 'l':
        if ((s & (INSTANTIATED | INITIALIZATION)) && (v->initial == 'e' || v->initial == 'a')) return NULL;
        return "is a local variable";
    case 'i': return NULL;
    default: /* parameters */
        if (s & (INSTANTIATED | INITIALIZATION)) return NULL;
        return v->variability == 't' ? NULL : "is a fixed parameter";
    }
}

/* fmi2OK if every value reference names a variable of type `type` (an index into TYPE_NAMES) that
   may be read (`set` 0) or set in the current state; else fmi2Error and one message. */
static fmi2Status check_references(struct instance *i, const char *function, const fmi2ValueReference vr[],
                                   size_t n, const void *values, int type, int set) {
    char reason[TEXT];
    if (n > 0 && (!vr || !values)) {
        snprintf(reason, sizeof reason, "%zu values asked for, but the %s array is NULL", n,
                 !vr ? "value reference" : "value");
        return refuse(i, function, reason);
    }
    if (n > description.n) { /* the arrays cannot be that long: not read */
        snprintf(reason, sizeof reason, "%zu value references, more than the model's %zu variables", n,
                 description.n);
        return refuse(i, function, reason);
    }
    if (set && type == 3) /* a NULL string would reach pythonfmu's std::string */
        for (size_t k = 0; k < n; k++)
            if (!((const fmi2String *)values)[k]) {
                snprintf(reason, sizeof reason, "value[%zu] is NULL, not a string", k);
                return refuse(i, function, reason);
            }
    for (size_t k = 0; k < n; k++) {
        const struct ftc_variable *v = ftc_variable(&description, vr[k] + FTC_VR_OFFSET);
        const char *problem = NULL;
        if (!v) {
            snprintf(reason, sizeof reason, "no variable has the value reference %u", vr[k] + FTC_VR_OFFSET);
            return refuse(i, function, reason);
        }
        if (v->type != TYPE_CODES[type]) {
            const char *actual = strchr(TYPE_CODES, v->type) ? TYPE_NAMES[strchr(TYPE_CODES, v->type) - TYPE_CODES]
                                                             : "variable of another type";
            snprintf(reason, sizeof reason, "%s (value reference %u) is a%s %s, not a%s %s", v->name,
                     vr[k] + FTC_VR_OFFSET, actual[0] == 'I' ? "n" : "", actual, type == 1 ? "n" : "",
                     TYPE_NAMES[type]);
            return refuse(i, function, reason);
        }
        if (set && (problem = unsettable(v, i->state))) {
            snprintf(reason, sizeof reason, "%s (value reference %u) %s: it cannot be set in %s", v->name,
                     vr[k] + FTC_VR_OFFSET, problem, state_name(i->state));
            return refuse(i, function, reason);
        }
    }
    return fmi2OK;
}

#ifdef FTC_TIME_VR /* the FMI 3.0 build: FMI 3.0 allows the getters in Instantiated too */
#define GET_STATES (INSTANTIATED | INITIALIZATION | STEP_COMPLETE | STEP_FAILED | TERMINATED)
#else
#define GET_STATES (INITIALIZATION | STEP_COMPLETE | STEP_FAILED | TERMINATED)
#endif
#define SET_STATES (INSTANTIATED | INITIALIZATION | STEP_COMPLETE)

/* Served by the FMI 3.0 layer of this shared object (fmi3_shim.c): messages name its function;
   and its own refusals latch the instance too. */
void ftc_serving(fmi2Component c, const char *function) {
    if (c) ((struct instance *)c)->serving = function;
}

fmi2Status ftc_latch(fmi2Component c, fmi2Status status) { return c ? settle(c, status) : status; }

fmi2Status ftc_allowed(fmi2Component c, const char *function, int in_error) {
    return c ? allowed_in(c, function, ANY_STATE, in_error) : fmi2Error;
}

size_t ftc_variable_count(void) { return description.n; }

/* ---- Arguments ---------------------------------------------------------------------------------

   Each function's pointers, counts and times, checked after its state (ARGS_<name> in the
   FORWARD macros below): 0, or fmi2Error with one message (the call is then not forwarded). */

#define REFUSE_IF(condition, ...)                                                                             \
    do {                                                                                                      \
        if (condition) {                                                                                      \
            char reason_[TEXT];                                                                               \
            snprintf(reason_, sizeof reason_, __VA_ARGS__);                                                   \
            return refuse(i, function, reason_);                                                              \
        }                                                                                                     \
    } while (0)

static fmi2Status check_categories(struct instance *i, const char *function, size_t n,
                                   const fmi2String categories[]) {
    REFUSE_IF(n > 0 && !categories, "%zu categories given, but the categories array is NULL", n);
    for (size_t k = 0; k < n; k++) REFUSE_IF(!categories[k], "categories[%zu] is NULL, not a category name", k);
    return fmi2OK;
}

/* The experiment's times: the start finite; the stop (if defined) finite and not before the start;
   the tolerance (if defined) positive and finite. Values not defined are ignored, as the standard says. */
static fmi2Status check_experiment(struct instance *i, const char *function, fmi2Boolean tolerance_defined,
                                   fmi2Real tolerance, fmi2Real start, fmi2Boolean stop_defined, fmi2Real stop) {
    REFUSE_IF(!isfinite(start), "the start time %g is not a finite number", start);
    REFUSE_IF(stop_defined && !isfinite(stop), "the stop time %g is not a finite number", stop);
    REFUSE_IF(stop_defined && stop < start, "the stop time %g is before the start time %g", stop, start);
    REFUSE_IF(tolerance_defined && !(isfinite(tolerance) && tolerance > 0.0),
              "the tolerance %g is not a positive finite number", tolerance);
    return fmi2OK;
}

/* A capability the model description declares false: the standard says the function must not be called. */
static fmi2Status check_capability(struct instance *i, const char *function, int declared, const char *what) {
    REFUSE_IF(!declared, "not provided: the model description declares %s", what);
    return fmi2OK;
}

static fmi2Status check_pointer(struct instance *i, const char *function, const void *pointer, const char *what) {
    REFUSE_IF(!pointer, "%s is NULL", what);
    return fmi2OK;
}

/* Arrays of `n` value references (and values): not NULL when n > 0, n not beyond the variables. */
static fmi2Status check_array(struct instance *i, const char *function, size_t n, const void *references,
                              const void *values, const char *what) {
    REFUSE_IF(n > 0 && (!references || !values), "%zu %s asked for, but an array is NULL", n, what);
    REFUSE_IF(n > description.n, "%zu %s, more than the model's %zu variables", n, what, description.n);
    return fmi2OK;
}

/* ---- Pool ----------------------------------------------------------------------------------------

   pythonfmu 0.7.0 leaks 16-34 KB every time it constructs a component (its findClass runs the
   FMU's script again and keeps references to the classes it made; each constructor also puts the
   resources folder on sys.path once more), and nothing when it resets one. So a freed instance's
   component is kept, and the next fmi2Instantiate with the same resources folder and visibility
   resets it (pythonfmu constructs a new Python slave from the class it found, as fmi2Reset does)
   instead of constructing another: one of the same instance name if there is one, else any whose
   slave is the project's (renamable). pythonfmu constructs the new slave under the name it was
   first instantiated with; bind_direct renames it (its instance_name) to the new instance's, and
   the shim's logger gives the host the new name, so hosts that name every instance anew (run0,
   run1, ... as campaign tools and FMPy do) leak nothing either. At most POOL_SIZE are kept; the
   pool is emptied when the shim is unloaded. */

#define POOL_SIZE 16
static ftc_mutex pool_lock = FTC_MUTEX_INIT;
static struct pooled *pool;
static size_t pooled_count;

static struct pooled *take(const char *name, const char *resources, fmi2Boolean visible) {
    ftc_lock(&pool_lock);
    struct pooled **p = &pool;
    while (*p && (strcmp((*p)->name, name) || strcmp((*p)->resources, resources) || (*p)->visible != visible))
        p = &(*p)->next;
    if (!*p) /* none of this name: one that can be renamed */
        for (p = &pool; *p && (!(*p)->renamable || strcmp((*p)->resources, resources) || (*p)->visible != visible);)
            p = &(*p)->next;
    struct pooled *found = *p;
    if (found) {
        *p = found->next;
        pooled_count--;
    }
    ftc_unlock(&pool_lock);
    return found;
}

static void give_back(struct pooled *p) {
    p->owner = NULL;
    ftc_lock(&pool_lock);
    int kept = pooled_count < POOL_SIZE;
    if (kept) {
        p->next = pool;
        pool = p;
        pooled_count++;
    }
    ftc_unlock(&pool_lock);
    if (!kept) {
        inner_fmi2FreeInstance(p->c);
        free(p);
    }
}

#ifndef _WIN32 /* see unload(): Windows leaves the components to the end of the process */
static void empty_pool(void) {
    ftc_lock(&pool_lock);
    struct pooled *p = pool;
    pool = NULL;
    pooled_count = 0;
    ftc_unlock(&pool_lock);
    while (p) {
        struct pooled *next = p->next;
        inner_fmi2FreeInstance(p->c);
        free(p);
        p = next;
    }
}
#endif

/* ---- Direct calls ------------------------------------------------------------------------------

   pythonfmu spends about 1.5 us of every FMI call on its own machinery before the model's code
   runs (a list of value references built per call, the method looked up by name, three strings
   built to scan the log queue), whatever the model does; a communication step of the closed loop
   makes 11 such calls. For the project's own slaves (those made with fmu_src.fmu_support's
   fmu_model) the shim makes the four calls of every step itself, on the same Python objects:

   * fmi2SetReal of inputs writes the floats into the slave's __dict__ (what the slave's own
     set_real does) and marks the outputs stale if some output depends on an input;
   * fmi2GetReal of inputs and outputs reads them from __dict__, after the slave's
     refresh_outputs() if an output is asked for and they are stale (what get_real does);
   * fmi2DoStep calls the slave's do_step through a wrapper that turns its result into a code.

   Everything else, and any call that the direct path does not cover (parameters, unknown value
   references, a Python exception), goes to pythonfmu as before, so its messages and statuses are
   unchanged: a do_step that raises is replayed through pythonfmu's fmi2DoStep, which raises the
   same exception object again (fmu_support keeps it), and a refresh that raises is retried by
   pythonfmu's fmi2GetReal. Messages the slave queued during a direct call are passed to the host
   by an empty pythonfmu fmi2GetReal, which forwards the queue as after any call. The shim keeps
   the last successful time and the terminate wish that pythonfmu's fmi2DoStep would record.

   The binding: pythonfmu constructs the slave inside fmi2Instantiate (and again in fmi2Reset) in
   the calling thread; fmu_model's __init__ leaves a weak reference to it under the thread's id in
   sys._ftc_fmu_slaves, and sys._ftc_fmu_claim(model, instance name) hands the shim the binding of
   that slave (checked to be of this model and instance name) or None. FTC_FMU_DIRECT=0 turns the
   direct path off (everything forwarded), for comparison. */

#define DIRECT_PROTOCOL 1
enum { KIND_NONE = 0, KIND_INPUT = 1, KIND_OUTPUT = 2 };
enum { STEP_OK = 0, STEP_DISCARD = 1, STEP_RAISED = 2 };

typedef struct _object PyObject; /* opaque: only pointers cross this file */

/* The Python C-API functions the direct path uses, looked up in the process's libpython. */
static struct {
    int ready;
    int (*gil_ensure)(void);
    void (*gil_release)(int);
    PyObject *(*import)(const char *);
    PyObject *(*getattr)(PyObject *, const char *);
    PyObject *(*call)(PyObject *, PyObject *);         /* PyObject_CallObject */
    PyObject *(*call2)(PyObject *, ...);               /* PyObject_CallFunctionObjArgs */
    PyObject *(*from_string)(const char *);
    PyObject *(*from_double)(double);
    double (*as_double)(PyObject *);
    long (*as_long)(PyObject *);
    PyObject *(*tuple_item)(PyObject *, long);
    long (*tuple_size)(PyObject *);
    char *(*bytes_string)(PyObject *);
    long (*bytes_size)(PyObject *);
    PyObject *(*dict_get)(PyObject *, PyObject *);
    int (*dict_set)(PyObject *, PyObject *, PyObject *);
    long (*list_size)(PyObject *);
    int (*is_true)(PyObject *);
    PyObject *(*error)(void);
    void (*clear_error)(void);
    void (*decref)(PyObject *);
    PyObject *true_object;
    int (*is_initialized)(void);
} py;

static void resolve_python_api(void *python) {
    py.ready = 1;
#define FIND(field, symbol) py.ready &= (*(void **)(&py.field) = ftc_library_symbol(python, symbol)) != NULL
    FIND(gil_ensure, "PyGILState_Ensure");
    FIND(gil_release, "PyGILState_Release");
    FIND(import, "PyImport_ImportModule");
    FIND(getattr, "PyObject_GetAttrString");
    FIND(call, "PyObject_CallObject");
    FIND(call2, "PyObject_CallFunctionObjArgs");
    FIND(from_string, "PyUnicode_FromString");
    FIND(from_double, "PyFloat_FromDouble");
    FIND(as_double, "PyFloat_AsDouble");
    FIND(as_long, "PyLong_AsLong");
    FIND(tuple_item, "PyTuple_GetItem");
    FIND(tuple_size, "PyTuple_Size");
    FIND(bytes_string, "PyBytes_AsString");
    FIND(bytes_size, "PyBytes_Size");
    FIND(dict_get, "PyDict_GetItem");
    FIND(dict_set, "PyDict_SetItem");
    FIND(list_size, "PyList_Size");
    FIND(is_true, "PyObject_IsTrue");
    FIND(error, "PyErr_Occurred");
    FIND(clear_error, "PyErr_Clear");
    FIND(decref, "Py_DecRef");
    FIND(true_object, "_Py_TrueStruct"); /* the object Py_True itself */
    FIND(is_initialized, "Py_IsInitialized");
#undef FIND
}

/* A slave's binding: the tuple it handed over (one strong reference, released at fmi2FreeInstance
   and before fmi2Reset) and the items of that tuple, borrowed. */
struct direct {
    PyObject *dict;      /* the slave's __dict__: its variables by name */
    PyObject *do_step;   /* function (t, h) -> STEP_* */
    PyObject *refresh;   /* function: refresh_outputs(), then _fmu_stale = False */
    PyObject *log_queue; /* the list pythonfmu forwards to the host's logger */
    PyObject *stale;     /* the key "_fmu_stale" */
    PyObject *names;     /* tuple: value reference -> variable name (None if not direct) */
    const unsigned char *kinds; /* value reference -> KIND_* (bytes owned by `binding`) */
    size_t n;            /* number of value references covered */
    int feedthrough;     /* some output depends directly on an input */
    PyObject *binding;   /* the tuple the slave handed over, owning the objects above */
};

static void release_binding(struct instance *i) {
    if (!i->direct) return;
    int gil = py.gil_ensure();
    py.decref(i->direct->binding);
    py.gil_release(gil);
    free(i->direct);
    i->direct = NULL;
}

/* Asks the slave just constructed in this thread (under the name pythonfmu keeps) for its binding,
   and gives it the instance's name; leaves i->direct NULL (every call forwarded) for slaves that
   do not offer one, such as plain pythonfmu slaves, and when FTC_FMU_DIRECT is "0". */
static void bind_direct(struct instance *i) {
    if (!py.ready) return;
    int gil = py.gil_ensure();
    PyObject *sys = py.import("sys"), *claim = NULL, *binding = NULL, *model_name = NULL, *name = NULL;
    if (sys) claim = py.getattr(sys, "_ftc_fmu_claim");
    if (claim) model_name = py.from_string(model);
    if (model_name) name = py.from_string(i->pooled->name);
    if (name) binding = py.call2(claim, model_name, name, NULL);
    if (binding && py.tuple_size(binding) == 9 && py.as_long(py.tuple_item(binding, 0)) == DIRECT_PROTOCOL) {
        PyObject *key = py.from_string("instance_name"), *renamed = py.from_string(i->name);
        i->pooled->renamable = key && renamed && py.dict_set(py.tuple_item(binding, 1), key, renamed) == 0;
        if (key) py.decref(key);
        if (renamed) py.decref(renamed);
    }
    if (!i->direct_allowed && binding) {
        py.decref(binding);
        binding = NULL;
    }
    struct direct *d = NULL;
    if (binding && py.tuple_size(binding) == 9 && py.as_long(py.tuple_item(binding, 0)) == DIRECT_PROTOCOL) {
        d = calloc(1, sizeof *d);
        PyObject *kinds = py.tuple_item(binding, 6);
        if (d) {
            d->dict = py.tuple_item(binding, 1);
            d->do_step = py.tuple_item(binding, 2);
            d->refresh = py.tuple_item(binding, 3);
            d->log_queue = py.tuple_item(binding, 4);
            d->names = py.tuple_item(binding, 5);
            d->kinds = (const unsigned char *)py.bytes_string(kinds);
            d->n = (size_t)py.bytes_size(kinds);
            d->feedthrough = py.is_true(py.tuple_item(binding, 7)) == 1;
            d->stale = py.tuple_item(binding, 8);
            d->binding = binding;
            binding = NULL; /* owned by d */
        }
        if (!d || !d->kinds || py.error()) {
            if (d && d->binding) py.decref(d->binding);
            free(d);
            d = NULL;
        }
    }
    if (py.error()) py.clear_error();
    PyObject *owned[] = {binding, name, model_name, claim, sys};
    for (size_t k = 0; k < sizeof owned / sizeof owned[0]; k++)
        if (owned[k]) py.decref(owned[k]);
    py.gil_release(gil);
    i->direct = d;
}

/* Passes the messages the slave queued during a direct call to the host (pythonfmu forwards its
   log queue after every call it makes; an empty fmi2GetReal is such a call). */
static void flush_log(struct instance *i, int gil) {
    long queued = py.list_size(i->direct->log_queue);
    py.gil_release(gil);
    if (queued > 0) inner_fmi2GetReal(i->inner, NULL, 0, NULL);
}

/* Whether every value reference is of the kinds in `allowed` (a bit mask of 1 << KIND_*). */
static int covered(const struct direct *d, const fmi2ValueReference vr[], size_t n, int allowed, int *outputs) {
    *outputs = 0;
    for (size_t k = 0; k < n; k++) {
        if (vr[k] >= d->n || !(allowed & (1 << d->kinds[vr[k]]))) return 0;
        *outputs |= d->kinds[vr[k]] == KIND_OUTPUT;
    }
    return 1;
}

static fmi2Status get_real(struct instance *i, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    int outputs;
    if (!i->direct || !covered(i->direct, vr, n, 1 << KIND_INPUT | 1 << KIND_OUTPUT, &outputs))
        return inner_fmi2GetReal(i->inner, vr, n, v);
    struct direct *d = i->direct;
    int gil = py.gil_ensure();
    if (outputs) {
        PyObject *stale = py.dict_get(d->dict, d->stale);
        if (!stale || py.is_true(stale)) {
            PyObject *result = py.call(d->refresh, NULL);
            if (!result) { /* pythonfmu calls refresh_outputs again and reports the exception */
                py.clear_error();
                py.gil_release(gil);
                return inner_fmi2GetReal(i->inner, vr, n, v);
            }
            py.decref(result);
        }
    }
    for (size_t k = 0; k < n; k++) {
        PyObject *value = py.dict_get(d->dict, py.tuple_item(d->names, (long)vr[k]));
        v[k] = value ? py.as_double(value) : -1.0;
        if (!value || (v[k] == -1.0 && py.error())) { /* not a number: pythonfmu reports it */
            py.clear_error();
            py.gil_release(gil);
            return inner_fmi2GetReal(i->inner, vr, n, v);
        }
    }
    flush_log(i, gil);
    return fmi2OK;
}

static fmi2Status set_real(struct instance *i, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
    int outputs;
    if (!i->direct || !covered(i->direct, vr, n, 1 << KIND_INPUT, &outputs))
        return inner_fmi2SetReal(i->inner, vr, n, v);
    struct direct *d = i->direct;
    int gil = py.gil_ensure();
    int failed = 0;
    for (size_t k = 0; k < n && !failed; k++) {
        PyObject *value = py.from_double(v[k]);
        failed = !value || py.dict_set(d->dict, py.tuple_item(d->names, (long)vr[k]), value) != 0;
        if (value) py.decref(value);
    }
    if (!failed && d->feedthrough) failed = py.dict_set(d->dict, d->stale, py.true_object) != 0;
    if (failed) { /* out of memory: pythonfmu sets them again and reports */
        py.clear_error();
        py.gil_release(gil);
        return inner_fmi2SetReal(i->inner, vr, n, v);
    }
    flush_log(i, gil);
    return fmi2OK;
}

static fmi2Status do_step(struct instance *i, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior) {
    if (!i->direct) return inner_fmi2DoStep(i->inner, t, h, noSetPrior);
    int gil = py.gil_ensure();
    PyObject *time = py.from_double(t), *step = py.from_double(h), *result = NULL;
    if (time && step) result = py.call2(i->direct->do_step, time, step, NULL);
    long code = result ? py.as_long(result) : STEP_RAISED;
    PyObject *owned[] = {result, step, time};
    for (size_t k = 0; k < sizeof owned / sizeof owned[0]; k++)
        if (owned[k]) py.decref(owned[k]);
    if (py.error()) py.clear_error();
    if (code == STEP_RAISED) { /* pythonfmu's fmi2DoStep raises the kept exception and reports it */
        py.gil_release(gil);
        return inner_fmi2DoStep(i->inner, t, h, noSetPrior);
    }
    flush_log(i, gil);
    if (code == STEP_OK) {
        i->last_successful_time = t + h;
        return fmi2OK;
    }
    i->last_successful_time = t; /* as pythonfmu's fmi2DoStep after a step that returned False */
    i->wants_to_terminate = 1;
    return fmi2Discard;
}

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

/* pythonfmu's component for a new instance: one from the pool, reset, or a new one. */
static struct pooled *component_for(struct instance *i, fmi2Type type, fmi2String guid, const char *resources,
                                    fmi2Boolean visible, fmi2Boolean loggingOn) {
    struct pooled *p = take(i->name, resources, visible);
    if (p) {
        p->owner = i;
        if (inner_fmi2Reset(p->c) < fmi2Error) {
            inner_fmi2SetDebugLogging(p->c, loggingOn, 0, NULL);
            return p;
        }
        p->owner = NULL; /* pythonfmu could not construct the slave again: abandoned, as after fmi2Fatal */
    }
    p = calloc(1, sizeof *p);
    if (!p) return NULL;
    p->owner = i;
    p->callbacks.logger = relay;
    p->callbacks.allocateMemory = calloc;
    p->callbacks.freeMemory = free;
    p->callbacks.componentEnvironment = p;
    snprintf(p->name, sizeof p->name, "%s", i->name);
    snprintf(p->resources, sizeof p->resources, "%s", resources);
    p->visible = visible;
    p->c = inner_fmi2Instantiate(i->name, type, guid, resources, &p->callbacks, visible, loggingOn);
    if (!p->c) {
        free(p);
        return NULL;
    }
    return p;
}

/* fmi2Instantiate, and fmi3InstantiateCoSimulation for the FMI 3.0 layer (`function` names the
   host's call in messages). */
fmi2Component ftc_instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn, const char *function) {
    ftc_lock(&load_lock);
    if (loaded == 0) loaded = load() == 0 ? 1 : -1;
    ftc_unlock(&load_lock);
    if (loaded < 0) {
        report(functions, instanceName, fmi2Error, failure);
        return NULL;
    }
    char message[3 * TEXT], resources[TEXT], note[2 * TEXT];
    const char *problem = NULL;
    if (!instanceName) problem = "instanceName is NULL";
    else if (fmuType != fmi2CoSimulation) problem = "this FMU is a Co-Simulation FMU only";
    else if (!fmuGUID) problem = "the GUID (instantiation token) is NULL";
    else if (strcmp(fmuGUID, description.token) != 0) {
        snprintf(note, sizeof note, "the GUID (instantiation token) %s is not this FMU's %s (modelDescription.xml)",
                 fmuGUID, description.token);
        problem = note;
    }
    int found = problem ? 0 : ftc_resources(&description, fmuResourceLocation, resources, sizeof resources, note,
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
    CHECK(check_capability(i, function, description.can_get_and_set_state, "canGetAndSet" FMU_STATE "=\"false\""))
#define CAN_SERIALIZE                                                                                        \
    CHECK(check_capability(i, function, description.can_get_and_set_state && description.can_serialize_state,  \
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
    CHECK(check_capability(i, function, description.directional_derivatives,                                 \
                           "providesDirectionalDerivative=\"false\""));                                     \
    CHECK(check_array(i, function, nUnknown, unknown, dvUnknown, "unknowns"));                               \
    CHECK(check_array(i, function, nKnown, known, dvKnown, "knowns"))
#define ARGS_fmi2SetRealInputDerivatives                                                                     \
    CHECK(check_capability(i, function, description.interpolate_inputs, "canInterpolateInputs=\"false\""));  \
    CHECK(check_array(i, function, n, vr, order && value ? value : NULL, "input derivatives"))
#define ARGS_fmi2GetRealOutputDerivatives                                                                    \
    CHECK(check_capability(i, function, description.output_derivative_order > 0,                             \
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

#ifndef _WIN32
/* Releases pythonfmu's binary when the shim is unloaded and at exit, whichever comes first.

   pythonfmu 0.7.0 releases its global std::shared_ptr<PyState> twice when its binary is still
   loaded at exit: the C++ static destructor (an exit handler) frees the PyState, then its ELF
   destructor finalizePythonInterpreter() assigns nullptr to the destroyed pointer and frees it
   again: heap corruption, "free(): corrupted unsorted chunks" (NTNU-IHB/PythonFMU#228, #229; seen
   here in fmpy and C hosts alike). dlclose cannot unload that binary (its STB_GNU_UNIQUE symbols
   make it NODELETE), so the shim calls finalizePythonInterpreter() itself while the pointer is
   alive: the PyState is freed once, and the later destructors see nullptr. The exit handler is
   registered after pythonfmu's static destructors (at load), so it runs before them. Python itself
   stays: an interpreter cannot be unloaded. The pool is emptied first while Python is there (a
   Python host has finalized its interpreter before the exit handlers run: then the components
   are left to the end of the process). */
static void unload(void) {
    if (!inner) return;
    if (py.ready && py.is_initialized()) empty_pool();
    void (*finalize)(void) = (void (*)(void))ftc_library_symbol(inner, "finalizePythonInterpreter");
    if (finalize) finalize();
    ftc_library_close(inner);
    inner = NULL;
}

__attribute__((destructor)) static void unload_with_shim(void) { unload(); }
#endif
