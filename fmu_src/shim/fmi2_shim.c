/* FMI 2.0 Co-Simulation shim in front of pythonfmu's binary: the FMU runs in any FMI host, with or
   without Python on the machine.

   pythonfmu 0.7.0's binaries/linux64/<model>.so does not link libpython: a host without Python
   in its process cannot dlopen it (undefined symbol: _Py_NoneStruct). The build installs this
   shim as binaries/linux64/<model>.so, keeps pythonfmu's binary beside it as
   <model>_pythonfmu.so, and bundles a CPython runtime in binaries/linux64/python/ (libpython,
   the two libraries it links, a zipped subset of the standard library; fmu_src/runtime.py).
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

   Needs a C compiler, libc and the pinned runtime's headers (for start_python.c only): the
   Python C-API functions are looked up with dlsym, so the shim links no libpython. */

#define _GNU_SOURCE
#include <dlfcn.h>
#include <fcntl.h>
#include <pthread.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include "fmi2_types.h"
#include "start_python.h"

#ifndef EXPORT /* the FMI 3.0 build defines it empty: its FMI 2.0 functions are internal */
#define EXPORT __attribute__((visibility("default")))
#endif
#define RUNTIME_DIR "python"
#define INNER_SUFFIX "_pythonfmu.so"
#define TEXT 4096

/* pythonfmu's functions, resolved once by load() before the first instance exists. */
#define DECLARE_POINTER(name, params, args) static fmi2Status(*inner_##name) params;
FMI2_FORWARDED(DECLARE_POINTER)
static fmi2Component (*inner_fmi2Instantiate)(fmi2String, fmi2Type, fmi2String, fmi2String,
                                              const fmi2CallbackFunctions *, fmi2Boolean, fmi2Boolean);
static void (*inner_fmi2FreeInstance)(fmi2Component);

/* What the shim hands the host as fmi2Component: pythonfmu's component and the direct path. */
struct direct;
struct instance {
    fmi2Component inner;        /* pythonfmu's component */
    struct direct *direct;      /* NULL: every call forwarded (see "Direct calls") */
    int direct_allowed;         /* FTC_FMU_DIRECT is not "0" */
    char name[256];             /* instance name */
    fmi2Real last_successful_time; /* what pythonfmu's fmi2DoStep would record */
    fmi2Boolean wants_to_terminate;
};

/* call_<name>(c, ...): the pythonfmu function on the instance's own component. */
#define INNER_CALL(name, params, args)                                                                       \
    static fmi2Status call_##name params {                                                                   \
        c = ((struct instance *)c)->inner;                                                                   \
        return inner_##name args;                                                                            \
    }
FMI2_PLAIN(INNER_CALL)

static void unload(void);
static void resolve_python_api(void *python);

static pthread_mutex_t load_lock = PTHREAD_MUTEX_INITIALIZER;
static int loaded;            /* 0: not tried, 1: pythonfmu's binary is ready, -1: failed */
static void *inner;           /* handle of <model>_pythonfmu.so */
static char model[256];       /* model identifier: the shim's file name without .so */
static char failure[TEXT];    /* the one message of a failed load() */
static char python_info[TEXT]; /* "Python X.Y.Z bundled with the FMU" or "of the host process" */

/* dlerror() without a leading "<path>: " (the message names the path already). */
static const char *dl_reason(const char *path) {
    const char *error = dlerror();
    size_t n = strlen(path);
    if (!error) return "unknown error";
    if (strncmp(error, path, n) == 0 && strncmp(error + n, ": ", 2) == 0) return error + n + 2;
    return error;
}

/* Loads a library of the runtime by soname, globally: one already in the process is reused, else
   the search reaches the shim's DT_RUNPATH ($ORIGIN/python/lib, holding libpython only) and then
   the system's folders; `fallback` (a path), if given, is loaded where that finds nothing. */
static void *load_runtime_library(const char *soname, const char *fallback) {
    void *handle = dlopen(soname, RTLD_NOW | RTLD_GLOBAL);
    if (!handle && fallback) handle = dlopen(fallback, RTLD_NOW | RTLD_GLOBAL);
    if (!handle) {
        const char *name = fallback ? fallback : soname;
        snprintf(failure, TEXT, "%s: cannot load the bundled %s: %s", model, soname, dl_reason(name));
    }
    return handle;
}

