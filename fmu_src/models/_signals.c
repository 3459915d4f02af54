/* SPDX-License-Identifier: BSD-2-Clause */
/* _signals: the Reference and Actuator FMUs' step and output refresh, compiled.

   Owns: no state. Everything a call reads or writes is in the slave's __dict__ (state snapshots
   deep-copy it), reached through a binding tuple that fmu_src/models/signals_native.py builds
   once per slave; the shim calls these through functools.partial(function, binding) in place of
   the slave's do_step and refresh_outputs (fmu_support's compiled_calls hook).

   Why: the two models are a few lines of arithmetic, but each spent about 12 000 instructions
   per communication step in the interpreter; here a step and a refresh run with no interpreter
   frame.

   The same values as the Python code, to the bit: every expression is evaluated operation for
   operation in the order Python evaluates it (left to right, no reassociation; built with
   -ffp-contract=off, so no fused multiply-add), sin, cos and exp are controller/fmath.h's (what
   controller.fmath computes), and min/max follow Python's builtins (the first argument unless the
   second is strictly smaller/larger, which decides for nan).

   May not: change the dict on any path but the usual one. Where a value is not an exact float,
   the parameters are not frozen yet (_params is None), reading raised, or fmath would raise (an
   infinite sin/cos argument, an exp that overflows), the call leaves the dict as it was, clears
   any error of its own and returns what the Python method returns (or raises), so that every
   message and exception stays the Python code's.

   Bindings (tuples; keys interned str):
     step:      (dict, do_step, refresh_outputs, "time", ...)
     reference: (dict, do_step, refresh_outputs, "time", "_params", "_param_values",
                 "yd", "yd_dot", "yd_ddot", "yd_dddot", "yd_ddddot")
     actuator:  (dict, do_step, refresh_outputs, "time", "_params", "_param_values",
                 "v", "x1", "x2", "uf", "u_dz", fault time tolerance (float))
   "_param_values" holds (params, p1, ..., pn): the frozen parameters object itself (the values
   are used only while it is still the dict's "_params") and its fields as floats, in the order of
   the dataclass (Reference: amplitude, omega, phase, offset; Actuator: m_r, m_l, b_r, b_l, K_inf,
   K_amp, K_rate, L_gain, L_bias, t_fault, u_max).
   Built against the stable ABI (Py_LIMITED_API), as the other extension modules. */

#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>

/* fmath.h brings pow too, which these models do not use */
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-function"
#include "fmath.h"
#pragma GCC diagnostic pop

#include "direct_calls.h"

enum { B_DICT, B_STEP, B_REFRESH, B_TIME, B_PARAMS, B_VALUES, B_FIRST };
enum { REFERENCE_PARAMS = 4, REFERENCE_OUTPUTS = 5 };
enum { ACTUATOR_PARAMS = 11, ACTUATOR_INPUTS = 3, ACTUATOR_OUTPUTS = 2 };
enum { M_R, M_L, B_R, B_L, K_INF, K_AMP, K_RATE, L_GAIN, L_BIAS, T_FAULT, U_MAX };
#define REFERENCE_SIZE (B_FIRST + REFERENCE_OUTPUTS)
#define ACTUATOR_SIZE (B_FIRST + ACTUATOR_INPUTS + ACTUATOR_OUTPUTS + 1)

/* Whether binding is a tuple of at least `size` items (signals_native's bindings). */
static int is_binding(PyObject *binding, Py_ssize_t size) {
    return PyTuple_Check(binding) && PyTuple_Size(binding) >= size;
}

/* The binding passed as the call's first argument, checked to have at least `size` items. */
static PyObject *binding_of(PyObject *args, Py_ssize_t nargs, Py_ssize_t size) {
    if (!PyTuple_Check(args) || PyTuple_Size(args) != nargs) {
        PyErr_SetString(PyExc_TypeError, "_signals: wrong number of arguments");
        return NULL;
    }
    PyObject *binding = PyTuple_GetItem(args, 0);
    if (!binding || !is_binding(binding, size)) {
        PyErr_SetString(PyExc_TypeError, "_signals: not a binding of fmu_src/models/signals_native.py");
        return NULL;
    }
    return binding;
}

/* dict[key] as a double, or 0 (no error set: the caller falls back) where it is missing or not an
   exact float. */
static int exact_float(PyObject *dict, PyObject *key, double *value) {
    PyObject *item = PyDict_GetItemWithError(dict, key);
    if (!item || !PyFloat_CheckExact(item)) return 0;
    *value = PyFloat_AsDouble(item);
    return 1;
}

