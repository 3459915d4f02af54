/* SPDX-License-Identifier: BSD-2-Clause */
/* _dopri: the plants' Dormand-Prince 5(4) step over one communication step, compiled.

   The same algorithm as fmu_src/models/plants.py:dopri_hold_step, operation for operation, so
   that it gives the same bits: the plant's right-hand side and the step-size control are written
   in the order Python evaluates them (left to right, no reassociation: built without
   -ffast-math and with -ffp-contract=off, so no fused multiply-add), sin, cos and pow are
   controller/fmath.h's, which controller/fmath.py repeats in Python (same bits on every platform,
   unlike the C library's), sqrt is IEEE's correctly rounded one (ftc_sqrt), and min/max follow
   Python's builtins (the first argument unless the second is strictly smaller/larger), which
   matters for nan. fmath.sin and fmath.cos raise ValueError on an infinite argument where
   C returns nan: such an evaluation marks the trial step as failed (err = inf), as the Python
   code's `except ValueError` does, and at the step's first evaluation it is reported as a math
   domain error.

   Why compiled: a plant FMU spends its step in this loop, about 3.9 us per integrator step in
   Python (0.36 us here). Runs whose state escapes (the finite-time law's finite escapes in a campaign over
   initial states) need hundreds to thousands of integrator steps per communication step while
   the state is still inside its range of validity; compiled, such a run costs milliseconds.

   hold_step(kind, c1, c2, c3, c4, c5, c6, t, y1, y2, y3, uf, h, rtol, atol, first_step, limit,
             max_steps, y_limit, rate_horizon)
   kind 0: Example 1 (eq. 85; c1..c6 unused); kind 1: the pendulum (eq. 99) with c1 = d1,
   c2 = d2, c3 = M L, c4 = g / L + B / M, as plants.pendulum_rhs_for binds them (c5, c6 unused);
   kind 2: the manipulator (models/manipulator.py) with c1 = M, c2 = N, c3 = B, c4 = L, c5 = R,
   c6 = K_B, as manipulator.manipulator_rhs_for binds them.
   Returns (status, t, a, b, c, next_step, accepted, rejected, k1, k2, k3), k the rate at a RATE
   status (zeros otherwise); plants.native_hold_step turns
   a status other than OK into the Python code's exception and message.

   step_slave(binding, t, h) and refresh_slave(binding): a plant FMU's do_step and
   refresh_outputs, which the FMU's shim calls (fmu_src/plant_core.py:compiled_plant_calls binds
   them, fmu_support._direct_binding hands them over). Why: around the 2 500 instructions of this
   integrator, a communication step spent about 24 000 in the interpreter (plant_core.step_plant,
   native_hold_step, their argument tuples); here the usual path (Dormand-Prince, status OK, the
   new state within its limits) reads and writes the slave's __dict__ entries that step_plant and
   refresh_plant_outputs read and write, with the same values, and enters no Python frame. Every
   other path (RK4, a rejected step, a value of another type, a missing entry, initialization)
   leaves the __dict__ untouched and calls the Python method, whose result, exception and
   messages are then the FMU's. Nothing is kept here: the state stays in the __dict__, which state
   snapshots copy.

   Built against the stable ABI (Py_LIMITED_API 3.8: METH_VARARGS, no METH_FASTCALL) so that one
   binary loads in any CPython 3.8 or later: the FMU's own runtime, or the host's Python when the
   host runs one. */

#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>

#include "direct_calls.h"
#include "fmath.h"

enum { OK = 0, RATE = 1, BEYOND = 2, BUDGET = 3, NO_STEP = 4, DOMAIN = 5 };
enum { EXAMPLE1 = 0, PENDULUM = 1, MANIPULATOR = 2 };

static const double C2 = 1.0 / 5, C3 = 3.0 / 10, C4 = 4.0 / 5, C5 = 8.0 / 9;
static const double A21 = 1.0 / 5;
static const double A31 = 3.0 / 40, A32 = 9.0 / 40;
static const double A41 = 44.0 / 45, A42 = -56.0 / 15, A43 = 32.0 / 9;
static const double A51 = 19372.0 / 6561, A52 = -25360.0 / 2187, A53 = 64448.0 / 6561, A54 = -212.0 / 729;
static const double A61 = 9017.0 / 3168, A62 = -355.0 / 33, A63 = 46732.0 / 5247, A64 = 49.0 / 176,
                    A65 = -5103.0 / 18656;
