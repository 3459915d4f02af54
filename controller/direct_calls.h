/* SPDX-License-Identifier: BSD-2-Clause */
/* The C entry points a model's extension module offers the FMU shim (fmu_src/toolchain/shim/
   cosimulation.c): a slave's step and output refresh called as C functions, with no Python call
   between (no argument tuple, no float objects for t and h, no functools.partial), on the binding
   tuple the module's step_slave / refresh_slave take as their first argument.

   Each module exposes one capsule per model, named FTC_DIRECT_CALLS, holding a pointer to a static
   struct ftc_direct_calls; the model's compiled_calls hook (fmu_src) hands the shim that capsule with
   the slave's binding. The shim checks the name and the version and otherwise calls the Python
   callables as before.

   Both functions are called with the GIL held and return 1 when done on the usual path, 0 when they
   changed nothing and set no error (the caller then calls the Python step_slave / refresh_slave, which
   run the Python method and give its result and messages), -1 with an exception set (after a write:
   out of memory). The shim declares the same layout; bump FTC_DIRECT_CALLS_VERSION in both when it
   changes. */
#ifndef FTC_DIRECT_CALLS_H
#define FTC_DIRECT_CALLS_H

#define FTC_DIRECT_CALLS "ftc_direct_calls"
#define FTC_DIRECT_CALLS_VERSION 1

struct ftc_direct_calls {
    int version; /* FTC_DIRECT_CALLS_VERSION */
    int (*step)(PyObject *binding, double t, double h);
    int (*refresh)(PyObject *binding);
};

/* An entry's answer `done`, with the error its "not here" (0) may have left cleared. */
static inline int ftc_answer(int done) {
    if (done == 0) PyErr_Clear();
    return done;
}

/* The capsule for `calls` added to `module` under `name`; -1 on an error. */
static inline int ftc_add_direct_calls(PyObject *module, const char *name, const struct ftc_direct_calls *calls) {
    PyObject *capsule = PyCapsule_New((void *)calls, FTC_DIRECT_CALLS, NULL);
    if (capsule == NULL) return -1;
    int failed = PyModule_AddObject(module, name, capsule);
    if (failed) Py_DECREF(capsule);
    return failed;
}

#endif