/* The frozen parameters' values into p[0..n-1]; 0 where they are not frozen (or not as floats). */
static int frozen_params(PyObject *binding, PyObject *dict, double *p, Py_ssize_t n) {
    PyObject *params = PyDict_GetItemWithError(dict, PyTuple_GetItem(binding, B_PARAMS));
    PyObject *values = PyDict_GetItemWithError(dict, PyTuple_GetItem(binding, B_VALUES));
    if (!params || params == Py_None || !values || !PyTuple_Check(values) || PyTuple_Size(values) != n + 1
        || PyTuple_GetItem(values, 0) != params)
        return 0;
    for (Py_ssize_t k = 0; k < n; k++) {
        PyObject *item = PyTuple_GetItem(values, k + 1);
        if (!item || !PyFloat_CheckExact(item)) return 0;
        p[k] = PyFloat_AsDouble(item);
    }
    return 1;
}

/* The Python method at binding[which], called with args[1:], after clearing any error of ours. */
static PyObject *fallback(PyObject *binding, PyObject *args, Py_ssize_t which) {
    if (PyErr_Occurred()) PyErr_Clear();
    PyObject *rest = PyTuple_GetSlice(args, 1, PyTuple_Size(args));
    if (!rest) return NULL;
    PyObject *result = PyObject_Call(PyTuple_GetItem(binding, which), rest, NULL);
    Py_DECREF(rest);
    return result;
}

/* dict[keys[k]] = values[k] for every k, in order; -1 on an error (out of memory). */
static int store(PyObject *dict, PyObject *binding, Py_ssize_t first, const double *values, Py_ssize_t n) {
    for (Py_ssize_t k = 0; k < n; k++) {
        PyObject *value = PyFloat_FromDouble(values[k]);
        if (!value) return -1;
        int failed = PyDict_SetItem(dict, PyTuple_GetItem(binding, first + k), value);
        Py_DECREF(value);
        if (failed) return -1;
    }
    return 0;
}

/* Python's max(a, b) and min(a, b) of two floats: a unless b is strictly larger/smaller. */
static inline double py_max(double a, double b) { return b > a ? b : a; }
static inline double py_min(double a, double b) { return b < a ? b : a; }

/* do_step's `time = current_time + step_size` on binding: 1 done, -1 an error (out of memory). */
static int step_here(PyObject *binding, double t, double h) {
    PyObject *time = PyFloat_FromDouble(t + h);
    if (!time) return -1;
    int failed = PyDict_SetItem(PyTuple_GetItem(binding, B_DICT), PyTuple_GetItem(binding, B_TIME), time);
    Py_DECREF(time);
    return failed ? -1 : 1;
}

/* step_slave(binding, t, h): do_step's `time = current_time + step_size`, True. */
static PyObject *step_slave(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *binding = binding_of(args, 3, B_TIME + 1);
    if (!binding) return NULL;
    PyObject *t = PyTuple_GetItem(args, 1), *h = PyTuple_GetItem(args, 2);
    if (!PyFloat_CheckExact(t) || !PyFloat_CheckExact(h)) return fallback(binding, args, B_STEP);
    if (step_here(binding, PyFloat_AsDouble(t), PyFloat_AsDouble(h)) < 0) return NULL;
    Py_RETURN_TRUE;
}

/* refresh_outputs of fmu_src/reference.py, i.e. models/reference.py:reference_derivatives(time,
   _params) into yd .. yd_ddddot: 1 done, 0 the Python method's path (nothing written), -1 error. */
static int reference_here(PyObject *binding) {
    PyObject *dict = PyTuple_GetItem(binding, B_DICT);
    double p[REFERENCE_PARAMS], t;
    if (!exact_float(dict, PyTuple_GetItem(binding, B_TIME), &t) || !frozen_params(binding, dict, p, REFERENCE_PARAMS))
        return 0;
    const double amplitude = p[0], omega = p[1], phase = p[2], offset = p[3];
    /* angle = p.omega * t + p.phase; s, c = sin(angle), cos(angle) (ValueError for an infinite angle) */
    const double angle = omega * t + phase;
    if (isinf(angle)) return 0;
    const double s = ftc_sin(angle), c = ftc_cos(angle);
    const double a = amplitude, w = omega;
    /* (a * s + p.offset, a * w * c, -a * w * w * s, -a * w * w * w * c, a * w * w * w * w * s) */
    const double out[REFERENCE_OUTPUTS] = {
        a * s + offset,
        a * w * c,
        -a * w * w * s,
        -a * w * w * w * c,
        a * w * w * w * w * s,
    };
    return store(dict, binding, B_FIRST, out, REFERENCE_OUTPUTS) != 0 ? -1 : 1;
}

/* refresh_outputs of fmu_src/actuator.py, i.e. the fault time snapped to t_fault within the
   tolerance, then models/actuator.py:actuator_output(t, v, x1, x2, _params) into uf and u_dz: as
   reference_here. */
