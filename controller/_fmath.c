/* SPDX-License-Identifier: BSD-2-Clause */
/* _fmath: controller/fmath.h's exp, sin, cos and pow for Python, compiled.

   Owns: nothing of its own. controller/fmath.py calls these in place of its Python transcriptions
   (_exp, _sin, _cos, _pow: the same algorithms, the same bits; tests/test_fmath.py compares all
   three forms) where the FMU build has compiled this module, so the models that run in Python
   (reference, actuator, the law for n > 4) pay about 0.05 us per call instead of 0.7-3 us. May
   not: raise where the functions return inf or nan (fmath.py's wrappers keep the Python contracts).
   Built against the stable ABI (Py_LIMITED_API), as the other extension modules. */

#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include "fmath.h"

#define UNARY(name)                                                   \
    static PyObject *f_##name(PyObject *self, PyObject *arg) {        \
        (void)self;                                                   \
        double x = PyFloat_AsDouble(arg);                             \
        if (x == -1.0 && PyErr_Occurred()) return NULL;               \
        return PyFloat_FromDouble(ftc_##name(x));                     \
    }

UNARY(exp)
UNARY(sin)
UNARY(cos)

static PyObject *f_pow(PyObject *self, PyObject *args) {
    (void)self;
    double x, y;
    if (!PyArg_ParseTuple(args, "dd:pow", &x, &y)) return NULL;
    return PyFloat_FromDouble(ftc_pow(x, y));
}

static PyMethodDef methods[] = {
    {"exp", f_exp, METH_O, "exp(x) as IEEE gives it (fmath.h's ftc_exp)."},
    {"sin", f_sin, METH_O, "sin(x) as IEEE gives it (fmath.h's ftc_sin)."},
    {"cos", f_cos, METH_O, "cos(x) as IEEE gives it (fmath.h's ftc_cos)."},
    {"pow", f_pow, METH_VARARGS, "x ** y as IEEE gives it (fmath.h's ftc_pow)."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_fmath", "controller/fmath.h's exp, sin, cos and pow, compiled.", -1, methods,
    NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__fmath(void) { return PyModule_Create(&module); }
