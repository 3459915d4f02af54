/* SPDX-License-Identifier: BSD-2-Clause */
/* _law: the controller's law and its RK4 step over one communication step, compiled.

   Owns: the arithmetic of controller/law.py (_law: evaluate and derivative) and of
   controller/stepping.py (rk4_step), operation for operation, so that it gives the same bits.
   Called by controller/native.py (CompiledLaw), which packs the constants; the FMUs call it through
   that module. May not: keep state between calls (every call is a pure function of its
   arguments), or differ from the Python reference in a value, an exception or its message.

   Same bits: every expression is evaluated in the order Python evaluates it (left to right, no
   reassociation: built without -ffast-math and with -ffp-contract=off, so no fused multiply-add);
   exp and pow are fmath.h's, which controller/fmath.py repeats in Python (same bits on every
   platform, unlike the C library's); min follows Python's builtin (the first argument unless the
   second is strictly smaller), which matters for nan. fmath.exp and fmath.power raise where C
   returns inf: py_pow and py_exp below repeat their special cases (those of CPython's float_pow,
   Objects/floatobject.c, and math_1, Modules/mathmodule.c), and an evaluation raises the first
   error at the point where the Python code would.

   Why compiled: the law costs about 1.5 us per RK4 stage in Python, four stages per communication
   step; a controller FMU spends its step there. What depends on the held inputs alone (|x1|^gamma,
   z1 and its powers, X_1's input sums) is computed once per call and shared by the stages (as
   controller/order2.py did in Python until issue 47); a power computed early keeps its error until
   the point where the reference computes it.

   Functions (constants: bytes packed by controller.native.law_constants, n = 1..4; state: the tuple
   (r, eta_1..eta_n); inputs: the tuple (x_1..x_n, yd, yd', ..., yd^(n))):
   evaluate(constants, state, inputs) -> (v, z_1..z_n, zeta_1..zeta_n, ptp_1..ptp_n, r', eta_1'..eta_n')
   advance(constants, substeps, h, first, state, inputs) -> (r, eta_1..eta_n) after h; first: None or
       evaluate's result at this state and inputs (its derivative is the first RK4 stage).
   step_slave(binding, t, h), refresh_slave(binding): a controller FMU's do_step and refresh_outputs on
       its slave's __dict__ (fmu_src/controller_core.py, compiled_controller_calls), what the FMU's shim
       calls per step: the Python ones did the same around evaluate and advance in about 11,000
       interpreter instructions per step (n = 2).
   Built against the stable ABI (Py_LIMITED_API) so that one binary loads in any CPython 3.8 or
   later: the FMU's own runtime, or the host's Python when the host runs one. */

#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>

#include "direct_calls.h"
#include "fmath.h"

#define MAX_ORDER 4
#define HEADER 12 /* doubles before the per-step gains, see law_constants in native.py */

/* A parameter set, pointing into the packed constants. */
typedef struct {
    int n, semi, m, nn; /* plant order, semi-implicit law, RBF neurons, NN term in zeta_i (0: off) */
    double p_alpha, p_beta, a_bar, gamma_gain, gamma_power, d_r, scale, bh;
    const double *k, *q, *two_a2, *kappa, *leak; /* n each: k_eff, q, 2 a^2, kappa, rho + rho_bar */
    const double *two_mu;                         /* m: 2 mu_j */
    const double *dim_mu2;                        /* n x m: (dim_i mu_j) mu_j, dim_i = 4 + 3 (i - 1) */
} Law;

/* A power computed ahead of its use: its value, and the error Python raises when it computes it
   (0: none; OVERFLOWED: OverflowError; NEGATIVE_ZERO_POWER: 0 raised to a negative power). */
typedef struct {
    double value;
    int error;
} Power;

enum { OVERFLOWED = 1, NEGATIVE_ZERO_POWER = 2 };

static int raise_power(int error) {
    if (error == NEGATIVE_ZERO_POWER) {
        PyErr_SetString(PyExc_ZeroDivisionError, "0.0 cannot be raised to a negative power");
    } else {
        PyErr_SetString(PyExc_OverflowError, "math range error");
    }
    return -1;
}

static int is_odd_integer(double x) { return fmod(fabs(x), 2.0) == 1.0; }

