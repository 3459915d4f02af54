/* SPDX-License-Identifier: BSD-2-Clause */
/* Starts the CPython runtime the FMU carries, isolated from the host: compiled against the headers
   of exactly that runtime (fmu_src/toolchain/runtime.py pins both), so the PyPreConfig/PyConfig layouts match.

   The functions are looked up with dlsym in the libpython the shim loaded: the shim does not link
   libpython, so that a host which already runs Python keeps its own.

   Windows: the same start, of python.org's embeddable CPython 3.11 (python311.dll), compiled
   against the same 3.11 headers with the Windows pyconfig.h of fmu_src/toolchain/shim/win64/ (mingw-w64
   and python.org's MSVC build share the ABI: LLP64, 16-bit wchar_t, so the layouts match; the
   configuration structures are the same in every 3.11 release). */

#define PY_SSIZE_T_CLEAN
#include <Python.h>
#ifdef _WIN32
#define FTC_EXTENSIONS NULL /* the .pyd files sit beside python311.dll */
#else
#define FTC_EXTENSIONS "lib-dynload"
#endif
#include "platform.h"
#include <stdio.h>
#include <string.h>

#include "start_python.h"

struct api {
    void (*pre_isolated)(PyPreConfig *);
    PyStatus (*pre_initialize)(const PyPreConfig *);
    void (*config_isolated)(PyConfig *);
    PyStatus (*set_bytes)(PyConfig *, wchar_t **, const char *);
    PyStatus (*append)(PyWideStringList *, const wchar_t *);
    wchar_t *(*decode)(const char *, size_t *);
    void (*raw_free)(void *);
    PyStatus (*initialize)(const PyConfig *);
    void (*clear)(PyConfig *);
    int (*is_exception)(PyStatus);
    PyThreadState *(*save_thread)(void);
};

static int find_api(void *python, struct api *a) {
    int ok = 1;
#define FIND(field, symbol) ok &= (*(void **)(&a->field) = ftc_library_symbol(python, symbol)) != NULL
    FIND(pre_isolated, "PyPreConfig_InitIsolatedConfig");
    FIND(pre_initialize, "Py_PreInitialize");
    FIND(config_isolated, "PyConfig_InitIsolatedConfig");
    FIND(set_bytes, "PyConfig_SetBytesString");
    FIND(append, "PyWideStringList_Append");
    FIND(decode, "Py_DecodeLocale");
    FIND(raw_free, "PyMem_RawFree");
    FIND(initialize, "Py_InitializeFromConfig");
    FIND(clear, "PyConfig_Clear");
    FIND(is_exception, "PyStatus_Exception");
    FIND(save_thread, "PyEval_SaveThread");
#undef FIND
    return ok;
}

/* Appends home/leaf (leaf NULL: home) to the module search path; 0 on success. */
static int add_path(const struct api *a, PyConfig *config, const char *home, const char *leaf) {
    char path[4096];
    snprintf(path, sizeof path, "%s%s%s", home, leaf ? "/" : "", leaf ? leaf : "");
    wchar_t *wide = a->decode(path, NULL);
    if (!wide) return -1;
    PyStatus status = a->append(&config->module_search_paths, wide);
    a->raw_free(wide);
    return a->is_exception(status) ? -1 : 0;
}

int ftc_start_python(void *python, const char *home, char *failure, size_t size) {
    struct api a;
    if (!find_api(python, &a)) {
        snprintf(failure, size, "the bundled libpython lacks the PyConfig API of Python %d.%d", PY_MAJOR_VERSION,
                 PY_MINOR_VERSION);
        return -1;
    }
    PyPreConfig pre;
    a.pre_isolated(&pre);
    pre.utf8_mode = 1; /* paths and messages are UTF-8 whatever the host's locale */
    PyStatus status = a.pre_initialize(&pre);
    if (a.is_exception(status)) {
        snprintf(failure, size, "Py_PreInitialize failed: %s", status.err_msg ? status.err_msg : "?");
        return -1;
    }

    /* Isolated: no environment variable (PYTHONPATH, PYTHONHOME...), no user site, no current
       directory on sys.path, no signal handlers; and no site module, no bytecode written into
       the FMU's folder. The module search path is the runtime's alone. */
    PyConfig config;
    a.config_isolated(&config);
    config.site_import = 0;
    config.write_bytecode = 0;
    config.install_signal_handlers = 0;
    config.module_search_paths_set = 1;
    status = a.set_bytes(&config, &config.home, home);
    if (a.is_exception(status) || add_path(&a, &config, home, "python" FTC_TAG ".zip") != 0 ||
        add_path(&a, &config, home, FTC_EXTENSIONS) != 0) {
        a.clear(&config);
        snprintf(failure, size, "cannot set the runtime's home and path to %s (out of memory?)", home);
        return -1;
    }
    int saved[3];
    ftc_standard_streams(python, saved);
    status = a.initialize(&config);
    ftc_standard_streams_done(saved);
    a.clear(&config);
    if (a.is_exception(status)) {
        snprintf(failure, size, "Py_InitializeFromConfig failed: %s%s%s",
                 status.func ? status.func : "", status.func ? ": " : "", status.err_msg ? status.err_msg : "?");
        return -1;
    }
    a.save_thread(); /* release the GIL: pythonfmu takes it with PyGILState_Ensure */
    return 0;
}