static const double B1 = 35.0 / 384, B3 = 500.0 / 1113, B4 = 125.0 / 192, B5 = -2187.0 / 6784, B6 = 11.0 / 84;
static const double E1 = 71.0 / 57600, E3 = -71.0 / 16695, E4 = 71.0 / 1920, E5 = -17253.0 / 339200,
                    E6 = 22.0 / 525, E7 = -1.0 / 40;
static const double SAFETY = 0.9, FAC_MIN = 0.2, FAC_MAX = 10.0;

struct plant {
    int kind;
    double c1, c2, c3, c4, c5, c6;
    double uf;
    int domain; /* a sin/cos argument was infinite (Python: ValueError) */
};

static double sin_(struct plant *p, double x) {
    if (isinf(x)) p->domain = 1;
    return ftc_sin(x);
}

static double cos_(struct plant *p, double x) {
    if (isinf(x)) p->domain = 1;
    return ftc_cos(x);
}

/* plants.example1_rhs, plants.pendulum_rhs_for and manipulator.manipulator_rhs_for, term by term. */
static void rhs(struct plant *p, double t, double x1, double x2, double z, double *k) {
    double uf = p->uf;
    if (p->kind == EXAMPLE1) {
        k[0] = (2.0 + sin_(p, x1)) * x2 + 0.1 * sin_(p, x1 * x2) + z * sin_(p, x1 * x1);
        k[1] = (2.0 + cos_(p, x1 * x2)) * uf + 0.5 * sin_(p, x1 * x1 * x2 * x2) + x1 * x1 * z;
        k[2] = -z - x1 * x1 + 0.5;
    } else if (p->kind == PENDULUM) {
        k[0] = x2 + z * x1 + p->c1 * sin_(p, t);
        k[1] = uf / p->c3 - p->c4 * sin_(p, x1 * x2) + z * x2 * sin_(p, x1) + p->c2 * cos_(p, t);
        k[2] = -2.0 * z + 0.25 * x1 * x1;
    } else { /* z is the motor current x3 */
        k[0] = x2;
        k[1] = (z - p->c3 * x2 - p->c2 * sin_(p, x1)) / p->c1;
        k[2] = (uf - p->c5 * z - p->c6 * x2) / p->c4;
    }
}

static double py_max(double a, double b) { return b > a ? b : a; }
static double py_min(double a, double b) { return b < a ? b : a; }

/* Whether the rate bound ends the step (plants.carried_beyond): the state moved on at rate k for
   reach seconds beyond its bound. */
static int too_fast(double y1, double y2, double y3, const double *k, double reach, double x1_limit,
                    double limit) {
    return reach > 0.0 && (fabs(y1 + k[0] * reach) > x1_limit || fabs(y2 + k[1] * reach) > limit ||
                           fabs(y3 + k[2] * reach) > limit);
}

/* Where a step ended: status, t, state a b c, next step, accepted and rejected steps, and the rate
   k for RATE (else zeros). */
struct outcome {
    int status;
    double t, a, b, c, next;
    long long accepted, rejected;
    double k[3];
};

static int end(struct outcome *o, int status, double t, double a, double b, double c, double next,
               long long accepted, long long rejected) {
    *o = (struct outcome){status, t, a, b, c, next, accepted, rejected, {0.0, 0.0, 0.0}};
    return status;
}

static int end_rate(struct outcome *o, double t, double a, double b, double c, const double *k) {
    end(o, RATE, t, a, b, c, 0.0, 0, 0);
    o->k[0] = k[0];
    o->k[1] = k[1];
    o->k[2] = k[2];
    return RATE;
}

/* One communication step from (t, y1, y2, y3) over h with p->uf held (plants.dopri_hold_step): its
   status, the outcome in *o. */