/* fmath.power(iv, iw) (CPython's float_pow on fmath's pow), for iv >= 0 or nan (the law raises |z|, |x1|). */
static Power py_pow(double iv, double iw) {
    Power out = {0.0, 0};
    if (iw == 0.0) {
        out.value = 1.0;
    } else if (isnan(iv)) {
        out.value = iv;
    } else if (isnan(iw)) {
        out.value = iv == 1.0 ? 1.0 : iw;
    } else if (isinf(iw)) {
        iv = fabs(iv);
        out.value = iv == 1.0 ? 1.0 : ((iw > 0.0) == (iv > 1.0) ? fabs(iw) : 0.0);
    } else if (isinf(iv)) {
        int odd = is_odd_integer(iw);
        out.value = iw > 0.0 ? (odd ? iv : fabs(iv)) : (odd ? copysign(0.0, iv) : 0.0);
    } else if (iv == 0.0) {
        if (iw < 0.0)
            out.error = NEGATIVE_ZERO_POWER;
        else
            out.value = is_odd_integer(iw) ? iv : 0.0;
    } else if (iv == 1.0) {
        out.value = 1.0;
    } else {
        out.value = ftc_pow(iv, iw);
        if (isinf(out.value)) out.error = OVERFLOWED;
    }
    return out;
}

/* fmath.exp(x) into *out; -1 with its OverflowError where the result overflows. */
static int py_exp(double x, double *out) {
    double r = ftc_exp(x);
    if (isinf(r) && isfinite(x)) {
        PyErr_SetString(PyExc_OverflowError, "math range error");
        return -1;
    }
    *out = r;
    return 0;
}

/* a / b into *out; -1 with Python's exception where float division raises (b == 0: 2 a^2 or
   b_max sample_time underflowed to zero). */
static int divide(double a, double b, double *out) {
    if (b == 0.0) {
        PyErr_SetString(PyExc_ZeroDivisionError, "float division by zero");
        return -1;
    }
    *out = a / b;
    return 0;
}

/* What the law takes from the held inputs alone, computed once per call. */
typedef struct {
    const double *x, *yd; /* n and n + 1 */
    double s1, s2;        /* x1 + yd + yd' and x1^2 + yd^2 + yd'^2: X_1's sums before r */
    double z1;
    Power gamma, z1_alpha, z1_beta; /* |x1|^gamma_power, |z1|^(2 alpha - 1), |z1|^(2 beta - 1) */
} Held;

static void hold(const Law *law, const double *x, const double *yd, Held *held) {
    held->x = x;
    held->yd = yd;
    held->s1 = x[0] + yd[0] + yd[1];
    held->s2 = x[0] * x[0] + yd[0] * yd[0] + yd[1] * yd[1];
    held->z1 = x[0] - yd[0];
    held->gamma = py_pow(fabs(x[0]), law->gamma_power);
    held->z1_alpha = py_pow(fabs(held->z1), law->p_alpha);
    held->z1_beta = py_pow(fabs(held->z1), law->p_beta);
}

/* P^T P of step i (controller.rbf.rbf_energy with dim = 4 + 3 i). */
static int energy(const Law *law, int i, double s1, double s2, double *ptp) {
    const double *dim_mu2 = law->dim_mu2 + (size_t)i * (size_t)law->m;
    double total = 0.0;
    for (int j = 0; j < law->m; j++) {
        double e;
        if (py_exp(law->scale * (s2 - law->two_mu[j] * s1 + dim_mu2[j]), &e)) return -1;
        total += e;
    }
    *ptp = total;
    return 0;
}

/* zeta_i from its error z, weight and estimate (eq. 37/54/68, or the semi-implicit value);
   alpha_power, beta_power: |z|^(2 alpha - 1), |z|^(2 beta - 1), raised here if they failed. */
static int virtual_control(const Law *law, int i, double z, double weight, double eta, Power alpha_power,
                           Power beta_power, double *zeta) {
    if (law->semi) {
        double a = fabs(z);
        if (alpha_power.error) return raise_power(alpha_power.error);
        if (beta_power.error) return raise_power(beta_power.error);
        double phi = law->nn ? law->k[i] * alpha_power.value + law->q[i] * beta_power.value + eta * a * weight
                             : law->k[i] * alpha_power.value + law->q[i] * beta_power.value;
        if (z == 0.0) {
            *zeta = 0.0;
        } else {
            double layer;
            if (divide(a, law->bh, &layer)) return -1;
            *zeta = -copysign(layer < phi ? layer : phi, z);
        }
    } else if (z != 0.0) {
        if (alpha_power.error) return raise_power(alpha_power.error);
        double sig_alpha = copysign(alpha_power.value, z);
        if (beta_power.error) return raise_power(beta_power.error);
        double sig_beta = copysign(beta_power.value, z);
        *zeta = law->nn ? -law->k[i] * sig_alpha - law->q[i] * sig_beta - eta * z * weight
                        : -law->k[i] * sig_alpha - law->q[i] * sig_beta;
    } else {
        *zeta = 0.0;
    }
    return 0;
}