static int actuator_here(PyObject *binding) {
    PyObject *dict = PyTuple_GetItem(binding, B_DICT);
    PyObject *tolerance = PyTuple_GetItem(binding, B_FIRST + ACTUATOR_INPUTS + ACTUATOR_OUTPUTS);
    double p[ACTUATOR_PARAMS], t, in[ACTUATOR_INPUTS];
    int usual = PyFloat_CheckExact(tolerance) && exact_float(dict, PyTuple_GetItem(binding, B_TIME), &t)
                && frozen_params(binding, dict, p, ACTUATOR_PARAMS);
    for (Py_ssize_t k = 0; usual && k < ACTUATOR_INPUTS; k++)
        usual = exact_float(dict, PyTuple_GetItem(binding, B_FIRST + k), &in[k]);
    if (!usual) return 0;
    const double v_in = in[0], x1 = in[1], x2 = in[2];
    /* if isfinite(p.t_fault) and abs(t - p.t_fault) <= FAULT_TIME_TOLERANCE * max(1.0, abs(p.t_fault)):
       t = p.t_fault */
    double near = PyFloat_AsDouble(tolerance) * py_max(1.0, fabs(p[T_FAULT]));
    if (isfinite(p[T_FAULT]) && fabs(t - p[T_FAULT]) <= near) t = p[T_FAULT];
    /* saturate: max(-u_max, min(u_max, v)) */
    const double v = py_max(-p[U_MAX], py_min(p[U_MAX], v_in));
    /* dead_zone */
    double u;
    if (v >= p[B_R])
        u = p[M_R] * (v - p[B_R]);
    else if (v <= -p[B_L])
        u = p[M_L] * (v + p[B_L]);
    else
        u = 0.0;
    double out[ACTUATOR_OUTPUTS] = {v, u};
    if (!(t < p[T_FAULT])) {
        /* K = p.K_inf + p.K_amp * exp(-p.K_rate * t) (OverflowError where exp overflows) */
        const double x = -p[K_RATE] * t;
        const double e = ftc_exp(x);
        if (e == INFINITY && x != INFINITY) return 0;
        const double K = p[K_INF] + p[K_AMP] * e;
        /* cos_x1 = cos(x1) (ValueError for an infinite x1); L = p.L_gain * x2 * cos_x1 * cos_x1 + p.L_bias */
        if (isinf(x1)) return 0;
        const double cos_x1 = ftc_cos(x1);
        const double L = p[L_GAIN] * x2 * cos_x1 * cos_x1 + p[L_BIAS];
        out[0] = K * u + L;
    }
    return store(dict, binding, B_FIRST + ACTUATOR_INPUTS, out, ACTUATOR_OUTPUTS) != 0 ? -1 : 1;
}

/* A refresh on the usual path (`here`, 1 done, 0 the Python method's path, -1 error), else the
   Python method. */
static PyObject *refresh(PyObject *args, Py_ssize_t size, int (*here)(PyObject *)) {
    PyObject *binding = binding_of(args, 1, size);
    if (!binding) return NULL;
    int done = here(binding);
    if (done < 0) return NULL;
    if (done) Py_RETURN_NONE;
    return fallback(binding, args, B_REFRESH);
}

static PyObject *reference_refresh(PyObject *self, PyObject *args) {
    (void)self;
    return refresh(args, REFERENCE_SIZE, reference_here);
}

static PyObject *actuator_refresh(PyObject *self, PyObject *args) {
    (void)self;
    return refresh(args, ACTUATOR_SIZE, actuator_here);
}

/* The shim's C entries (direct_calls.h): 0 (no error set) where the binding is not of this model or
   the usual path does not apply, which the shim then leaves to step_slave and the refresh. */
static int step_entry(PyObject *binding, double t, double h) {
    return is_binding(binding, B_TIME + 1) ? step_here(binding, t, h) : 0;
}

static int reference_entry(PyObject *binding) {
    return ftc_answer(is_binding(binding, REFERENCE_SIZE) ? reference_here(binding) : 0);
}

static int actuator_entry(PyObject *binding) {
    return ftc_answer(is_binding(binding, ACTUATOR_SIZE) ? actuator_here(binding) : 0);
}

static const struct ftc_direct_calls reference_calls = {FTC_DIRECT_CALLS_VERSION, step_entry, reference_entry};
static const struct ftc_direct_calls actuator_calls = {FTC_DIRECT_CALLS_VERSION, step_entry, actuator_entry};

static PyMethodDef methods[] = {
    {"step_slave", step_slave, METH_VARARGS,
     "step_slave(binding, t, h): the slave's time = t + h, True (its do_step where t, h are floats)."},
    {"reference_refresh", reference_refresh, METH_VARARGS,
     "reference_refresh(binding): the Reference FMU's refresh_outputs."},
    {"actuator_refresh", actuator_refresh, METH_VARARGS,
     "actuator_refresh(binding): the Actuator FMU's refresh_outputs."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_signals", "The Reference and Actuator FMUs' step and refresh, compiled.", -1, methods,
    NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__signals(void) {
    PyObject *m = PyModule_Create(&module);
    if (m != NULL && (ftc_add_direct_calls(m, "reference_direct_calls", &reference_calls) != 0 ||
                      ftc_add_direct_calls(m, "actuator_direct_calls", &actuator_calls) != 0))
        Py_CLEAR(m);
    return m;
}