/* Whether `library` is an FMU's bundled libpython (<home>/lib/<libpython> beside <home>/python311.zip);
   if so, writes <home>. */
static int bundled_home(const char *library, char home[TEXT]) {
    const char *suffix = "/lib/" FTC_LIBPYTHON;
    size_t n = strlen(library), m = strlen(suffix);
    if (n <= m || n - m >= TEXT || strcmp(library + n - m, suffix) != 0) return 0;
    snprintf(home, TEXT, "%.*s", (int)(n - m), library);
    char zip[TEXT + 32];
    snprintf(zip, sizeof zip, "%s/python" FTC_TAG ".zip", home);
    struct stat info;
    return stat(zip, &info) == 0 && S_ISREG(info.st_mode);
}

/* Makes Python available if needed, then opens pythonfmu's binary. Called once, under load_lock. */
static int load(void) {
    Dl_info self;
    if (!dladdr((void *)&load, &self) || !self.dli_fname) {
        snprintf(failure, TEXT, "fmi2 shim: cannot find its own file (dladdr failed)");
        return -1;
    }
    char dir[TEXT];
    snprintf(dir, sizeof dir, "%s", self.dli_fname);
    char *slash = strrchr(dir, '/');
    const char *base = slash ? slash + 1 : dir;
    snprintf(model, sizeof model, "%s", base);
    char *dot = strrchr(model, '.');
    if (dot && strcmp(dot, ".so") == 0) *dot = '\0';
    if (slash) *slash = '\0';
    else snprintf(dir, sizeof dir, ".");

    void *python = RTLD_DEFAULT;
    int own; /* Python is an FMU's bundled runtime (this one's or another's), not the host's */
    if (!dlsym(RTLD_DEFAULT, "Py_IsInitialized")) {
        char zlib[TEXT + 64], expat[TEXT + 64];
        snprintf(zlib, sizeof zlib, "%s/%s/fallback/libz.so.1", dir, RUNTIME_DIR);
        snprintf(expat, sizeof expat, "%s/%s/fallback/libexpat.so.1", dir, RUNTIME_DIR);
        if (!load_runtime_library("libz.so.1", zlib) || !load_runtime_library("libexpat.so.1", expat) ||
            !(python = load_runtime_library(FTC_LIBPYTHON, NULL)))
            return -1;
    }
    int (*is_initialized)(void) = (int (*)(void))dlsym(python, "Py_IsInitialized");
    if (!is_initialized) {
        snprintf(failure, TEXT, "%s: %s has no Py_IsInitialized: not a libpython", model, FTC_LIBPYTHON);
        return -1;
    }
    /* The shims of two FMUs may start at once in different threads: the second may find the
       libpython the first loaded before the first started it. So whether Python is an FMU's own
       runtime is decided by the file that defines it (<home>/lib/libpython... beside
       <home>/python311.zip), whoever loaded it, and a lock on that file makes the first start it
       completely before the other looks. */
    Dl_info defining;
    const char *library = FTC_LIBPYTHON;
    if (dladdr((void *)is_initialized, &defining) && defining.dli_fname && defining.dli_fname[0])
        library = defining.dli_fname;
    char home[TEXT];
    own = bundled_home(library, home);
    int lock = open(library, O_RDONLY | O_CLOEXEC);
    if (lock >= 0) flock(lock, LOCK_EX);
    int status = 0;
    if (!is_initialized()) {
        if (own) {
            char reason[TEXT];
            status = ftc_start_python(python, home, reason, sizeof reason);
            if (status != 0)
                snprintf(failure, TEXT, "%s: cannot start the bundled Python in %s: %s", model, home, reason);
        } else { /* the host loaded a libpython of its own without starting it: start that one */
            void (*initialize)(int) = (void (*)(int))dlsym(python, "Py_InitializeEx");
            void *(*save_thread)(void) = (void *(*)(void))dlsym(python, "PyEval_SaveThread");
            if (initialize && save_thread) {
                initialize(0); /* 0: keep the host's signal handlers */
                save_thread();
            }
            status = is_initialized() ? 0 : -1;
            if (status != 0) snprintf(failure, TEXT, "%s: cannot initialize the host's Python (%s)", model, library);
        }
    }
    if (lock >= 0) close(lock); /* releases the lock */
    if (status != 0) return -1;

    char path[TEXT + 300];
    snprintf(path, sizeof path, "%s/%s%s", dir, model, INNER_SUFFIX);
    inner = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!inner) {
        snprintf(failure, TEXT, "%s: cannot load pythonfmu's binary %s: %s", model, path, dl_reason(path));
        return -1;
    }
    inner_fmi2Instantiate = (fmi2Component(*)(fmi2String, fmi2Type, fmi2String, fmi2String,
                                               const fmi2CallbackFunctions *, fmi2Boolean, fmi2Boolean))
        dlsym(inner, "fmi2Instantiate");
    inner_fmi2FreeInstance = (void (*)(fmi2Component))dlsym(inner, "fmi2FreeInstance");
    if (!inner_fmi2Instantiate || !inner_fmi2FreeInstance) {
        snprintf(failure, TEXT, "%s: %s lacks fmi2Instantiate or fmi2FreeInstance", model, path);
        return -1;
    }