/* One evaluation of the law at state (r, eta) (controller.law._law): z, zeta, ptp (n each) and the
   state derivative rates (n + 1); with_v 0 leaves zeta_n out. 0, or -1 with the exception set. */
static int law_at(const Law *law, const Held *held, double r, const double *eta, int with_v, double *z,
                  double *zeta, double *ptp, double *rates) {
    int n = law->n;
    if (held->gamma.error) return raise_power(held->gamma.error);
    rates[0] = -law->a_bar * r + law->gamma_gain * held->gamma.value + law->d_r; /* eq. 20 */
    double s1 = held->s1 + r;
    double s2 = held->s2 + r * r;
    double previous = held->yd[0];
    for (int i = 0; i < n; i++) {
        const double *x = held->x, *yd = held->yd;
        if (i > 0) {
            s1 += x[i] + eta[i - 1] + yd[i + 1];
            s2 += x[i] * x[i] + eta[i - 1] * eta[i - 1] + yd[i + 1] * yd[i + 1];
        }
        double zi = i == 0 ? held->z1 : x[i] - previous; /* eq. 26 */
        double weight;
        if (energy(law, i, s1, s2, &ptp[i]) || divide(ptp[i], law->two_a2[i], &weight)) return -1;
        zeta[i] = 0.0;
        if (i < n - 1 || with_v) {
            Power alpha_power = i == 0 ? held->z1_alpha : py_pow(fabs(zi), law->p_alpha);
            Power beta_power = i == 0 ? held->z1_beta : py_pow(fabs(zi), law->p_beta);
            if (virtual_control(law, i, zi, weight, eta[i], alpha_power, beta_power, &zeta[i])) return -1;
        }
        rates[i + 1] = law->kappa[i] * zi * zi * weight - law->leak[i] * eta[i]; /* eq. 38 */
        z[i] = zi;
        previous = zeta[i];
    }
    return 0;
}

/* The packed constants (bytes, see controller.native.law_constants) as a Law; -1 if malformed. */
static int unpack(PyObject *constants, Law *law) {
    char *buffer;
    Py_ssize_t size;
    if (PyBytes_AsStringAndSize(constants, &buffer, &size)) return -1;
    const double *c = (const double *)(void *)buffer;
    if ((uintptr_t)buffer % sizeof(double) || size < (Py_ssize_t)(HEADER * sizeof(double))) {
        PyErr_SetString(PyExc_ValueError, "constants: not packed by controller.native.law_constants");
        return -1;
    }
    law->n = (int)c[0];
    law->semi = c[1] != 0.0;
    law->m = (int)c[2];
    Py_ssize_t n = law->n, m = law->m;
    if (n < 1 || n > MAX_ORDER || m < 0 || size != (Py_ssize_t)sizeof(double) * (HEADER + 5 * n + m + n * m)) {
        PyErr_Format(PyExc_ValueError, "constants: not packed by controller.native.law_constants for a plant "
                     "order n = 1..%d", MAX_ORDER);
        return -1;
    }
    law->p_alpha = c[3];
    law->p_beta = c[4];
    law->a_bar = c[5];
    law->gamma_gain = c[6];
    law->gamma_power = c[7];
    law->d_r = c[8];
    law->scale = c[9];
    law->bh = c[10];
    law->nn = c[11] != 0.0;
    const double *at = c + HEADER;
    law->k = at;
    law->q = at + n;
    law->two_a2 = at + 2 * n;
    law->kappa = at + 3 * n;
    law->leak = at + 4 * n;
    law->two_mu = at + 5 * n;
    law->dim_mu2 = at + 5 * n + m;
    return 0;
}

