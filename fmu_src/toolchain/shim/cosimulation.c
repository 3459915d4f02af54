/* SPDX-License-Identifier: BSD-2-Clause */
/* The behaviour (shim.h): the calls of every communication step made on the slave's Python
   objects (the direct path), else forwarded to pythonfmu. */

#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "shim.h"

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
   * fmi2DoStep calls the slave's own do_step (bound), marks the outputs stale and turns its
     result into fmi2OK or fmi2Discard; an exception it raised is kept in __dict__.

   Everything else, and any call that the direct path does not cover (parameters, unknown value
   references, a Python exception), goes to pythonfmu as before, so its messages and statuses are
   unchanged: a do_step that raises is replayed through pythonfmu's fmi2DoStep, which raises the
   same exception object again (the shim keeps it where fmu_support's do_step finds it, with its
   traceback), and a refresh that raises is retried by
   pythonfmu's fmi2GetReal. Messages the slave queued during a direct call are passed to the host
   by an empty pythonfmu fmi2GetReal, which forwards the queue as after any call. The shim keeps
   the last successful time and the terminate wish that pythonfmu's fmi2DoStep would record.

   Where the model's extension offers them (its class's compiled_calls), the step and the refresh
   are first called as C functions (controller/direct_calls.h: a capsule of function pointers and
   the binding they take), with no Python call between: no argument tuple, no float objects for the
   time and step, no functools.partial. Their "not here" (0) leaves the call to the Python callables
   as above.

   The binding: pythonfmu constructs the slave inside fmi2Instantiate (and again in fmi2Reset) in
   the calling thread; fmu_model's __init__ leaves a weak reference to it under the thread's id in
   sys._ftc_fmu_slaves, and sys._ftc_fmu_claim(model, instance name) hands the shim the binding of
   that slave (checked to be of this model and instance name) or None. FTC_FMU_DIRECT=0 turns the
   direct path off (everything forwarded), for comparison. */

#define DIRECT_PROTOCOL 3
#define BINDING_ITEMS 12
enum { KIND_NONE = 0, KIND_INPUT = 1, KIND_OUTPUT = 2 };

typedef struct _object PyObject; /* opaque: only pointers cross this file */

/* controller/direct_calls.h's layout (that header needs Python.h, which the shim is built without). */
#define FTC_DIRECT_CALLS "ftc_direct_calls"
#define FTC_DIRECT_CALLS_VERSION 1
struct ftc_direct_calls {
    int version;
    int (*step)(PyObject *binding, double t, double h);
    int (*refresh)(PyObject *binding);
};

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
    PyObject *(*dict_get)(PyObject *, PyObject *); /* PyDict_GetItemWithError: no error saved and restored */
    int (*dict_set)(PyObject *, PyObject *, PyObject *);
    long (*list_size)(PyObject *);
    int (*is_true)(PyObject *);
    PyObject *(*error)(void);
    void (*clear_error)(void);
    void (*fetch_error)(PyObject **, PyObject **, PyObject **);
    void (*normalize_error)(PyObject **, PyObject **, PyObject **);
    int (*set_traceback)(PyObject *, PyObject *);
    void (*decref)(PyObject *);
    PyObject *true_object;
    PyObject *false_object;
    int (*is_initialized)(void);
    void *(*capsule_pointer)(PyObject *, const char *);
} py;

void resolve_python_api(void *python) {
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
    FIND(dict_get, "PyDict_GetItemWithError");
    FIND(dict_set, "PyDict_SetItem");
    FIND(list_size, "PyList_Size");
    FIND(is_true, "PyObject_IsTrue");
    FIND(error, "PyErr_Occurred");
    FIND(clear_error, "PyErr_Clear");
    FIND(fetch_error, "PyErr_Fetch");
    FIND(normalize_error, "PyErr_NormalizeException");
    FIND(set_traceback, "PyException_SetTraceback");
    FIND(decref, "Py_DecRef");
    FIND(true_object, "_Py_TrueStruct"); /* the object Py_True itself */
    FIND(false_object, "_Py_FalseStruct");
    FIND(is_initialized, "Py_IsInitialized");
    FIND(capsule_pointer, "PyCapsule_GetPointer");
#undef FIND
}

/* A slave's binding: the tuple it handed over (one strong reference, released at fmi2FreeInstance
   and before fmi2Reset) and the items of that tuple, borrowed. */
struct direct {
    PyObject *dict;      /* the slave's __dict__: its variables by name */
    PyObject *do_step;   /* the slave's own do_step(t, h), bound: true to go on, false to discard */
    PyObject *refresh;   /* the slave's refresh_outputs(), bound */
    PyObject *log_queue; /* the list pythonfmu forwards to the host's logger */
    PyObject *stale;     /* the key "_fmu_stale" */
    PyObject *raised;    /* the key "_fmu_raised": an exception do_step raised, for pythonfmu */
    PyObject **names;    /* value reference -> variable name (None if not direct), the binding's */
    unsigned char *kinds; /* value reference -> KIND_*: where the slave's and the table's agree */
    size_t n;            /* number of value references covered */
    int feedthrough;     /* some output depends directly on an input */
    const struct ftc_direct_calls *calls; /* the model's C entries, or NULL */
    PyObject *model;     /* the binding they take */
    PyObject *binding;   /* the tuple the slave handed over, owning the objects above */
};