#define RESOLVE(name, params, args) *(void **)(&inner_##name) = dlsym(inner, #name);
    FMI2_FORWARDED(RESOLVE)
    atexit(unload); /* after pythonfmu's static destructors were registered: runs before them */
    resolve_python_api(python);
    const char *(*get_version)(void) = (const char *(*)(void))dlsym(python, "Py_GetVersion");
    snprintf(python_info, TEXT, "Python %.*s %s", get_version ? (int)strcspn(get_version(), " ") : 1,
             get_version ? get_version() : "?", own ? "bundled with the FMU" : "of the host process");
    return 0;
}

/* One message to the host's logger (if any) and to stderr; '%' escaped for the printf-style logger. */
static void report(const fmi2CallbackFunctions *functions, fmi2String instanceName, fmi2Status status,
                   const char *message) {
    fprintf(stderr, "%s\n", message);
    if (!functions || !functions->logger) return;
    char escaped[2 * TEXT];
    size_t j = 0;
    for (const char *p = message; *p && j + 2 < sizeof escaped; p++) {
        if (*p == '%') escaped[j++] = '%';
        escaped[j++] = *p;
    }
    escaped[j] = '\0';
    functions->logger(functions->componentEnvironment, instanceName ? instanceName : model, status,
                      status == fmi2Warning ? "logStatusWarning" : "logStatusError", escaped);
}

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
} py;

static void resolve_python_api(void *python) {
    py.ready = 1;
#define FIND(field, symbol) py.ready &= (*(void **)(&py.field) = dlsym(python, symbol)) != NULL
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

/* Asks the slave just constructed in this thread for its binding; leaves i->direct NULL (every
   call forwarded) for slaves that do not offer one, such as plain pythonfmu slaves. */
static void bind_direct(struct instance *i) {
    if (!i->direct_allowed || !py.ready) return;
    int gil = py.gil_ensure();
    PyObject *sys = py.import("sys"), *claim = NULL, *binding = NULL, *model_name = NULL, *name = NULL;
    if (sys) claim = py.getattr(sys, "_ftc_fmu_claim");
    if (claim) model_name = py.from_string(model);
    if (model_name) name = py.from_string(i->name);
    if (name) binding = py.call2(claim, model_name, name, NULL);
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

EXPORT fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    struct instance *i = c;
    int outputs;
    if (!i || !inner_fmi2GetReal) return fmi2Error;
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

EXPORT fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
    struct instance *i = c;
    int outputs;
    if (!i || !inner_fmi2SetReal) return fmi2Error;
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

EXPORT fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior) {
    struct instance *i = c;
    if (!i || !inner_fmi2DoStep) return fmi2Error;
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

EXPORT fmi2Status fmi2Reset(fmi2Component c) {
    struct instance *i = c;
    if (!i || !inner_fmi2Reset) return fmi2Error;
    release_binding(i);
    fmi2Status status = inner_fmi2Reset(i->inner); /* pythonfmu constructs a new slave */
    i->last_successful_time = 0.0;
    i->wants_to_terminate = 0;
    if (status < fmi2Error) bind_direct(i);
    return status;
}

/* Once the direct path has made a step, pythonfmu's record of the last step is not current. */
EXPORT fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    struct instance *i = c;
    if (!i || !inner_fmi2GetRealStatus) return fmi2Error;
    if (i->direct && s == fmi2LastSuccessfulTime && value) {
        *value = i->last_successful_time;
        return fmi2OK;
    }
    return inner_fmi2GetRealStatus(i->inner, s, value);
}

EXPORT fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    struct instance *i = c;
    if (!i || !inner_fmi2GetBooleanStatus) return fmi2Error;
    if (i->direct && s == fmi2Terminated && value) {
        *value = i->wants_to_terminate;
        return fmi2OK;
    }
    return inner_fmi2GetBooleanStatus(i->inner, s, value);
}

EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }

EXPORT const char *fmi2GetVersion(void) { return "2.0"; }

EXPORT fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                                     fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                                     fmi2Boolean visible, fmi2Boolean loggingOn) {
    pthread_mutex_lock(&load_lock);
    if (loaded == 0) loaded = load() == 0 ? 1 : -1;
    pthread_mutex_unlock(&load_lock);
    if (loaded < 0) {
        report(functions, instanceName, fmi2Error, failure);
        return NULL;
    }
    fmi2Component c = inner_fmi2Instantiate(instanceName, fmuType, fmuGUID, fmuResourceLocation, functions,
                                            visible, loggingOn);
    if (!c) {
        char message[2 * TEXT];
        snprintf(message, sizeof message, "%s: pythonfmu could not instantiate %s in %s; instantiate with "
                 "logging on for its reason", model, instanceName ? instanceName : "the model", python_info);
        report(functions, instanceName, fmi2Error, message);
    }
    if (!c) return NULL;
    struct instance *i = calloc(1, sizeof *i);
    if (!i) {
        inner_fmi2FreeInstance(c);
        report(functions, instanceName, fmi2Error, "fmi2 shim: out of memory");
        return NULL;
    }
    i->inner = c;
    snprintf(i->name, sizeof i->name, "%s", instanceName ? instanceName : "");
    const char *setting = getenv("FTC_FMU_DIRECT");
    i->direct_allowed = !(setting && strcmp(setting, "0") == 0);
    bind_direct(i);
    return i;
}

EXPORT void fmi2FreeInstance(fmi2Component c) {
    struct instance *i = c;
    if (!i) return;
    release_binding(i);
    if (inner_fmi2FreeInstance) inner_fmi2FreeInstance(i->inner);
    free(i);
}

/* The FMI2_PLAIN functions: pythonfmu's, called with its own component. */
#define FORWARD(name, params, args)                                                                          \
    EXPORT fmi2Status name params {                                                                          \
        if (!inner_##name || !c) return fmi2Error;                                                           \
        return call_##name args;                                                                             \
    }
FMI2_PLAIN(FORWARD)

/* Releases pythonfmu's binary when the shim is unloaded and at exit, whichever comes first.

   pythonfmu 0.7.0 releases its global std::shared_ptr<PyState> twice when its binary is still
   loaded at exit: the C++ static destructor (an exit handler) frees the PyState, then its ELF
   destructor finalizePythonInterpreter() assigns nullptr to the destroyed pointer and frees it
   again: heap corruption, "free(): corrupted unsorted chunks" (NTNU-IHB/PythonFMU#228, #229; seen
   here in fmpy and C hosts alike). dlclose cannot unload that binary (its STB_GNU_UNIQUE symbols
   make it NODELETE), so the shim calls finalizePythonInterpreter() itself while the pointer is
   alive: the PyState is freed once, and the later destructors see nullptr. The exit handler is
   registered after pythonfmu's static destructors (at load), so it runs before them. Python itself
   stays: an interpreter cannot be unloaded. */
static void unload(void) {
    if (!inner) return;
    void (*finalize)(void) = (void (*)(void))dlsym(inner, "finalizePythonInterpreter");
    if (finalize) finalize();
    dlclose(inner);
    inner = NULL;
}

__attribute__((destructor)) static void unload_with_shim(void) { unload(); }