/* The tuple t of count doubles into out (what names them, for the message); -1 if it is not one. */
static int doubles_of(PyObject *t, Py_ssize_t count, const char *what, int n, double *out) {
    if (!PyTuple_Check(t)) {
        PyErr_Format(PyExc_TypeError, "the law of order n = %d takes %s as a tuple", n, what);
        return -1;
    }
    if (PyTuple_Size(t) != count) {
        PyErr_Format(PyExc_TypeError, "the law of order n = %d takes %s: %zd values (got %zd)", n, what, count,
                     PyTuple_Size(t));
        return -1;
    }
    for (Py_ssize_t i = 0; i < count; i++) {
        out[i] = PyFloat_AsDouble(PyTuple_GetItem(t, i));
        if (out[i] == -1.0 && PyErr_Occurred()) return -1;
    }
    return 0;
}

/* state (r, eta_1..eta_n) and inputs (x_1..x_n, yd..yd^(n)) into in[0..n] and in[n + 1..3n + 1]. */
static int arguments(PyObject *state, PyObject *inputs, int n, double *in) {
    if (doubles_of(state, n + 1, "state (r, eta_hat_1..eta_hat_n)", n, in)) return -1;
    return doubles_of(inputs, 2 * n + 1, "inputs (x1..xn, yd..yd^(n))", n, in + n + 1);
}

static PyObject *doubles(const double *v, Py_ssize_t count) {
    PyObject *tuple = PyTuple_New(count);
    if (tuple == NULL) return NULL;
    for (Py_ssize_t i = 0; i < count; i++) {
        PyObject *item = PyFloat_FromDouble(v[i]);
        if (item == NULL) {
            Py_DECREF(tuple);
            return NULL;
        }
        PyTuple_SetItem(tuple, i, item);
    }
    return tuple;
}

static PyObject *evaluate(PyObject *self, PyObject *args) {
    (void)self;
    Law law;
    double in[3 * MAX_ORDER + 2], out[4 * MAX_ORDER + 2];
    PyObject *constants, *state, *inputs;
    if (!PyArg_UnpackTuple(args, "evaluate", 3, 3, &constants, &state, &inputs) || unpack(constants, &law))
        return NULL;
    int n = law.n;
    if (arguments(state, inputs, n, in)) return NULL;
    Held held;
    hold(&law, in + n + 1, in + 2 * n + 1, &held);
    double *z = out + 1, *zeta = out + 1 + n, *ptp = out + 1 + 2 * n, *rates = out + 1 + 3 * n;
    if (law_at(&law, &held, in[0], in + 1, 1, z, zeta, ptp, rates)) return NULL;
    out[0] = zeta[n - 1];
    return doubles(out, 4 * (Py_ssize_t)n + 2);
}

/* The state derivative at state y (n + 1 values), into rates; -1 with the exception set. */
static int derivative(const Law *law, const Held *held, const double *y, double *rates) {
    double z[MAX_ORDER], zeta[MAX_ORDER], ptp[MAX_ORDER];
    return law_at(law, held, y[0], y + 1, 0, z, zeta, ptp, rates);
}

/* controller.stepping.rk4_step: substeps classical RK4 steps of h / substeps, inputs held; first
   (n + 1 values or NULL) is the derivative at y, the first stage. */
static int rk4(const Law *law, const Held *held, long substeps, double h, const double *first, double *y) {
    int m = law->n + 1;
    double k1[MAX_ORDER + 1], k2[MAX_ORDER + 1], k3[MAX_ORDER + 1], k4[MAX_ORDER + 1], stage[MAX_ORDER + 1];
    double dt = h / (double)substeps;
    for (long s = 0; s < substeps; s++) {
        if (first != NULL && s == 0) {
            for (int j = 0; j < m; j++) k1[j] = first[j];
        } else if (derivative(law, held, y, k1)) {
            return -1;
        }
        for (int j = 0; j < m; j++) stage[j] = y[j] + 0.5 * dt * k1[j];
        if (derivative(law, held, stage, k2)) return -1;
        for (int j = 0; j < m; j++) stage[j] = y[j] + 0.5 * dt * k2[j];
        if (derivative(law, held, stage, k3)) return -1;
        for (int j = 0; j < m; j++) stage[j] = y[j] + dt * k3[j];
        if (derivative(law, held, stage, k4)) return -1;
        for (int j = 0; j < m; j++) y[j] = y[j] + dt / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]);
    }
    return 0;
}