static void free_direct(struct direct *d) {
    if (!d) return;
    if (d->binding) py.decref(d->binding);
    free(d->kinds);
    free(d->names);
    free(d);
}

void release_binding(struct instance *i) {
    if (!i->direct) return;
    int gil = py.gil_ensure();
    free_direct(i->direct);
    py.gil_release(gil);
    i->direct = NULL;
}

static int is_binding(PyObject *binding) {
    return binding && py.tuple_size(binding) == BINDING_ITEMS &&
           py.as_long(py.tuple_item(binding, 0)) == DIRECT_PROTOCOL;
}

/* The kind of variable `vr` (the FMI 2.0 value reference) in the build's table (description.h): a
   Real input or output, else KIND_NONE. */
static unsigned char table_kind(unsigned vr) {
    const struct ftc_variable *v = ftc_variable(&ftc_description, vr + FTC_VR_OFFSET);
    if (!v || v->type != 'r') return KIND_NONE;
    return v->causality == 'i' ? KIND_INPUT : v->causality == 'o' ? KIND_OUTPUT : KIND_NONE;
}

/* The C entries in `capsule` (controller/direct_calls.h), or NULL (no error left) where it is not
   such a capsule (None: the model has none) or of another version. */
static const struct ftc_direct_calls *entries(PyObject *capsule) {
    const struct ftc_direct_calls *calls = capsule ? py.capsule_pointer(capsule, FTC_DIRECT_CALLS) : NULL;
    if (!calls) py.clear_error();
    return calls && calls->version == FTC_DIRECT_CALLS_VERSION ? calls : NULL;
}

/* The direct path on `binding` (taken over), or NULL (then released): the slave's kinds kept
   only where the build's table agrees, so that the direct path serves no variable the guard
   does not know as that Real input or output. */
static struct direct *direct_of(PyObject *binding) {
    struct direct *d = calloc(1, sizeof *d);
    if (!d) {
        py.decref(binding);
        return NULL;
    }
    d->binding = binding;
    PyObject *kinds = py.tuple_item(binding, 6);
    const unsigned char *offered = (const unsigned char *)py.bytes_string(kinds);
    d->n = offered ? (size_t)py.bytes_size(kinds) : 0;
    d->kinds = offered ? malloc(d->n + 1) : NULL;
    d->names = offered ? calloc(d->n + 1, sizeof *d->names) : NULL;
    if (!d->kinds || !d->names || py.error()) {
        free_direct(d);
        return NULL;
    }
    PyObject *names = py.tuple_item(binding, 5);
    for (size_t vr = 0; vr < d->n; vr++) {
        d->names[vr] = names ? py.tuple_item(names, (long)vr) : NULL;
        d->kinds[vr] = d->names[vr] && offered[vr] == table_kind((unsigned)vr) ? offered[vr] : KIND_NONE;
    }
    d->dict = py.tuple_item(binding, 1);
    d->do_step = py.tuple_item(binding, 2);
    d->refresh = py.tuple_item(binding, 3);
    d->log_queue = py.tuple_item(binding, 4);
    d->feedthrough = py.is_true(py.tuple_item(binding, 7)) == 1;
    d->stale = py.tuple_item(binding, 8);
    d->raised = py.tuple_item(binding, 9);
    d->calls = entries(py.tuple_item(binding, 10));
    d->model = py.tuple_item(binding, 11);
    if (py.error()) {
        free_direct(d);
        return NULL;
    }
    return d;
}

/* The binding the slave just constructed in this thread (under the name pythonfmu keeps) offers
   (a new reference), or NULL; gives the slave the instance's name. */
static PyObject *claim_binding(struct instance *i) {
    PyObject *sys = py.import("sys"), *claim = NULL, *binding = NULL, *model_name = NULL, *name = NULL;
    if (sys) claim = py.getattr(sys, "_ftc_fmu_claim");
    if (claim) model_name = py.from_string(model);
    if (model_name) name = py.from_string(i->pooled->name);
    if (name) binding = py.call2(claim, model_name, name, NULL);
    if (is_binding(binding)) {
        PyObject *key = py.from_string("instance_name"), *renamed = py.from_string(i->name);
        i->pooled->renamable = key && renamed && py.dict_set(py.tuple_item(binding, 1), key, renamed) == 0;
        if (key) py.decref(key);
        if (renamed) py.decref(renamed);
    }
    PyObject *owned[] = {name, model_name, claim, sys};
    for (size_t k = 0; k < sizeof owned / sizeof owned[0]; k++)
        if (owned[k]) py.decref(owned[k]);
    return binding;
}