static int integrate(struct plant *p, double t, double y1, double y2, double y3, double h, double rtol,
                     double atol, double first_step, double limit, long long max_steps, double y_limit,
                     double rate_horizon, struct outcome *o) {
    double k1[3], k2[3], k3[3], k4[3], k5[3], k6[3], k7[3];
    double t_end = t + h;
    rhs(p, t, y1, y2, y3, k1);
    if (p->domain) return end(o, DOMAIN, t, 0.0, 0.0, 0.0, 0.0, 0, 0);
    double reach = rate_horizon * h;
    double x1_limit = py_min(limit, y_limit);
    if (too_fast(y1, y2, y3, k1, reach, x1_limit, limit)) return end_rate(o, t, y1, y2, y3, k1);
    double dt = first_step > 0.0 ? py_min(first_step, h) : h;
    long long accepted = 0, rejected = 0;
    double grow = FAC_MAX;
    for (;;) {
        double remaining = t_end - t;
        double wanted = dt;
        int last = dt >= remaining * (1.0 - 1e-12);
        if (last) dt = remaining;
        p->domain = 0;
        rhs(p, t + C2 * dt, y1 + dt * A21 * k1[0], y2 + dt * A21 * k1[1], y3 + dt * A21 * k1[2], k2);
        rhs(p, t + C3 * dt,
            y1 + dt * (A31 * k1[0] + A32 * k2[0]),
            y2 + dt * (A31 * k1[1] + A32 * k2[1]),
            y3 + dt * (A31 * k1[2] + A32 * k2[2]), k3);
        rhs(p, t + C4 * dt,
            y1 + dt * (A41 * k1[0] + A42 * k2[0] + A43 * k3[0]),
            y2 + dt * (A41 * k1[1] + A42 * k2[1] + A43 * k3[1]),
            y3 + dt * (A41 * k1[2] + A42 * k2[2] + A43 * k3[2]), k4);
        rhs(p, t + C5 * dt,
            y1 + dt * (A51 * k1[0] + A52 * k2[0] + A53 * k3[0] + A54 * k4[0]),
            y2 + dt * (A51 * k1[1] + A52 * k2[1] + A53 * k3[1] + A54 * k4[1]),
            y3 + dt * (A51 * k1[2] + A52 * k2[2] + A53 * k3[2] + A54 * k4[2]), k5);
        double t_new = last ? t_end : t + dt;
        rhs(p, t_new,
            y1 + dt * (A61 * k1[0] + A62 * k2[0] + A63 * k3[0] + A64 * k4[0] + A65 * k5[0]),
            y2 + dt * (A61 * k1[1] + A62 * k2[1] + A63 * k3[1] + A64 * k4[1] + A65 * k5[1]),
            y3 + dt * (A61 * k1[2] + A62 * k2[2] + A63 * k3[2] + A64 * k4[2] + A65 * k5[2]), k6);
        double n1 = y1 + dt * (B1 * k1[0] + B3 * k3[0] + B4 * k4[0] + B5 * k5[0] + B6 * k6[0]);
        double n2 = y2 + dt * (B1 * k1[1] + B3 * k3[1] + B4 * k4[1] + B5 * k5[1] + B6 * k6[1]);
        double n3 = y3 + dt * (B1 * k1[2] + B3 * k3[2] + B4 * k4[2] + B5 * k5[2] + B6 * k6[2]);
        rhs(p, t_new, n1, n2, n3, k7);
        double err = INFINITY;
        if (!p->domain) {
            double e1 = dt * (E1 * k1[0] + E3 * k3[0] + E4 * k4[0] + E5 * k5[0] + E6 * k6[0] + E7 * k7[0]);
            double e2 = dt * (E1 * k1[1] + E3 * k3[1] + E4 * k4[1] + E5 * k5[1] + E6 * k6[1] + E7 * k7[1]);
            double e3 = dt * (E1 * k1[2] + E3 * k3[2] + E4 * k4[2] + E5 * k5[2] + E6 * k6[2] + E7 * k7[2]);
            double s1 = e1 / (atol + rtol * py_max(fabs(y1), fabs(n1)));
            double s2 = e2 / (atol + rtol * py_max(fabs(y2), fabs(n2)));
            double s3 = e3 / (atol + rtol * py_max(fabs(y3), fabs(n3)));
            err = ftc_sqrt((s1 * s1 + s2 * s2 + s3 * s3) / 3.0);
        }
        if (err <= 1.0) { /* accepted (false for nan) */
            accepted += 1;
            if (fabs(n1) > y_limit || fabs(n1) > limit || fabs(n2) > limit || fabs(n3) > limit)
                return end(o, BEYOND, t_new, n1, n2, n3, 0.0, accepted, rejected);
            double fac = err > 0.0 ? py_min(grow, SAFETY * ftc_pow(err, -0.2)) : grow;
            double proposal = dt * py_max(FAC_MIN, fac);
            if (last) return end(o, OK, t_new, n1, n2, n3, py_max(proposal, wanted), accepted, rejected);
            if (accepted + rejected >= max_steps)
                return end(o, BUDGET, t_new, n1, n2, n3, 0.0, accepted, rejected);
            t = t_new;
            y1 = n1;
            y2 = n2;
            y3 = n3;
            k1[0] = k7[0]; /* first same as last */
            k1[1] = k7[1];
            k1[2] = k7[2];
            if (too_fast(y1, y2, y3, k1, reach, x1_limit, limit)) return end_rate(o, t, y1, y2, y3, k1);
            dt = proposal;
            grow = FAC_MAX;
        } else {
            rejected += 1;
            if (dt <= 1e-12 * h) return end(o, NO_STEP, t, y1, y2, y3, 0.0, accepted, rejected);
            if (accepted + rejected >= max_steps) return end(o, BUDGET, t, y1, y2, y3, 0.0, accepted, rejected);
            dt *= isfinite(err) ? py_max(FAC_MIN, SAFETY * ftc_pow(err, -0.2)) : FAC_MIN;
            grow = 1.0;
        }
    }
}