static PyObject *advance(PyObject *self, PyObject *args) {
    (void)self;
    Law law;
    double in[3 * MAX_ORDER + 2], first[MAX_ORDER + 1];
    PyObject *constants, *count, *step, *stage, *state, *inputs;
    if (!PyArg_UnpackTuple(args, "advance", 6, 6, &constants, &count, &step, &stage, &state, &inputs) ||
        unpack(constants, &law))
        return NULL;
    int n = law.n;
    long substeps = PyLong_AsLong(count);
    if (substeps == -1 && PyErr_Occurred()) return NULL;
    if (substeps < 1) {
        PyErr_Format(PyExc_ValueError, "substeps must be >= 1 (got %ld)", substeps);
        return NULL;
    }
    double h = PyFloat_AsDouble(step);
    if (h == -1.0 && PyErr_Occurred()) return NULL;
    const double *start = NULL;
    if (stage != Py_None) {
        if (!PyTuple_Check(stage) || PyTuple_Size(stage) != 4 * n + 2) {
            PyErr_Format(PyExc_TypeError, "first must be None or evaluate's result for order n = %d", n);
            return NULL;
        }
        for (int j = 0; j <= n; j++) {
            first[j] = PyFloat_AsDouble(PyTuple_GetItem(stage, 3 * n + 1 + j));
            if (first[j] == -1.0 && PyErr_Occurred()) return NULL;
        }
        start = first;
    }
    if (arguments(state, inputs, n, in)) return NULL;
    Held held;
    hold(&law, in + n + 1, in + 2 * n + 1, &held);
    if (rk4(&law, &held, substeps, h, start, in)) return NULL;
    return doubles(in, n + 1);
}

/* The controller FMU's own calls (fmu_src/controller_core.py, compiled_controller_calls): its step and
   output refresh on the slave's __dict__, with no interpreter frame. binding: (the dict, the Python
   step, the Python refresh, the input keys x_1..x_n, yd..yd^(n), the output keys r, eta_1_hat..
   eta_n_hat, v, z_1..z_n, zeta_1..zeta_(n-1), then the keys below). The usual path reads and writes
   the entries step_controller and refresh_controller_outputs do, with the same values; any other
   (initialization, the semi-implicit law's step-size check, a non-finite state, an error, an entry
   of another type) calls the Python function instead, having changed nothing, so that every message
   stays the Python code's. The dict keeps every state (snapshots deep-copy it); nothing is kept here. */
enum { B_DICT, B_STEP, B_REFRESH, B_INPUTS, B_OUTPUTS, B_LAW, B_STATE, B_STAGE, B_STALE, B_UNCHECKED,
       B_PARAMS, B_SAMPLE_TIME, B_CONSTANTS, B_SUBSTEPS, B_LAW_TYPE, B_ITEMS };

/* v as a double if it is exactly a float (no Python code runs to convert it: the entries read stay
   as they are while this code holds them borrowed); 0 if it is anything else. */
static int exact(PyObject *v, double *out) {
    if (v == NULL || !PyFloat_CheckExact(v)) return 0;
    *out = PyFloat_AsDouble(v);
    return 1;
}

/* The count floats of t at offset from, exactly (see exact), if t is exactly a tuple of size items;
   0 if not. */
static int exact_doubles(PyObject *t, Py_ssize_t size, Py_ssize_t from, Py_ssize_t count, double *out) {
    if (t == NULL || !PyTuple_CheckExact(t) || PyTuple_Size(t) != size) return 0;
    for (Py_ssize_t i = 0; i < count; i++)
        if (!exact(PyTuple_GetItem(t, from + i), &out[i])) return 0;
    return 1;
}

/* The slave's law and its inputs and state: 1, 0 to call the Python function (an error cleared), -1
   on an error to raise. *constants (a new reference) keeps law's arrays alive. */
