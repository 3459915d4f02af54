/* SPDX-License-Identifier: BSD-2-Clause */
/* FMI 2.0 host without Python that instantiates several FMUs at the same moment, one thread each
   (as a parallel master may): checks that the FMUs' shims start Python once, not concurrently.

   usage: fmu_c_host_parallel BINARY RESOURCE_URI GUID [BINARY RESOURCE_URI GUID]...
   Prints "ok" or "NULL" per FMU; exit status 0 if every instance was created. */
#include <dlfcn.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

#define MAX_FMUS 16

#include "fmi2FunctionTypes.h" /* the official FMI 2.0 types (fmu_src/cbase/fmi) */

struct job {
    const char *binary, *uri, *guid;
    void *lib, *instance;
};

static pthread_barrier_t start;

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                   fmi2String message, ...) {
    (void)env;
    (void)category;
    va_list args;
    va_start(args, message);
    fprintf(stderr, "[%s status %d] ", name, status);
    vfprintf(stderr, message, args);
    fprintf(stderr, "\n");
    va_end(args);
}

static void *instantiate(void *arg) {
    struct job *job = arg;
    static const fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
    void *(*f)(const char *, int, const char *, const char *, const fmi2CallbackFunctions *, int, int) =
        dlsym(job->lib, "fmi2Instantiate");
    pthread_barrier_wait(&start);
    job->instance = f ? f(job->binary, 1, job->guid, job->uri, &callbacks, 0, 1) : NULL;
    return NULL;
}

int main(int argc, char **argv) {
    int n = (argc - 1) / 3, failed = 0;
    if (n < 1 || n > MAX_FMUS || argc != 1 + 3 * n) {
        fprintf(stderr, "usage: %s BINARY RESOURCE_URI GUID [BINARY RESOURCE_URI GUID]...\n", argv[0]);
        return 2;
    }
    struct job jobs[MAX_FMUS];
    pthread_t threads[MAX_FMUS];
    pthread_barrier_init(&start, NULL, (unsigned)n);
    for (int i = 0; i < n; i++) {
        jobs[i] = (struct job){argv[1 + 3 * i], argv[2 + 3 * i], argv[3 + 3 * i], NULL, NULL};
        jobs[i].lib = dlopen(jobs[i].binary, RTLD_NOW | RTLD_LOCAL);
        if (!jobs[i].lib) {
            printf("dlopen failed: %s\n", dlerror());
            return 2;
        }
    }
    for (int i = 0; i < n; i++) pthread_create(&threads[i], NULL, instantiate, &jobs[i]);
    for (int i = 0; i < n; i++) pthread_join(threads[i], NULL);
    for (int i = 0; i < n; i++) {
        printf("%s\n", jobs[i].instance ? "ok" : "NULL");
        failed |= jobs[i].instance == NULL;
        void (*free_instance)(void *) = dlsym(jobs[i].lib, "fmi2FreeInstance");
        if (jobs[i].instance) free_instance(jobs[i].instance);
    }
    return failed;
}
