/* SPDX-License-Identifier: BSD-2-Clause */
/* Minimal FMI 2.0 co-simulation host without Python, as a C/C++ importer loads an FMU: dlopen the
   extracted FMU's binary, instantiate, set real variables, step, print real variables.

   usage: fmu_c_host BINARY RESOURCE_URI GUID STEPS STEP_SIZE [VR=VALUE]... [VR]...
   VR=VALUE is set once after fmi2Instantiate (parameters, initial states and held inputs); each bare
   VR is read after the last step and printed as "VR VALUE" (%.17g).
   Exit status: 0 all calls fmi2OK, 2 dlopen/dlsym failed, 3 fmi2Instantiate returned NULL,
   otherwise the OR of the FMI statuses (1 warning, 2 discard, 3 error, 4 fatal). */
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2FunctionTypes.h" /* the official FMI 2.0 types (fmu_src/cbase/fmi) */

/* The FMI logger: message is a printf format. */
static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                   fmi2String message, ...) {
    (void)env;
    va_list args;
    va_start(args, message);
    fprintf(stderr, "[%s status %d %s] ", name, status, category ? category : "");
    vfprintf(stderr, message, args);
    fprintf(stderr, "\n");
    va_end(args);
}

static void *symbol(void *lib, const char *name) {
    void *f = dlsym(lib, name);
    if (!f) {
        printf("dlsym %s failed: %s\n", name, dlerror());
        exit(2);
    }
    return f;
}

int main(int argc, char **argv) {
    if (argc < 6) {
        fprintf(stderr, "usage: %s BINARY RESOURCE_URI GUID STEPS STEP_SIZE [VR=VALUE]... [VR]...\n", argv[0]);
        return 2;
    }
    void *lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        printf("dlopen failed: %s\n", dlerror());
        return 2;
    }
    fmi2Component (*instantiate)(const char *, int, const char *, const char *, const fmi2CallbackFunctions *,
                                 int, int) = symbol(lib, "fmi2Instantiate");
    int (*setup)(fmi2Component, int, double, double, int, double) = symbol(lib, "fmi2SetupExperiment");
    int (*enter)(fmi2Component) = symbol(lib, "fmi2EnterInitializationMode");
    int (*exit_)(fmi2Component) = symbol(lib, "fmi2ExitInitializationMode");
    int (*step)(fmi2Component, double, double, int) = symbol(lib, "fmi2DoStep");
    int (*set)(fmi2Component, const unsigned *, size_t, const double *) = symbol(lib, "fmi2SetReal");
    int (*get)(fmi2Component, const unsigned *, size_t, double *) = symbol(lib, "fmi2GetReal");
    int (*terminate)(fmi2Component) = symbol(lib, "fmi2Terminate");
    void (*freeInstance)(fmi2Component) = symbol(lib, "fmi2FreeInstance");

    fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
    fmi2Component c = instantiate("host", 1, argv[3], argv[2], &callbacks, 0, 1);
    if (!c) {
        printf("instantiate failed\n");
        return 3;
    }
    int steps = atoi(argv[4]), status = 0;
    double h = atof(argv[5]);
    for (int i = 6; i < argc; i++) {
        char *equals = strchr(argv[i], '=');
        if (!equals) continue;
        unsigned vr = (unsigned)strtoul(argv[i], NULL, 10);
        double value = strtod(equals + 1, NULL);
        status |= set(c, &vr, 1, &value);
    }
    status |= setup(c, 0, 0.0, 0.0, 0, 0.0);
    status |= enter(c);
    status |= exit_(c);
    for (int k = 0; k < steps && status == 0; k++) status |= step(c, k * h, h, 1);
    for (int i = 6; i < argc; i++) {
        if (strchr(argv[i], '=')) continue;
        unsigned vr = (unsigned)strtoul(argv[i], NULL, 10);
        double value = 0.0;
        status |= get(c, &vr, 1, &value);
        printf("%u %.17g\n", vr, value);
    }
    printf("status %d\n", status);
    terminate(c);
    freeInstance(c);
    return status;
}