static int slave_law(PyObject *binding, Law *law, PyObject **constants, long *substeps, double *in) {
    PyObject *d = PyTuple_GetItem(binding, B_DICT);
    PyObject *held = PyDict_GetItemWithError(d, PyTuple_GetItem(binding, B_LAW)); /* None: initialization */
    PyObject *keys = PyTuple_GetItem(binding, B_INPUTS);
    if (held == NULL || (PyObject *)Py_TYPE(held) != PyTuple_GetItem(binding, B_LAW_TYPE)) return 0;
    *constants = PyObject_GetAttr(held, PyTuple_GetItem(binding, B_CONSTANTS)); /* a CompiledLaw's slots */
    PyObject *count = *constants ? PyObject_GetAttr(held, PyTuple_GetItem(binding, B_SUBSTEPS)) : NULL;
    if (count == NULL || !PyBytes_Check(*constants) || unpack(*constants, law)) goto other;
    *substeps = PyLong_AsLong(count);
    Py_DECREF(count);
    count = NULL;
    PyObject *state = PyDict_GetItemWithError(d, PyTuple_GetItem(binding, B_STATE));
    if (*substeps < 1 || PyTuple_Size(keys) != 2 * law->n + 1 ||
        !exact_doubles(state, law->n + 1, 0, law->n + 1, in))
        goto other;
    for (Py_ssize_t i = 0; i < 2 * law->n + 1; i++)
        if (!exact(PyDict_GetItemWithError(d, PyTuple_GetItem(keys, i)), &in[law->n + 1 + i])) goto other;
    return 1;
other:
    Py_XDECREF(count);
    Py_CLEAR(*constants);
    PyErr_Clear();
    return 0;
}

/* The Python function binding[which] with args (a step's t and h, or none). */
static PyObject *python_call(PyObject *binding, int which, PyObject *args) {
    PyErr_Clear();
    return PyObject_CallObject(PyTuple_GetItem(binding, which), args);
}

/* step_controller on the usual path for a step of h: 1 done, 0 call the Python step, -1 error. */
static int step_here(PyObject *binding, double h) {
    PyObject *d = PyTuple_GetItem(binding, B_DICT), *constants = NULL;
    Law law;
    long substeps;
    double in[3 * MAX_ORDER + 2], first[MAX_ORDER + 1];
    int usual = slave_law(binding, &law, &constants, &substeps, in);
    if (usual <= 0) return usual;
    int n = law.n;
    PyObject *unchecked = PyDict_GetItemWithError(d, PyTuple_GetItem(binding, B_UNCHECKED));
    PyObject *stale = PyDict_GetItemWithError(d, PyTuple_GetItem(binding, B_STALE));
    int check = unchecked == Py_True, is_stale = stale == Py_True; /* exactly bool, or Python decides */
    if ((!check && unchecked != Py_False) ||
        (!is_stale && stale != Py_False))
        goto other;
    if (check) { /* the semi-implicit law: nothing to check while h is its sample time */
        PyObject *params = PyDict_GetItemWithError(d, PyTuple_GetItem(binding, B_PARAMS));
        PyObject *sample = params ? PyObject_GetAttr(params, PyTuple_GetItem(binding, B_SAMPLE_TIME)) : NULL;
        double sample_time = sample ? PyFloat_AsDouble(sample) : -1.0;
        Py_XDECREF(sample);
        if (PyErr_Occurred() || h != sample_time) goto other; /* the Python step checks and warns */
    }
    const double *start = NULL;
    if (!is_stale) { /* the law behind the outputs is the first stage */
        PyObject *stage = PyDict_GetItemWithError(d, PyTuple_GetItem(binding, B_STAGE));
        if (!exact_doubles(stage, 4 * n + 2, 3 * n + 1, n + 1, first)) goto other;
        start = first;
    }
    Held held;
    hold(&law, in + n + 1, in + 2 * n + 1, &held);
    if (rk4(&law, &held, substeps, h, start, in)) goto other;
    for (int j = 0; j <= n; j++)
        if (!isfinite(in[j])) goto other; /* rejected: the Python step reports it */
    Py_DECREF(constants);
    PyObject *state = doubles(in, n + 1);
    /* the stale flag: the shim sets it after every step, as step_controller's caller does */
    int failed = state == NULL || PyDict_SetItem(d, PyTuple_GetItem(binding, B_STATE), state);
    Py_XDECREF(state);
    return failed ? -1 : 1;
other:
    Py_DECREF(constants);
    return 0;
}

/* Whether binding is a tuple of compiled_controller_calls' size. */
static int is_slave_binding(PyObject *binding) {
    return PyTuple_Check(binding) && PyTuple_Size(binding) == B_ITEMS;
}

static PyObject *step_slave(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *binding, *t, *h;
    if (!PyArg_UnpackTuple(args, "step_slave", 3, 3, &binding, &t, &h)) return NULL;
    if (!is_slave_binding(binding)) {
        PyErr_SetString(PyExc_TypeError, "step_slave: binding not made by compiled_controller_calls");
        return NULL;
    }
    double step = PyFloat_AsDouble(h);
    int done = step == -1.0 && PyErr_Occurred() ? 0 : step_here(binding, step);
    if (done < 0) return NULL;
    if (done) Py_RETURN_TRUE;
    PyObject *pair = PyTuple_Pack(2, t, h);
    PyObject *result = pair ? python_call(binding, B_STEP, pair) : NULL;
    Py_XDECREF(pair);
    return result;
}