static int known_kind(int kind) { return kind == EXAMPLE1 || kind == PENDULUM || kind == MANIPULATOR; }

static PyObject *hold_step(PyObject *self, PyObject *args) {
    (void)self;
    struct plant p = {0};
    double t, y1, y2, y3, h, rtol, atol, first_step, limit, y_limit, rate_horizon;
    long long max_steps;
    if (!PyArg_ParseTuple(args, "iddddddddddddddddLdd", &p.kind, &p.c1, &p.c2, &p.c3, &p.c4, &p.c5, &p.c6, &t,
                          &y1, &y2, &y3, &p.uf, &h, &rtol, &atol, &first_step, &limit, &max_steps, &y_limit,
                          &rate_horizon))
        return NULL;
    if (!known_kind(p.kind)) {
        PyErr_SetString(PyExc_ValueError, "unknown plant kind");
        return NULL;
    }
    struct outcome o;
    integrate(&p, t, y1, y2, y3, h, rtol, atol, first_step, limit, max_steps, y_limit, rate_horizon, &o);
    return Py_BuildValue("(idddddLLddd)", o.status, o.t, o.a, o.b, o.c, o.next, o.accepted, o.rejected, o.k[0],
                         o.k[1], o.k[2]);
}

/* ---- A plant FMU's step and output refresh (the shim's direct calls, fmu_src/fmu_support.py) ----

   plant_core.compiled_plant_calls builds the binding, once per slave: the slave's __dict__, its
   Python do_step and refresh_outputs (bound), plants.DOPRI, the class NativePlant, then the keys
   (interned strings) of the entries read and written. Every state stays in the __dict__ (state
   snapshots deep-copy it): nothing is kept here. */

enum {
    B_DICT, B_STEP, B_REFRESH, B_DOPRI, B_NATIVE_TYPE, B_STATE, B_UF, B_RTOL, B_ATOL, B_NEXT_STEP,
    B_STATE_LIMIT, B_MAX_STEPS, B_Y_LIMIT, B_RATE_HORIZON, B_METHOD, B_NATIVE, B_STATES, B_Y, B_ITEMS
};

/* Whether binding is a tuple of compiled_plant_calls' size around a dict. */
static int is_binding(PyObject *binding) {
    return PyTuple_Check(binding) && PyTuple_Size(binding) == B_ITEMS && PyDict_Check(PyTuple_GetItem(binding, B_DICT));
}

static PyObject *binding_of(PyObject *args, int n, PyObject **t, PyObject **h) {
    PyObject *binding = NULL;
    if (!PyArg_UnpackTuple(args, n == 1 ? "refresh_slave" : "step_slave", n, n, &binding, t, h)) return NULL;
    if (!is_binding(binding)) {
        PyErr_SetString(PyExc_TypeError, "not a plant binding (plant_core.compiled_plant_calls)");
        return NULL;
    }
    return binding;
}

/* The __dict__ entry under the binding's key `key` (borrowed), NULL if missing (maybe with an error). */
static PyObject *entry(PyObject *binding, int key) {
    return PyDict_GetItemWithError(PyTuple_GetItem(binding, B_DICT), PyTuple_GetItem(binding, key));
}

/* A float or an int (exactly: no Python code runs, so the borrowed entries stay alive) converted
   as PyArg_ParseTuple's "d" converts it (PyFloat_AsDouble); 0 otherwise or on an error. */
static int as_double(PyObject *value, double *x) {
    if (!value || !(PyFloat_CheckExact(value) || PyLong_CheckExact(value))) return 0;
    *x = PyFloat_AsDouble(value);
    return !(*x == -1.0 && PyErr_Occurred());
}

