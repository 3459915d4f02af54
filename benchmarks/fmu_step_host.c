/* SPDX-License-Identifier: BSD-2-Clause */
/* A timing host for benchmarks/fmu_step.py: one FMI 2.0 Co-Simulation FMU stepped as a C/C++ master
   steps it (libcosim, OMSimulator), with nothing of the host's own in the timed loop: per
   communication step fmi2SetReal of the inputs, fmi2GetReal of the outputs, fmi2DoStep. So the time
   is the FMU's share of a closed-loop step in any C host.

   usage: fmu_step_host BINARY RESOURCE_URI GUID STEPS STEP_SIZE BATCH [p:VR=VALUE]... [i:VR=A,W,P]...
          [o:VR]... [f:I,O=GAIN]...
   p: a Real parameter set before initialization; i: an input fed A sin(W t + P) (precomputed for every
   step before the clock starts); o: an output read every step; f: GAIN times the I-th output read in
   the previous step added to the O-th input (0-based: a feedback, so that a plant that diverges open
   loop stays in range). Prints "cpu_ns_per_step X" (the
   process's CPU time over the loop, divided by the steps: what other processes on the machine do
   not change) and "median_ns_per_step Y" (the median over batches of BATCH steps of the monotonic
   clock: preemptions fall out). Exit status 1 on a status other than fmi2OK, 2 on a load error. */
#define _POSIX_C_SOURCE 199309L
#include <dlfcn.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "fmi2FunctionTypes.h" /* the official FMI 2.0 types (fmu_src/cbase/fmi) */

enum { MAX_VARIABLES = 64 };

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
        fprintf(stderr, "dlsym %s failed: %s\n", name, dlerror());
        exit(2);
    }
    return f;
}

static double seconds(clockid_t clock) {
    struct timespec now;
    clock_gettime(clock, &now);
    return (double)now.tv_sec + 1e-9 * (double)now.tv_nsec;
}