/* refresh_controller_outputs on the usual path: 1 done, 0 call the Python refresh, -1 error. */
static int refresh_here(PyObject *binding) {
    PyObject *d = PyTuple_GetItem(binding, B_DICT), *constants = NULL;
    Law law;
    long substeps;
    double in[3 * MAX_ORDER + 2], out[4 * MAX_ORDER + 2];
    int usual = slave_law(binding, &law, &constants, &substeps, in);
    if (usual <= 0) return usual;
    int n = law.n;
    PyObject *keys = PyTuple_GetItem(binding, B_OUTPUTS);
    Held held;
    hold(&law, in + n + 1, in + 2 * n + 1, &held);
    double *z = out + 1, *zeta = out + 1 + n, *ptp = out + 1 + 2 * n, *rates = out + 1 + 3 * n;
    int failed = PyTuple_Size(keys) != 3 * n + 1 ||
                 law_at(&law, &held, in[0], in + 1, 1, z, zeta, ptp, rates);
    Py_DECREF(constants);
    if (failed) {
        PyErr_Clear();
        return 0;
    }
    out[0] = zeta[n - 1];
    PyObject *stage = doubles(out, 4 * (Py_ssize_t)n + 2);
    PyObject *state = PyDict_GetItemWithError(d, PyTuple_GetItem(binding, B_STATE));
    Py_XINCREF(state);
    failed = stage == NULL || PyDict_SetItem(d, PyTuple_GetItem(binding, B_STAGE), stage);
    /* r, eta_hat_i from the state; v, z_i, zeta_i (i < n) from the stage */
    for (Py_ssize_t i = 0; i < 3 * n + 1 && !failed; i++) {
        PyObject *value = i <= n ? PyTuple_GetItem(state, i) : PyTuple_GetItem(stage, i - n - 1);
        failed = PyDict_SetItem(d, PyTuple_GetItem(keys, i), value);
    }
    Py_XDECREF(stage);
    Py_XDECREF(state);
    return failed ? -1 : 1;
}

static PyObject *refresh_slave(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *binding;
    if (!PyArg_UnpackTuple(args, "refresh_slave", 1, 1, &binding)) return NULL;
    if (!is_slave_binding(binding)) {
        PyErr_SetString(PyExc_TypeError, "refresh_slave: binding not made by compiled_controller_calls");
        return NULL;
    }
    int done = refresh_here(binding);
    if (done < 0) return NULL;
    if (done) Py_RETURN_NONE;
    return python_call(binding, B_REFRESH, NULL);
}

/* The shim's C entries (direct_calls.h): step_slave and refresh_slave on their usual path, 0 (no
   error set) for every other, which the shim then leaves to them. */
static int step_entry(PyObject *binding, double t, double h) {
    (void)t;
    return ftc_answer(is_slave_binding(binding) ? step_here(binding, h) : 0);
}

static int refresh_entry(PyObject *binding) {
    return ftc_answer(is_slave_binding(binding) ? refresh_here(binding) : 0);
}

static const struct ftc_direct_calls direct_calls = {FTC_DIRECT_CALLS_VERSION, step_entry, refresh_entry};

static PyMethodDef methods[] = {
    {"evaluate", evaluate, METH_VARARGS,
     "The law at one state and input: (v, z, zeta, ptp, derivative), flat (see controller/native.py)."},
    {"advance", advance, METH_VARARGS,
     "The state after one communication step of RK4 with the inputs held (see controller/native.py)."},
    {"step_slave", step_slave, METH_VARARGS,
     "A controller FMU's step on its slave's dict (see fmu_src/controller_core.py)."},
    {"refresh_slave", refresh_slave, METH_VARARGS,
     "A controller FMU's output refresh on its slave's dict (see fmu_src/controller_core.py)."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_law", "The controller's law and its RK4 step, compiled.", -1, methods,
    NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__law(void) {
    PyObject *m = PyModule_Create(&module);
    if (m != NULL && ftc_add_direct_calls(m, "direct_calls", &direct_calls) != 0) Py_CLEAR(m);
    return m;
}