/* Asks the slave just constructed for its binding and gives it the instance's name; leaves
   i->direct NULL (every call forwarded) for slaves that do not offer one, such as plain pythonfmu
   slaves, and when FTC_FMU_DIRECT is "0". */
void bind_direct(struct instance *i) {
    if (!py.ready) return;
    int gil = py.gil_ensure();
    PyObject *binding = claim_binding(i);
    struct direct *d = NULL;
    if (i->direct_allowed && is_binding(binding)) d = direct_of(binding);
    else if (binding) py.decref(binding);
    if (py.error()) py.clear_error();
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

fmi2Status get_real(struct instance *i, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    int outputs;
    if (!i->direct || !covered(i->direct, vr, n, 1 << KIND_INPUT | 1 << KIND_OUTPUT, &outputs))
        return inner_fmi2GetReal(i->inner, vr, n, v);
    struct direct *d = i->direct;
    int gil = py.gil_ensure();
    if (outputs) {
        PyObject *stale = py.dict_get(d->dict, d->stale);
        if (!stale && py.error()) py.clear_error();
        if (!stale || py.is_true(stale)) {
            int done = d->calls ? d->calls->refresh(d->model) : 0; /* 0: not here, the callable's */
            PyObject *result = done == 0 ? py.call(d->refresh, NULL) : NULL;
            if (result) py.decref(result);
            if (done < 0 || (done == 0 && !result) || py.dict_set(d->dict, d->stale, py.false_object) != 0) {
                /* pythonfmu calls refresh_outputs again and reports the exception */
                py.clear_error();
                py.gil_release(gil);
                return inner_fmi2GetReal(i->inner, vr, n, v);
            }
        }
    }
    for (size_t k = 0; k < n; k++) {
        PyObject *value = py.dict_get(d->dict, d->names[vr[k]]);
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

fmi2Status set_real(struct instance *i, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
    int outputs;
    if (!i->direct || !covered(i->direct, vr, n, 1 << KIND_INPUT, &outputs))
        return inner_fmi2SetReal(i->inner, vr, n, v);
    struct direct *d = i->direct;
    int gil = py.gil_ensure();
    int failed = 0;
    for (size_t k = 0; k < n && !failed; k++) {
        PyObject *value = py.from_double(v[k]);
        failed = !value || py.dict_set(d->dict, d->names[vr[k]], value) != 0;
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

/* Keeps the exception being raised (its traceback attached) in the slave's __dict__, where
   fmu_support's do_step raises it again when pythonfmu's fmi2DoStep calls it; the error is
   cleared. Where it cannot be kept (no memory), pythonfmu steps the slave again itself. */
static void keep_raised(struct direct *d) {
    PyObject *type = NULL, *value = NULL, *traceback = NULL;
    py.fetch_error(&type, &value, &traceback);
    py.normalize_error(&type, &value, &traceback);
    if (value && (!traceback || py.set_traceback(value, traceback) == 0))
        py.dict_set(d->dict, d->raised, value);
    PyObject *owned[] = {type, value, traceback};
    for (size_t k = 0; k < sizeof owned / sizeof owned[0]; k++)
        if (owned[k]) py.decref(owned[k]);
    if (py.error()) py.clear_error();
}

fmi2Status do_step(struct instance *i, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior) {
    if (!i->direct) return inner_fmi2DoStep(i->inner, t, h, noSetPrior);
    struct direct *d = i->direct;
    int gil = py.gil_ensure();
    int go_on = d->calls ? d->calls->step(d->model, t, h) : 0; /* 1 stepped, 0 not here, -1 raised */
    if (go_on == 0) {
        PyObject *time = py.from_double(t), *step = py.from_double(h), *result = NULL;
        if (time && step) result = py.call2(d->do_step, time, step, NULL);
        go_on = result ? py.is_true(result) : -1; /* false: fmi2Discard */
        PyObject *owned[] = {result, step, time};
        for (size_t k = 0; k < sizeof owned / sizeof owned[0]; k++)
            if (owned[k]) py.decref(owned[k]);
    }
    if (go_on < 0) keep_raised(d);
    /* the time or the state moved: the outputs are recomputed at their next read */
    if (py.dict_set(d->dict, d->stale, py.true_object) != 0) py.clear_error();
    if (go_on < 0) { /* pythonfmu's fmi2DoStep raises the kept exception and reports it */
        py.gil_release(gil);
        return inner_fmi2DoStep(i->inner, t, h, noSetPrior);
    }
    flush_log(i, gil);
    if (go_on) {
        i->last_successful_time = t + h;
        return fmi2OK;
    }
    i->last_successful_time = t; /* as pythonfmu's fmi2DoStep after a step that returned False */
    i->wants_to_terminate = 1;
    return fmi2Discard;
}

int python_alive(void) { return py.ready && py.is_initialized(); }
