/* Minimal FMI 2.0 co-simulation host without Python: load an extracted FMU's binary,
   step it and print one output, as a C/C++ importer would. */
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

typedef void *fmi2Component;
typedef struct {
    void (*logger)(void *, const char *, int, const char *, const char *, ...);
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
    void *stepFinished;
    void *componentEnvironment;
} fmi2CallbackFunctions;

static void logger(void *env, const char *name, int status, const char *category, const char *message, ...) {
    fprintf(stderr, "[%s status %d] %s\n", name, status, message);
}

int main(int argc, char **argv) {
    /* argv: binary.so, resources URI, guid, output value reference, steps */
    void *lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!lib) { printf("dlopen failed: %s\n", dlerror()); return 2; }
    fmi2Component (*instantiate)(const char *, int, const char *, const char *, const fmi2CallbackFunctions *, int, int) =
        dlsym(lib, "fmi2Instantiate");
    int (*setup)(fmi2Component, int, double, double, int, double) = dlsym(lib, "fmi2SetupExperiment");
    int (*enter)(fmi2Component) = dlsym(lib, "fmi2EnterInitializationMode");
    int (*exit_)(fmi2Component) = dlsym(lib, "fmi2ExitInitializationMode");
    int (*step)(fmi2Component, double, double, int) = dlsym(lib, "fmi2DoStep");
    int (*get)(fmi2Component, const unsigned *, size_t, double *) = dlsym(lib, "fmi2GetReal");
    int (*terminate)(fmi2Component) = dlsym(lib, "fmi2Terminate");
    void (*freeInstance)(fmi2Component) = dlsym(lib, "fmi2FreeInstance");
    fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
    fmi2Component c = instantiate("host", 1, argv[3], argv[2], &callbacks, 0, 1);
    if (!c) { printf("instantiate failed\n"); return 3; }
    unsigned vr = (unsigned)atoi(argv[4]);
    int steps = atoi(argv[5]);
    double h = 1e-3, value = 0.0;
    int status = setup(c, 0, 0.0, 0.0, 0, 0.0) | enter(c) | exit_(c);
    for (int k = 0; k < steps && status == 0; k++) status = step(c, k * h, h, 1);
    status |= get(c, &vr, 1, &value);
    printf("status %d value %.17g\n", status, value);
    terminate(c);
    freeInstance(c);
    return status;
}