static int entry_double(PyObject *binding, int key, double *x) { return as_double(entry(binding, key), x); }

/* An entry that is a float itself (compared as a Python object by step_plant: an int would compare
   exactly, not rounded to a double). */
static int entry_float(PyObject *binding, int key, double *x) {
    PyObject *value = entry(binding, key);
    return value && PyFloat_CheckExact(value) && as_double(value, x);
}

/* The exact tuple `value` with n items converted by "d" into x[]; 0 otherwise. */
static int doubles(PyObject *value, Py_ssize_t n, double *x) {
    if (!value || !PyTuple_CheckExact(value) || PyTuple_Size(value) != n) return 0;
    for (Py_ssize_t k = 0; k < n; k++)
        if (!as_double(PyTuple_GetItem(value, k), &x[k])) return 0;
    return 1;
}

/* The usual path of plant_core.step_plant (Dormand-Prince, the compiled integrator, status OK, the
   new state within its limits), reading and writing the same __dict__ entries with the same
   values: 1 done; 0 another path (the __dict__ untouched, maybe an error set); -1 an error after
   the first write. */
static int usual_step(PyObject *binding, double t, double h) {
    PyObject *method = entry(binding, B_METHOD);
    if (!method || !PyLong_CheckExact(method) ||
        PyObject_RichCompareBool(method, PyTuple_GetItem(binding, B_DOPRI), Py_EQ) != 1)
        return 0;
    struct plant p = {0};
    PyObject *native = entry(binding, B_NATIVE); /* a NativePlant (kind, constants, names) */
    if (!native || (PyObject *)Py_TYPE(native) != PyTuple_GetItem(binding, B_NATIVE_TYPE)) return 0;
    PyObject *kind = PyTuple_GetItem(native, 0);
    if (!kind || !PyLong_CheckExact(kind)) return 0;
    long kind_value = PyLong_AsLong(kind);
    if (kind_value == -1 && PyErr_Occurred()) return 0;
    if (kind_value != EXAMPLE1 && kind_value != PENDULUM && kind_value != MANIPULATOR) return 0; /* ValueError */
    p.kind = (int)kind_value;
    double c[6], y[3], rtol, atol, first_step, limit, y_limit, rate_horizon;
    if (!doubles(PyTuple_GetItem(native, 1), 6, c)) return 0;
    p.c1 = c[0], p.c2 = c[1], p.c3 = c[2], p.c4 = c[3], p.c5 = c[4], p.c6 = c[5];
    PyObject *max_steps_obj = entry(binding, B_MAX_STEPS);
    if (!max_steps_obj || !PyLong_CheckExact(max_steps_obj)) return 0;
    long long max_steps = PyLong_AsLongLong(max_steps_obj);
    if (max_steps == -1 && PyErr_Occurred()) return 0;
    if (!(doubles(entry(binding, B_STATE), 3, y) && entry_double(binding, B_UF, &p.uf) &&
          entry_double(binding, B_RTOL, &rtol) && entry_double(binding, B_ATOL, &atol) &&
          entry_double(binding, B_NEXT_STEP, &first_step) && entry_float(binding, B_STATE_LIMIT, &limit) &&
          entry_float(binding, B_Y_LIMIT, &y_limit) && entry_double(binding, B_RATE_HORIZON, &rate_horizon)))
        return 0;
    struct outcome o;
    if (integrate(&p, t, y[0], y[1], y[2], h, rtol, atol, first_step, limit, max_steps, y_limit, rate_horizon,
                  &o) != OK)
        return 0;
    /* step_plant's check of the new state (nan fails it) */
    if (!(fabs(o.a) <= py_min(limit, y_limit) && fabs(o.b) <= limit && fabs(o.c) <= limit)) return 0;
    PyObject *state = PyTuple_New(3), *next = PyFloat_FromDouble(o.next);
    const double values[3] = {o.a, o.b, o.c};
    for (Py_ssize_t k = 0; state && k < 3; k++) {
        PyObject *value = PyFloat_FromDouble(values[k]);
        if (!value || PyTuple_SetItem(state, k, value) != 0) Py_CLEAR(state);
    }
    if (!state || !next) {
        Py_XDECREF(state);
        Py_XDECREF(next);
        return 0;
    }
    PyObject *d = PyTuple_GetItem(binding, B_DICT);
    /* step_plant's order: _next_step as it unpacks the integrator's result, state at the end */
    int failed = PyDict_SetItem(d, PyTuple_GetItem(binding, B_NEXT_STEP), next) != 0 ||
                 PyDict_SetItem(d, PyTuple_GetItem(binding, B_STATE), state) != 0;
    Py_DECREF(state);
    Py_DECREF(next);
    return failed ? -1 : 1;
}