static int by_value(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* The FMU's functions this host calls. */
struct fmu {
    fmi2Component (*instantiate)(const char *, int, const char *, const char *, const fmi2CallbackFunctions *, int,
                                 int);
    int (*setup)(fmi2Component, int, double, double, int, double);
    int (*enter)(fmi2Component);
    int (*exit_)(fmi2Component);
    int (*step)(fmi2Component, double, double, int);
    int (*set)(fmi2Component, const unsigned *, size_t, const double *);
    int (*get)(fmi2Component, const unsigned *, size_t, double *);
    int (*terminate)(fmi2Component);
    void (*free_instance)(fmi2Component);
};

/* The variables of the command line: inputs (and their waves), outputs, feedbacks. */
struct signals {
    unsigned inputs[MAX_VARIABLES], outputs[MAX_VARIABLES];
    double wave[MAX_VARIABLES][3], gain[MAX_VARIABLES];
    int loop[MAX_VARIABLES][2];
    size_t n_in, n_out, n_loop;
};

static struct fmu bind(void *lib) {
    struct fmu f;
    *(void **)&f.instantiate = symbol(lib, "fmi2Instantiate");
    *(void **)&f.setup = symbol(lib, "fmi2SetupExperiment");
    *(void **)&f.enter = symbol(lib, "fmi2EnterInitializationMode");
    *(void **)&f.exit_ = symbol(lib, "fmi2ExitInitializationMode");
    *(void **)&f.step = symbol(lib, "fmi2DoStep");
    *(void **)&f.set = symbol(lib, "fmi2SetReal");
    *(void **)&f.get = symbol(lib, "fmi2GetReal");
    *(void **)&f.terminate = symbol(lib, "fmi2Terminate");
    *(void **)&f.free_instance = symbol(lib, "fmi2FreeInstance");
    return f;
}

/* Reads the arguments p:, i:, o:, f: (parameters are set on `c` now); the status of the calls,
   or -1 for a malformed argument. */
static int parse(int argc, char **argv, const struct fmu *f, fmi2Component c, struct signals *s) {
    int status = 0;
    for (int a = 7; a < argc; a++) {
        char kind = argv[a][0];
        unsigned vr = (unsigned)strtoul(argv[a] + 2, NULL, 10);
        char *equals = strchr(argv[a], '=');
        if (kind == 'p' && equals) {
            double value = atof(equals + 1);
            status |= f->set(c, &vr, 1, &value);
        } else if (kind == 'i' && equals && s->n_in < MAX_VARIABLES) {
            s->inputs[s->n_in] = vr;
            double *w = s->wave[s->n_in];
            if (sscanf(equals + 1, "%lf,%lf,%lf", &w[0], &w[1], &w[2]) != 3) return -1;
            s->n_in++;
        } else if (kind == 'o' && s->n_out < MAX_VARIABLES) {
            s->outputs[s->n_out++] = vr;
        } else if (kind == 'f' && equals && s->n_loop < MAX_VARIABLES) {
            int *l = s->loop[s->n_loop];
            if (sscanf(argv[a] + 2, "%d,%d=%lf", &l[0], &l[1], &s->gain[s->n_loop]) != 3) return -1;
            s->n_loop++;
        }
    }
    return status;
}

/* The timed loop: `batches` batches of `batch` steps of size h on the precomputed input `values`;
   each batch's monotonic time in `times`; the OR of the statuses. */
static int run(const struct fmu *f, fmi2Component c, const struct signals *s, const double *values, long batches,
               long batch, double h, double *times) {
    double read[MAX_VARIABLES] = {0.0}, fed[MAX_VARIABLES];
    int status = 0;
    for (long b = 0; b < batches && status == 0; b++) {
        double start = seconds(CLOCK_MONOTONIC);
        for (long k = b * batch; k < (b + 1) * batch && status == 0; k++) {
            const double *in = values + k * (long)s->n_in;
            if (s->n_loop) {
                for (size_t i = 0; i < s->n_in; i++) fed[i] = in[i];
                for (size_t j = 0; j < s->n_loop; j++) fed[s->loop[j][1]] += s->gain[j] * read[s->loop[j][0]];
                in = fed;
            }
            if (s->n_in) status |= f->set(c, s->inputs, s->n_in, in);
            if (s->n_out) status |= f->get(c, s->outputs, s->n_out, read);
            status |= f->step(c, (double)k * h, h, 1);
        }
        times[b] = seconds(CLOCK_MONOTONIC) - start;
    }
    return status;
}

int main(int argc, char **argv) {
    if (argc < 7) {
        fprintf(stderr, "usage: %s BINARY RESOURCE_URI GUID STEPS STEP_SIZE BATCH [p:VR=V]... [i:VR=A,W,P]... "
                "[o:VR]...\n", argv[0]);
        return 2;
    }
    void *lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "dlopen failed: %s\n", dlerror());
        return 2;
    }
    struct fmu f = bind(lib);
    fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
    fmi2Component c = f.instantiate("timing", 1, argv[3], argv[2], &callbacks, 0, 0);
    if (!c) return 2;
    long steps = atol(argv[4]), batch = atol(argv[6]);
    double h = atof(argv[5]);
    static struct signals s;
    int status = f.setup(c, 0, 0.0, 0.0, 0, 0.0) | f.enter(c);
    int parsed = parse(argc, argv, &f, c, &s);
    if (parsed < 0) return 2;
    status |= parsed | f.exit_(c);
    double *values = malloc(sizeof(double) * (size_t)steps * (s.n_in ? s.n_in : 1));
    long batches = steps / batch;
    double *times = malloc(sizeof(double) * (size_t)(batches ? batches : 1));
    if (!values || !times) return 2;
    for (long k = 0; k < steps; k++)
        for (size_t i = 0; i < s.n_in; i++)
            values[k * (long)s.n_in + (long)i] = s.wave[i][0] * sin(s.wave[i][1] * (double)k * h + s.wave[i][2]);
    double cpu = seconds(CLOCK_PROCESS_CPUTIME_ID);
    if (status == 0) status = run(&f, c, &s, values, batches, batch, h, times);
    cpu = seconds(CLOCK_PROCESS_CPUTIME_ID) - cpu;
    qsort(times, (size_t)batches, sizeof(double), by_value);
    if (status) {
        fprintf(stderr, "an FMI call returned status %d\n", status);
        return 1;
    }
    printf("cpu_ns_per_step %.1f\n", 1e9 * cpu / (double)(batches * batch));
    printf("median_ns_per_step %.1f\n", batches ? 1e9 * times[batches / 2] / (double)batch : 0.0);
    status |= f.terminate(c);
    f.free_instance(c);
    free(values);
    free(times);
    return status ? 1 : 0;
}