/* step_slave(binding, t, h): the slave's do_step(t, h), its usual path here and every other one
   (RK4, a rejected step, an error) by the Python do_step, which gives its result and messages. */
static PyObject *step_slave(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *t = NULL, *h = NULL, *binding = binding_of(args, 3, &t, &h);
    if (!binding) return NULL;
    double t_value, h_value;
    int done = as_double(t, &t_value) && as_double(h, &h_value) ? usual_step(binding, t_value, h_value) : 0;
    if (done > 0) Py_RETURN_TRUE;
    if (done < 0) return NULL;
    PyErr_Clear(); /* the Python code meets the same problem and reports it its own way */
    return PyObject_CallFunctionObjArgs(PyTuple_GetItem(binding, B_STEP), t, h, NULL);
}

/* plant_core.refresh_plant_outputs, the outputs x1 (and y), x2 and the third from the state: 1
   done, 0 the Python function's path (before initialization has ended: no state yet), -1 error. */
static int refresh_here(PyObject *binding) {
    PyObject *state = entry(binding, B_STATE), *names = entry(binding, B_STATES);
    if (!(state && PyTuple_CheckExact(state) && PyTuple_Size(state) >= 3 && names && PyTuple_CheckExact(names) &&
          PyTuple_Size(names) == 3 && PyUnicode_CheckExact(PyTuple_GetItem(names, 0)) &&
          PyUnicode_CheckExact(PyTuple_GetItem(names, 1)) && PyUnicode_CheckExact(PyTuple_GetItem(names, 2))))
        return 0;
    PyObject *d = PyTuple_GetItem(binding, B_DICT), *x1 = PyTuple_GetItem(state, 0);
    /* refresh_plant_outputs' order: d[first] = d["y"] = state[0], then the second and third */
    if (PyDict_SetItem(d, PyTuple_GetItem(names, 0), x1) != 0 ||
        PyDict_SetItem(d, PyTuple_GetItem(binding, B_Y), x1) != 0 ||
        PyDict_SetItem(d, PyTuple_GetItem(names, 1), PyTuple_GetItem(state, 1)) != 0 ||
        PyDict_SetItem(d, PyTuple_GetItem(names, 2), PyTuple_GetItem(state, 2)) != 0)
        return -1;
    return 1;
}

static PyObject *refresh_slave(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *binding = binding_of(args, 1, NULL, NULL);
    if (!binding) return NULL;
    int done = refresh_here(binding);
    if (done < 0) return NULL;
    if (done) Py_RETURN_NONE;
    PyErr_Clear();
    return PyObject_CallObject(PyTuple_GetItem(binding, B_REFRESH), NULL);
}

/* The shim's C entries (direct_calls.h): 0 (no error set) where the binding is not a plant's or
   the usual path does not apply, which the shim then leaves to step_slave and refresh_slave. */
static int step_entry(PyObject *binding, double t, double h) {
    return ftc_answer(is_binding(binding) ? usual_step(binding, t, h) : 0);
}

static int refresh_entry(PyObject *binding) {
    return ftc_answer(is_binding(binding) ? refresh_here(binding) : 0);
}

static const struct ftc_direct_calls direct_calls = {FTC_DIRECT_CALLS_VERSION, step_entry, refresh_entry};

static PyMethodDef methods[] = {
    {"hold_step", hold_step, METH_VARARGS,
     "One communication step of a plant by Dormand-Prince 5(4) (see fmu_src/models/plants.py)."},
    {"step_slave", step_slave, METH_VARARGS,
     "step_slave(binding, t, h): a plant FMU's do_step (see fmu_src/plant_core.py:compiled_plant_calls)."},
    {"refresh_slave", refresh_slave, METH_VARARGS,
     "refresh_slave(binding): a plant FMU's refresh_outputs (see fmu_src/plant_core.py:compiled_plant_calls)."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_dopri", "The plants' Dormand-Prince 5(4) step, compiled.", -1, methods,
    NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__dopri(void) {
    PyObject *m = PyModule_Create(&module);
    if (m != NULL && ftc_add_direct_calls(m, "direct_calls", &direct_calls) != 0) Py_CLEAR(m);
    return m;
}
