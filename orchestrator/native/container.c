/* FMI 2.0 (and 3.0, at the end of this file) Co-Simulation container: a whole SSP scenario as one
   FMU (`orchestrate export`).

   The container is this shared library, a plan (resources/container.plan) and the scenario's
   FMUs unpacked under resources/fmus/<folder>/. It carries no interpreter of its own: each
   embedded FMU (FMI 2.0 or 3.0 Co-Simulation) is loaded with dlopen as any C host would load it,
   so the project's FMUs start their own bundled Python through their shim (one interpreter per
   process, whatever the number of FMUs) or use the host's.

   The plan is the engine's own (orchestrator/plan.py, read by plan.c): components, start values
   (SSD, SSV, --parameter-set, --set, units converted), the grid t_k = t0 + k h in integer
   nanoseconds, the value buffer and the master's operations, plus the container's variables. The
   core (core.c) replays it, making the same FMI calls with the same arguments in the same order as
   the engine's executors; this file is the FMI API around it:

   * fmi2Instantiate instantiates every FMU in the scenario's order;
   * fmi2EnterInitializationMode: per FMU start values, setup, initialization mode, start values
     again (core_enter_initialization); fmi2ExitInitializationMode: the master's initialization
     (core_exit_initialization);
   * fmi2DoStep(t, H) runs the internal steps from the container's own count k up to the grid point
     t + H, so H must be a whole number of the scenario's steps; the time passed to the FMUs is
     always (t0 + k h) / 1e9, never the host's sum. Inputs the host sets are passed on at once;
     with gauss-seidel, outputs that depend on them are propagated again before they are read. */

#define _GNU_SOURCE
#include <dlfcn.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core.h"
#include "fmi2Functions.h"
#include "fmi3Functions.h"
#include "plan.h"

#define EXPORT FMI2_Export
#define TEXT 4096

/* What an embedded FMI 3.0 FMU's logMessage needs (FMI 3.0 passes no instance name). */
struct relay3 {
    struct container *x;
    const char *name;
};

enum state { INSTANTIATED, INITIALIZATION, STEPPING, TERMINATED, FAILED };

struct container {
    struct plan plan;
    struct core core;
    void **libraries;       /* dlopen handles, per component */
    struct relay3 *relays;  /* per component */
    char name[256];
    char resources[TEXT];
    fmi2CallbackFunctions host;
    /* FMI 3.0 host (fmi3InstantiateCoSimulation): its logMessage and instance environment */
    void (*log3)(void *, int, const char *, const char *);
    void *env3;
    fmi2CallbackFunctions inner;
    int logging;
    enum state state;
    double *values;
    int64_t k;          /* internal steps done */
    int dirty;          /* gauss-seidel: an exposed input changed since the last propagation */
    int *input_set;     /* per exposed variable: the host set it (inputs are applied after start values) */
    double stop;
    int stop_defined;
};

/* ---- messages -------------------------------------------------------------------------------- */

static void say(struct container *x, fmi2Status status, const char *format, ...) {
    char text[TEXT], escaped[2 * TEXT];
    va_list args;
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    const char *category =
        status == fmi2OK ? "logAll" : status == fmi2Warning ? "logStatusWarning" : "logStatusError";
    if (x && status >= fmi2Error) x->state = FAILED; /* the standard's Error state: latched */
    if (x && x->log3) {
        x->log3(x->env3, (int)status, category, text);
        return;
    }
    if (!x || !x->host.logger) {
        fprintf(stderr, "%s\n", text);
        return;
    }
    size_t j = 0;
    for (const char *p = text; *p && j + 2 < sizeof escaped; p++) {
        if (*p == '%') escaped[j++] = '%';
        escaped[j++] = *p;
    }
    escaped[j] = '\0';
    x->host.logger(x->host.componentEnvironment, x->name, status, category, escaped);
}

/* An embedded FMU's message (formatted) to the host's logger under the container's name, prefixed
   with the FMU's instance name (its component name). */
static void pass_on(struct container *x, const char *instance, int status, const char *category,
                    const char *text) {
    char escaped[2 * TEXT + 300];
    if (x && x->log3) {
        snprintf(escaped, sizeof escaped, "%s: %s", instance ? instance : "?", text);
        x->log3(x->env3, status, category ? category : "logAll", escaped);
        return;
    }
    if (!x || !x->host.logger) {
        fprintf(stderr, "%s: %s\n", instance ? instance : "?", text);
        return;
    }
    size_t j = (size_t)snprintf(escaped, 300, "%s: ", instance ? instance : "?");
    for (const char *p = text; *p && j + 2 < sizeof escaped; p++) {
        if (*p == '%') escaped[j++] = '%';
        escaped[j++] = *p;
    }
    escaped[j] = '\0';
    x->host.logger(x->host.componentEnvironment, x->name, (fmi2Status)status, category ? category : "logAll",
                   escaped);
}

/* The embedded FMI 2.0 FMUs' logger. */
static void relay(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status, fmi2String category,
                  fmi2String message, ...) {
    char text[TEXT];
    va_list args;
    va_start(args, message);
    vsnprintf(text, sizeof text, message ? message : "", args);
    va_end(args);
    pass_on(env, instance, status, category, text);
}

/* The embedded FMI 3.0 FMUs' logMessage (the message comes formatted). */
static void relay3(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category, fmi3String message) {
    const struct relay3 *r = env;
    pass_on(r ? r->x : NULL, r ? r->name : NULL, status, category, message ? message : "");
}

/* The core's failure: one line as `orchestrate run` reports it; the container's status. */
static fmi2Status failed(struct container *x) {
    const struct failure *f = &x->core.failure;
    const struct part *c = &x->plan.components[f->component];
    say(x, f->status >= fmi2Error ? (fmi2Status)f->status : fmi2Error, "%s: %s returned %s at t=%.3f s", c->name,
        fmu_function(c->version, f->function), fmu_status(c->version, f->status), f->time);
    x->state = FAILED;
    return f->status >= fmi2Fatal ? fmi2Fatal : fmi2Error;
}

/* The core's result as the container's status. */
#define CORE(x, call) ((call) ? failed(x) : fmi2OK)

/* ---- loading the embedded FMUs ------------------------------------------------------------- */

/* The container's resources folder: ../../resources from this library (binaries/<platform>/X.so). */
static int own_resources(char *out, size_t size) {
    Dl_info self;
    if (!dladdr((void *)&own_resources, &self) || !self.dli_fname) return -1;
    snprintf(out, size, "%s", self.dli_fname);
    for (int up = 0; up < 3; up++) {
        char *slash = strrchr(out, '/');
        if (!slash) return -1;
        *slash = '\0';
    }
    size_t n = strlen(out);
    if (n + 11 >= size) return -1;
    memcpy(out + n, "/resources", 11);
    return 0;
}

/* file:// URI of a path, percent-encoding what is not unreserved or '/'. */
static void file_uri(const char *path, char *out, size_t size) {
    size_t j = (size_t)snprintf(out, size, "file://");
    for (const unsigned char *p = (const unsigned char *)path; *p && j + 4 < size; p++) {
        if ((*p >= 'a' && *p <= 'z') || (*p >= 'A' && *p <= 'Z') || (*p >= '0' && *p <= '9') ||
            strchr("/-._~", *p))
            out[j++] = (char)*p;
        else
            j += (size_t)snprintf(out + j, size - j, "%%%02X", *p);
    }
    out[j] = '\0';
}

static void *instantiate(struct container *x, size_t i) {
    const struct part *c = &x->plan.components[i];
    struct fmu *f = &x->core.fmus[i];
    char resources[2 * TEXT], uri[6 * TEXT];
    snprintf(resources, sizeof resources, "%s/fmus/%s/resources%s", x->resources, c->folder,
             c->version == 3 ? "/" : "");
    if (c->version == 3) {
        x->relays[i] = (struct relay3){x, c->name};
        return f->instantiate3(c->name, c->guid, resources, fmi3False, x->logging != 0, fmi3False, fmi3False, NULL,
                               0, &x->relays[i], relay3, NULL);
    }
    file_uri(resources, uri, sizeof uri);
    return f->instantiate2(c->name, fmi2CoSimulation, c->guid, uri, &x->inner, fmi2False, x->logging);
}

static int load_component(struct container *x, size_t i, char *why, size_t size) {
    const struct part *c = &x->plan.components[i];
    char path[2 * TEXT], reason[TEXT];
    snprintf(path, sizeof path, "%s/fmus/%s/binaries/%s/%s.so", x->resources, c->folder,
             c->version == 3 ? "x86_64-linux" : "linux64", c->identifier);
    x->libraries[i] = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!x->libraries[i]) {
        snprintf(why, size, "%s: cannot load %s: %s", c->name, path, dlerror());
        return -1;
    }
    if (fmu_bind(&x->core.fmus[i], x->libraries[i], c->version, 1, reason, sizeof reason) != 0) {
        snprintf(why, size, "%s: %s: %s", c->name, path, reason);
        return -1;
    }
    x->core.fmus[i].instance = instantiate(x, i);
    if (!x->core.fmus[i].instance) {
        snprintf(why, size, "%s: %s returned NULL", c->name, fmu_function(c->version, INSTANTIATE));
        return -1;
    }
    return 0;
}

static void release(struct container *x) {
    for (size_t i = x->plan.ncomponents; x->core.fmus && i-- > 0;) {
        fmu_free(&x->core.fmus[i]);
        /* The library stays loaded (no dlclose): the next container instance finds it, and the
           project's FMUs then reuse their pythonfmu components (see the shim's "Pool"), whose
           construction leaks in pythonfmu; unloaded, 80 KB per instantiate/free cycle were lost. */
    }
    plan_free(&x->plan);
    free(x->core.fmus);
    free(x->libraries);
    free(x->relays);
    free(x->values);
    free(x->input_set);
    free(x);
}

/* ---- the host's inputs ----------------------------------------------------------------------- */

/* The host's inputs set so far, passed on (after the start values, which they override). */
static fmi2Status apply_inputs(struct container *x, double t) {
    for (size_t j = 0; j < x->plan.nexposed; j++) {
        struct exposed *e = &x->plan.exposed[j];
        if (e->kind != 'i' || !x->input_set[j]) continue;
        if (core_set_input(&x->core, e->component, e->inner, &x->values[e->slot], t)) return failed(x);
    }
    return fmi2OK;
}

static fmi2Status propagate(struct container *x, double t) {
    fmi2Status s = CORE(x, core_propagate(&x->core, t));
    if (s == fmi2OK) x->dirty = 0;
    return s;
}

/* ---- FMI 2.0 functions ----------------------------------------------------------------------- */

#define CONTAINER(c, allowed)                                                                                \
    struct container *x = (c);                                                                               \
    if (!x) return fmi2Error;                                                                                \
    if (x->state == FAILED && strcmp(__func__, "fmi2Reset") != 0) {                                         \
        say(x, fmi2Error, "%s: called after a failure (only fmi2Reset and fmi2FreeInstance are allowed)",    \
            __func__);                                                                                       \
        return fmi2Error;                                                                                    \
    }                                                                                                        \
    if (!((allowed) & (1 << x->state))) {                                                                    \
        say(x, fmi2Error, "%s: not allowed in this state", __func__);                                        \
        return fmi2Error;                                                                                    \
    }

#define ANY (1 << INSTANTIATED | 1 << INITIALIZATION | 1 << STEPPING | 1 << TERMINATED)
#define ANY_OR_FAILED (ANY | 1 << FAILED)

EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }

EXPORT const char *fmi2GetVersion(void) { return "2.0"; }

/* The plan read and the value buffer made as it lays it out; -1 after one message. */
static int read_own_plan(struct container *x, const char *function) {
    char why[2 * TEXT], path[TEXT + 32];
    snprintf(path, sizeof path, "%s/container.plan", x->resources);
    if (plan_load(path, &x->plan, why, sizeof why) != 0) {
        say(x, fmi2Error, "%s: %s", function, why);
        return -1;
    }
    x->core.plan = &x->plan;
    size_t n = x->plan.ncomponents ? x->plan.ncomponents : 1;
    x->core.fmus = calloc(n, sizeof *x->core.fmus);
    x->libraries = calloc(n, sizeof *x->libraries);
    x->relays = calloc(n, sizeof *x->relays);
    x->values = calloc(x->plan.nvalues, sizeof *x->values);
    x->input_set = calloc(x->plan.nexposed ? x->plan.nexposed : 1, sizeof *x->input_set);
    if (!x->core.fmus || !x->libraries || !x->relays || !x->values || !x->input_set) {
        say(x, fmi2Error, "%s: out of memory", function);
        return -1;
    }
    memcpy(x->values, x->plan.initial, x->plan.nvalues * sizeof *x->values);
    x->core.values = x->values;
    return 0;
}

/* A new container: the plan read, every FMU loaded and instantiated; NULL after one message. `x` comes
   with its name, logging and host callbacks set; `function` names the host's call in messages. */
static struct container *create(struct container *x, const char *function, const char *token) {
    x->inner.logger = relay;
    if (!x->inner.allocateMemory) x->inner.allocateMemory = calloc;
    if (!x->inner.freeMemory) x->inner.freeMemory = free;
    x->inner.componentEnvironment = x;
    char why[2 * TEXT];
    if (own_resources(x->resources, sizeof x->resources) != 0) {
        say(x, fmi2Error, "%s: cannot find the container's own file (dladdr failed)", function);
        free(x);
        return NULL;
    }
    if (read_own_plan(x, function) != 0) {
        release(x);
        return NULL;
    }
    if (!token || strcmp(token, x->plan.guid) != 0) {
        say(x, fmi2Error, "%s: GUID %s does not match the container's %s", function, token ? token : "(NULL)",
            x->plan.guid);
        release(x);
        return NULL;
    }
    for (size_t i = 0; i < x->plan.ncomponents; i++) {
        if (load_component(x, i, why, sizeof why) != 0) {
            say(x, fmi2Error, "%s: %s", function, why);
            release(x);
            return NULL;
        }
    }
    x->state = INSTANTIATED;
    x->dirty = 1;
    return x;
}

EXPORT fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                                     fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                                     fmi2Boolean visible, fmi2Boolean loggingOn) {
    (void)fmuResourceLocation, (void)visible;
    struct container *x = calloc(1, sizeof *x);
    if (!x) return NULL;
    snprintf(x->name, sizeof x->name, "%s", instanceName ? instanceName : "container");
    if (functions) x->host = *functions;
    x->logging = loggingOn;
    x->inner.allocateMemory = functions ? functions->allocateMemory : NULL;
    x->inner.freeMemory = functions ? functions->freeMemory : NULL;
    if (fmuType != fmi2CoSimulation) {
        say(x, fmi2Error, "fmi2Instantiate: this FMU is Co-Simulation only");
        free(x);
        return NULL;
    }
    return create(x, "fmi2Instantiate", fmuGUID);
}

EXPORT void fmi2FreeInstance(fmi2Component c) {
    if (c) release(c);
}

EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String categories[]) {
    CONTAINER(c, ANY);
    x->logging = on;
    int worst = fmi2OK;
    for (size_t i = 0; i < x->plan.ncomponents; i++) {
        int s = fmu_set_debug_logging(&x->core.fmus[i], on, n, categories);
        if (s > worst) worst = s;
    }
    return worst > fmi2Warning ? fmi2Warning : (fmi2Status)worst;
}

EXPORT fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                                      fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    CONTAINER(c, 1 << INSTANTIATED);
    (void)toleranceDefined, (void)tolerance;
    double ns = startTime * 1e9;
    if (!(fabs(ns) < 9e18)) {
        say(x, fmi2Error, "fmi2SetupExperiment: start time %g s is not a finite time", startTime);
        return fmi2Error;
    }
    x->plan.t0 = llround(ns);
    x->stop_defined = stopTimeDefined;
    x->stop = stopTime;
    return fmi2OK;
}

EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    CONTAINER(c, 1 << INSTANTIATED);
    double t0 = plan_time(&x->plan, 0);
    fmi2Status s = CORE(x, core_enter_initialization(&x->core, t0, x->stop_defined, x->stop));
    if (s == fmi2OK) s = apply_inputs(x, t0);
    if (s != fmi2OK) return s;
    x->state = INITIALIZATION;
    x->dirty = 1;
    return fmi2OK;
}

EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    CONTAINER(c, 1 << INITIALIZATION);
    fmi2Status s = CORE(x, core_exit_initialization(&x->core, plan_time(&x->plan, 0)));
    if (s != fmi2OK) return s;
    x->dirty = 0;
    x->state = STEPPING;
    x->k = 0;
    return fmi2OK;
}

/* Whether the host's step [t, t + H] ends on the grid after the container's time; the target count. */
static int on_grid(const struct container *x, double t, double H, int64_t *target) {
    const struct plan *p = &x->plan;
    double now = (double)(p->t0 + p->h * x->k);
    double start = t * 1e9, end = (t + H) * 1e9;
    *target = llround((end - (double)p->t0) / (double)p->h);
    /* The host's time may be a sum of steps: within a thousandth of a step of the grid counts as on it. */
    double slack = 1e-3 * (double)p->h;
    return fabs(start - now) <= slack && fabs(end - (double)(p->t0 + p->h * *target)) <= slack && *target > x->k;
}

EXPORT fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                             fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    CONTAINER(c, 1 << STEPPING);
    (void)noSetFMUStatePriorToCurrentPoint;
    const struct plan *p = &x->plan;
    int64_t target;
    if (!on_grid(x, currentCommunicationPoint, communicationStepSize, &target)) {
        say(x, fmi2Error,
            "fmi2DoStep(t=%.17g s, h=%.17g s): the container steps on its scenario's grid t0 + k*%.9g s and is at "
            "t=%.17g s: the communication points must be on that grid and the step a positive multiple of %.9g s",
            currentCommunicationPoint, communicationStepSize, (double)p->h / 1e9, plan_time(p, x->k),
            (double)p->h / 1e9);
        return fmi2Error;
    }
    if (!p->jacobi && x->dirty) { /* an input set since the last propagation feeds other inputs */
        fmi2Status s = propagate(x, plan_time(p, x->k));
        if (s != fmi2OK) return s;
    }
    for (; x->k < target; x->k++)
        if (core_step(&x->core, x->k, NULL)) return failed(x);
    x->dirty = 0;
    return fmi2OK;
}

static struct exposed *find(struct container *x, fmi2ValueReference vr, char type) {
    for (size_t j = 0; j < x->plan.nexposed; j++)
        if (x->plan.exposed[j].vr == vr && x->plan.exposed[j].type == type) return &x->plan.exposed[j];
    return NULL;
}

EXPORT fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real value[]) {
    CONTAINER(c, ANY);
    if (!x->plan.jacobi && x->dirty && (x->state == INITIALIZATION || x->state == STEPPING)) {
        fmi2Status s = propagate(x, plan_time(&x->plan, x->k));
        if (s != fmi2OK) return s;
    }
    for (size_t j = 0; j < n; j++) {
        struct exposed *e = find(x, vr[j], 'r');
        if (!e) {
            say(x, fmi2Error, "fmi2GetReal: no Real variable with value reference %u", vr[j]);
            return fmi2Error;
        }
        value[j] = e->kind == 'p' ? x->plan.starts[e->call].reals[e->position] : x->values[e->slot];
    }
    return fmi2OK;
}

EXPORT fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real value[]) {
    CONTAINER(c, ANY);
    for (size_t j = 0; j < n; j++) {
        struct exposed *e = find(x, vr[j], 'r');
        if (!e || e->kind == 'o' || (e->kind == 'p' && x->state != INSTANTIATED && x->state != INITIALIZATION)) {
            say(x, fmi2Error, "fmi2SetReal: value reference %u is not a Real input or a parameter that can be "
                "set now", vr[j]);
            return fmi2Error;
        }
        if (e->kind == 'p') {
            x->plan.starts[e->call].reals[e->position] = value[j];
            continue;
        }
        x->values[e->slot] = value[j];
        x->input_set[e - x->plan.exposed] = 1;
        x->dirty |= e->feedthrough;
        if ((x->state == INITIALIZATION || x->state == STEPPING) &&
            core_set_input(&x->core, e->component, e->inner, &value[j], plan_time(&x->plan, x->k)))
            return failed(x);
    }
    return fmi2OK;
}

static fmi2Status get_ints(struct container *x, const fmi2ValueReference vr[], size_t n, int value[], char type) {
    for (size_t j = 0; j < n; j++) {
        struct exposed *e = find(x, vr[j], type);
        if (!e) {
            say(x, fmi2Error, "no %s variable with value reference %u", type == 'i' ? "Integer" : "Boolean", vr[j]);
            return fmi2Error;
        }
        value[j] = x->plan.starts[e->call].ints[e->position];
    }
    return fmi2OK;
}

static fmi2Status set_ints(struct container *x, const fmi2ValueReference vr[], size_t n, const int value[],
                           char type) {
    for (size_t j = 0; j < n; j++) {
        struct exposed *e = find(x, vr[j], type);
        if (!e || (x->state != INSTANTIATED && x->state != INITIALIZATION)) {
            say(x, fmi2Error, "value reference %u is not an %s parameter that can be set now", vr[j],
                type == 'i' ? "Integer" : "Boolean");
            return fmi2Error;
        }
        x->plan.starts[e->call].ints[e->position] = value[j];
    }
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer value[]) {
    CONTAINER(c, ANY);
    return get_ints(x, vr, n, value, 'i');
}

EXPORT fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean value[]) {
    CONTAINER(c, ANY);
    return get_ints(x, vr, n, value, 'b');
}

EXPORT fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                 const fmi2Integer value[]) {
    CONTAINER(c, ANY);
    return set_ints(x, vr, n, value, 'i');
}

EXPORT fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                 const fmi2Boolean value[]) {
    CONTAINER(c, ANY);
    return set_ints(x, vr, n, value, 'b');
}

EXPORT fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String value[]) {
    CONTAINER(c, ANY);
    (void)vr, (void)value;
    if (!n) return fmi2OK;
    say(x, fmi2Error, "fmi2GetString: the container exposes no String variable");
    return fmi2Error;
}

EXPORT fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                const fmi2String value[]) {
    CONTAINER(c, ANY);
    (void)vr, (void)value;
    if (!n) return fmi2OK;
    say(x, fmi2Error, "fmi2SetString: the container exposes no String variable");
    return fmi2Error;
}

EXPORT fmi2Status fmi2Terminate(fmi2Component c) {
    CONTAINER(c, 1 << STEPPING | 1 << INITIALIZATION);
    fmi2Status s = CORE(x, core_terminate(&x->core, plan_time(&x->plan, x->k)));
    if (s == fmi2OK) x->state = TERMINATED;
    return s;
}

EXPORT fmi2Status fmi2Reset(fmi2Component c) {
    CONTAINER(c, ANY_OR_FAILED);
    double t = plan_time(&x->plan, x->k);
    for (size_t i = 0; i < x->plan.ncomponents; i++) {
        int status = fmu_reset(&x->core.fmus[i]);
        if (status >= fmi2Discard) {
            x->core.failure = (struct failure){(int)i, RESET, status, t};
            return failed(x);
        }
    }
    /* Start values as exported: the plan is read again. */
    char path[TEXT + 32], why[2 * TEXT];
    struct plan fresh;
    snprintf(path, sizeof path, "%s/container.plan", x->resources);
    if (plan_load(path, &fresh, why, sizeof why) != 0) {
        plan_free(&fresh);
        say(x, fmi2Error, "fmi2Reset: %s", why);
        x->state = FAILED;
        return fmi2Error;
    }
    plan_free(&x->plan);
    x->plan = fresh;
    memcpy(x->values, x->plan.initial, x->plan.nvalues * sizeof *x->values);
    memset(x->input_set, 0, (x->plan.nexposed ? x->plan.nexposed : 1) * sizeof *x->input_set);
    x->k = 0;
    x->dirty = 1;
    x->state = INSTANTIATED;
    return fmi2OK;
}

static fmi2Status unsupported(fmi2Component c, const char *function) {
    say(c, fmi2Error, "%s is not supported by the scenario container", function);
    return fmi2Error;
}

EXPORT fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state) {
    (void)state;
    return unsupported(c, "fmi2GetFMUstate");
}
EXPORT fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
    (void)state;
    return unsupported(c, "fmi2SetFMUstate");
}
EXPORT fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    (void)state;
    return unsupported(c, "fmi2FreeFMUstate");
}
EXPORT fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size) {
    (void)state, (void)size;
    return unsupported(c, "fmi2SerializedFMUstateSize");
}
EXPORT fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte bytes[], size_t size) {
    (void)state, (void)bytes, (void)size;
    return unsupported(c, "fmi2SerializeFMUstate");
}
EXPORT fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size,
                                          fmi2FMUstate *state) {
    (void)bytes, (void)size, (void)state;
    return unsupported(c, "fmi2DeSerializeFMUstate");
}
EXPORT fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference unknown[],
                                               size_t nUnknown, const fmi2ValueReference known[], size_t nKnown,
                                               const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    (void)unknown, (void)nUnknown, (void)known, (void)nKnown, (void)dvKnown, (void)dvUnknown;
    return unsupported(c, "fmi2GetDirectionalDerivative");
}
EXPORT fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                              const fmi2Integer order[], const fmi2Real value[]) {
    (void)vr, (void)n, (void)order, (void)value;
    return unsupported(c, "fmi2SetRealInputDerivatives");
}
EXPORT fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                               const fmi2Integer order[], fmi2Real value[]) {
    (void)vr, (void)n, (void)order, (void)value;
    return unsupported(c, "fmi2GetRealOutputDerivatives");
}
EXPORT fmi2Status fmi2CancelStep(fmi2Component c) { return unsupported(c, "fmi2CancelStep"); }

EXPORT fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    (void)s, (void)value;
    return unsupported(c, "fmi2GetStatus");
}
EXPORT fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    struct container *x = c;
    if (x && s == fmi2LastSuccessfulTime && value) {
        *value = plan_time(&x->plan, x->k);
        return fmi2OK;
    }
    return unsupported(c, "fmi2GetRealStatus");
}
EXPORT fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    (void)s, (void)value;
    return unsupported(c, "fmi2GetIntegerStatus");
}
EXPORT fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    struct container *x = c;
    if (x && s == fmi2Terminated && value) {
        *value = 0;
        return fmi2OK;
    }
    return unsupported(c, "fmi2GetBooleanStatus");
}
EXPORT fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)s, (void)value;
    return unsupported(c, "fmi2GetStringStatus");
}

/* ---- FMI 3.0 ------------------------------------------------------------------------------------

   The same container behind the FMI 3.0 Co-Simulation API (an FMU exported with --fmi 3 declares
   fmiVersion 3.0; the FMUs inside are FMI 2.0 or 3.0 as the scenario has them): each function maps
   onto its FMI 2.0 counterpart above (fmi3EnterInitializationMode = fmi2SetupExperiment +
   fmi2EnterInitializationMode, Float64 = Real, Int32 = Integer), scalar variables only, no event
   mode. Compiled against the official FMI 3.0 headers (fmi/), so every signature is the standard's. */

static fmi3Status unsupported3(fmi3Instance instance, const char *function) {
    say(instance, fmi2Error, "%s is not supported by the scenario container", function);
    return fmi3Error;
}

FMI3_Export const char *fmi3GetVersion(void) { return fmi3Version; }

FMI3_Export fmi3Instance fmi3InstantiateCoSimulation(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath, fmi3Boolean visible,
    fmi3Boolean loggingOn, fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
    const fmi3ValueReference requiredIntermediateVariables[], size_t nRequiredIntermediateVariables,
    fmi3InstanceEnvironment instanceEnvironment, fmi3LogMessageCallback logMessage,
    fmi3IntermediateUpdateCallback intermediateUpdate) {
    (void)resourcePath, (void)visible, (void)eventModeUsed, (void)earlyReturnAllowed;
    (void)requiredIntermediateVariables, (void)nRequiredIntermediateVariables, (void)intermediateUpdate;
    struct container *x = calloc(1, sizeof *x);
    if (!x) return NULL;
    snprintf(x->name, sizeof x->name, "%s", instanceName ? instanceName : "container");
    x->logging = loggingOn;
    x->log3 = (void (*)(void *, int, const char *, const char *))logMessage;
    x->env3 = instanceEnvironment;
    return create(x, "fmi3InstantiateCoSimulation", instantiationToken);
}

FMI3_Export fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                                      fmi3String resourcePath, fmi3Boolean visible,
                                                      fmi3Boolean loggingOn,
                                                      fmi3InstanceEnvironment instanceEnvironment,
                                                      fmi3LogMessageCallback logMessage) {
    (void)instanceName, (void)instantiationToken, (void)resourcePath, (void)visible, (void)loggingOn;
    if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError", "Co-Simulation only");
    return NULL;
}

FMI3_Export fmi3Instance fmi3InstantiateScheduledExecution(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath, fmi3Boolean visible,
    fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment, fmi3LogMessageCallback logMessage,
    fmi3ClockUpdateCallback clockUpdate, fmi3LockPreemptionCallback lockPreemption,
    fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instanceName, (void)instantiationToken, (void)resourcePath, (void)visible, (void)loggingOn;
    (void)clockUpdate, (void)lockPreemption, (void)unlockPreemption;
    if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError", "Co-Simulation only");
    return NULL;
}

FMI3_Export void fmi3FreeInstance(fmi3Instance instance) { fmi2FreeInstance(instance); }

FMI3_Export fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                                           const fmi3String categories[]) {
    return (fmi3Status)fmi2SetDebugLogging(instance, loggingOn, nCategories, categories);
}

FMI3_Export fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
                                                   fmi3Float64 tolerance, fmi3Float64 startTime,
                                                   fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    fmi2Status s =
        fmi2SetupExperiment(instance, toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime);
    return (fmi3Status)(s == fmi2OK ? fmi2EnterInitializationMode(instance) : s);
}

FMI3_Export fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    return (fmi3Status)fmi2ExitInitializationMode(instance);
}

FMI3_Export fmi3Status fmi3Terminate(fmi3Instance instance) { return (fmi3Status)fmi2Terminate(instance); }

FMI3_Export fmi3Status fmi3Reset(fmi3Instance instance) { return (fmi3Status)fmi2Reset(instance); }

FMI3_Export fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                                  fmi3Float64 communicationStepSize,
                                  fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                  fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                                  fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    fmi2Status s = fmi2DoStep(instance, currentCommunicationPoint, communicationStepSize,
                              noSetFMUStatePriorToCurrentPoint);
    if (eventHandlingNeeded) *eventHandlingNeeded = fmi3False;
    if (terminateSimulation) *terminateSimulation = fmi3False;
    if (earlyReturn) *earlyReturn = fmi3False;
    if (lastSuccessfulTime && instance) {
        const struct container *x = instance;
        *lastSuccessfulTime = plan_time(&x->plan, x->k);
    }
    return (fmi3Status)s;
}

/* Scalar variables only: one value per value reference. */
static int scalars(fmi3Instance instance, size_t nValueReferences, size_t nValues) {
    if (nValues == nValueReferences) return 1;
    say(instance, fmi2Error, "the container's variables are scalars: %zu values for %zu value references",
        nValues, nValueReferences);
    return 0;
}

FMI3_Export fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                      size_t nValueReferences, fmi3Float64 values[], size_t nValues) {
    if (!scalars(instance, nValueReferences, nValues)) return fmi3Error;
    return (fmi3Status)fmi2GetReal(instance, valueReferences, nValueReferences, values);
}

FMI3_Export fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                      size_t nValueReferences, const fmi3Float64 values[], size_t nValues) {
    if (!scalars(instance, nValueReferences, nValues)) return fmi3Error;
    return (fmi3Status)fmi2SetReal(instance, valueReferences, nValueReferences, values);
}

FMI3_Export fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                    size_t nValueReferences, fmi3Int32 values[], size_t nValues) {
    if (!scalars(instance, nValueReferences, nValues)) return fmi3Error;
    return (fmi3Status)fmi2GetInteger(instance, valueReferences, nValueReferences, values);
}

FMI3_Export fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                    size_t nValueReferences, const fmi3Int32 values[], size_t nValues) {
    if (!scalars(instance, nValueReferences, nValues)) return fmi3Error;
    return (fmi3Status)fmi2SetInteger(instance, valueReferences, nValueReferences, values);
}

FMI3_Export fmi3Status fmi3GetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                      size_t nValueReferences, fmi3Boolean values[], size_t nValues) {
    if (!scalars(instance, nValueReferences, nValues)) return fmi3Error;
    for (size_t j = 0; j < nValueReferences; j++) {
        fmi2Boolean value;
        fmi2Status s = fmi2GetBoolean(instance, &valueReferences[j], 1, &value);
        if (s != fmi2OK) return (fmi3Status)s;
        values[j] = value != 0;
    }
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3SetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                      size_t nValueReferences, const fmi3Boolean values[], size_t nValues) {
    if (!scalars(instance, nValueReferences, nValues)) return fmi3Error;
    for (size_t j = 0; j < nValueReferences; j++) {
        fmi2Boolean value = values[j] ? 1 : 0;
        fmi2Status s = fmi2SetBoolean(instance, &valueReferences[j], 1, &value);
        if (s != fmi2OK) return (fmi3Status)s;
    }
    return fmi3OK;
}

/* Everything else of the FMI 3.0 API (Model Exchange, Scheduled Execution, clocks, event mode,
   other types, states, derivatives): one message and fmi3Error. */
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-parameter"
#define UNSUPPORTED(name, params)                                                                             \
    FMI3_Export fmi3Status name params { return unsupported3(instance, #name); }
UNSUPPORTED(fmi3EnterEventMode, (fmi3Instance instance))
UNSUPPORTED(fmi3GetFloat32, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3Float32 values[], size_t nValues))
UNSUPPORTED(fmi3GetInt8, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3Int8 values[], size_t nValues))
UNSUPPORTED(fmi3GetUInt8, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3UInt8 values[], size_t nValues))
UNSUPPORTED(fmi3GetInt16, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3Int16 values[], size_t nValues))
UNSUPPORTED(fmi3GetUInt16, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3UInt16 values[], size_t nValues))
UNSUPPORTED(fmi3GetUInt32, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3UInt32 values[], size_t nValues))
UNSUPPORTED(fmi3GetInt64, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3Int64 values[], size_t nValues))
UNSUPPORTED(fmi3GetUInt64, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3UInt64 values[], size_t nValues))
UNSUPPORTED(fmi3GetString, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3String values[], size_t nValues))
UNSUPPORTED(fmi3GetBinary, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, size_t valueSizes[], fmi3Binary values[], size_t nValues))
UNSUPPORTED(fmi3GetClock, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3Clock values[]))
UNSUPPORTED(fmi3SetFloat32, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3Float32 values[], size_t nValues))
UNSUPPORTED(fmi3SetInt8, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3Int8 values[], size_t nValues))
UNSUPPORTED(fmi3SetUInt8, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3UInt8 values[], size_t nValues))
UNSUPPORTED(fmi3SetInt16, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3Int16 values[], size_t nValues))
UNSUPPORTED(fmi3SetUInt16, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3UInt16 values[], size_t nValues))
UNSUPPORTED(fmi3SetUInt32, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3UInt32 values[], size_t nValues))
UNSUPPORTED(fmi3SetInt64, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3Int64 values[], size_t nValues))
UNSUPPORTED(fmi3SetUInt64, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3UInt64 values[], size_t nValues))
UNSUPPORTED(fmi3SetString, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3String values[], size_t nValues))
UNSUPPORTED(fmi3SetBinary, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const size_t valueSizes[], const fmi3Binary values[], size_t nValues))
UNSUPPORTED(fmi3SetClock, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3Clock values[]))
UNSUPPORTED(fmi3GetNumberOfVariableDependencies, (fmi3Instance instance, fmi3ValueReference valueReference,
            size_t* nDependencies))
UNSUPPORTED(fmi3GetVariableDependencies, (fmi3Instance instance, fmi3ValueReference dependent,
            size_t elementIndicesOfDependent[], fmi3ValueReference independents[],
            size_t elementIndicesOfIndependents[], fmi3DependencyKind dependencyKinds[],
            size_t nDependencies))
UNSUPPORTED(fmi3GetFMUState, (fmi3Instance instance, fmi3FMUState* FMUState))
UNSUPPORTED(fmi3SetFMUState, (fmi3Instance instance, fmi3FMUState FMUState))
UNSUPPORTED(fmi3FreeFMUState, (fmi3Instance instance, fmi3FMUState* FMUState))
UNSUPPORTED(fmi3SerializedFMUStateSize, (fmi3Instance instance, fmi3FMUState FMUState, size_t* size))
UNSUPPORTED(fmi3SerializeFMUState, (fmi3Instance instance, fmi3FMUState FMUState, fmi3Byte serializedState[],
            size_t size))
UNSUPPORTED(fmi3DeserializeFMUState, (fmi3Instance instance, const fmi3Byte serializedState[], size_t size,
            fmi3FMUState* FMUState))
UNSUPPORTED(fmi3GetDirectionalDerivative, (fmi3Instance instance, const fmi3ValueReference unknowns[],
            size_t nUnknowns, const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
            size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity))
UNSUPPORTED(fmi3GetAdjointDerivative, (fmi3Instance instance, const fmi3ValueReference unknowns[],
            size_t nUnknowns, const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
            size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity))
UNSUPPORTED(fmi3EnterConfigurationMode, (fmi3Instance instance))
UNSUPPORTED(fmi3ExitConfigurationMode, (fmi3Instance instance))
UNSUPPORTED(fmi3GetIntervalDecimal, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[]))
UNSUPPORTED(fmi3GetIntervalFraction, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[],
            fmi3IntervalQualifier qualifiers[]))
UNSUPPORTED(fmi3GetShiftDecimal, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3Float64 shifts[]))
UNSUPPORTED(fmi3GetShiftFraction, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[]))
UNSUPPORTED(fmi3SetIntervalDecimal, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3Float64 intervals[]))
UNSUPPORTED(fmi3SetIntervalFraction, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]))
UNSUPPORTED(fmi3SetShiftDecimal, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3Float64 shifts[]))
UNSUPPORTED(fmi3SetShiftFraction, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]))
UNSUPPORTED(fmi3EvaluateDiscreteStates, (fmi3Instance instance))
UNSUPPORTED(fmi3UpdateDiscreteStates, (fmi3Instance instance, fmi3Boolean* discreteStatesNeedUpdate,
            fmi3Boolean* terminateSimulation, fmi3Boolean* nominalsOfContinuousStatesChanged,
            fmi3Boolean* valuesOfContinuousStatesChanged, fmi3Boolean* nextEventTimeDefined,
            fmi3Float64* nextEventTime))
UNSUPPORTED(fmi3EnterContinuousTimeMode, (fmi3Instance instance))
UNSUPPORTED(fmi3CompletedIntegratorStep, (fmi3Instance instance,
            fmi3Boolean noSetFMUStatePriorToCurrentPoint, fmi3Boolean* enterEventMode,
            fmi3Boolean* terminateSimulation))
UNSUPPORTED(fmi3SetTime, (fmi3Instance instance, fmi3Float64 time))
UNSUPPORTED(fmi3SetContinuousStates, (fmi3Instance instance, const fmi3Float64 continuousStates[],
            size_t nContinuousStates))
UNSUPPORTED(fmi3GetContinuousStateDerivatives, (fmi3Instance instance, fmi3Float64 derivatives[],
            size_t nContinuousStates))
UNSUPPORTED(fmi3GetEventIndicators, (fmi3Instance instance, fmi3Float64 eventIndicators[],
            size_t nEventIndicators))
UNSUPPORTED(fmi3GetContinuousStates, (fmi3Instance instance, fmi3Float64 continuousStates[],
            size_t nContinuousStates))
UNSUPPORTED(fmi3GetNominalsOfContinuousStates, (fmi3Instance instance, fmi3Float64 nominals[],
            size_t nContinuousStates))
UNSUPPORTED(fmi3GetNumberOfEventIndicators, (fmi3Instance instance, size_t* nEventIndicators))
UNSUPPORTED(fmi3GetNumberOfContinuousStates, (fmi3Instance instance, size_t* nContinuousStates))
UNSUPPORTED(fmi3EnterStepMode, (fmi3Instance instance))
UNSUPPORTED(fmi3GetOutputDerivatives, (fmi3Instance instance, const fmi3ValueReference valueReferences[],
            size_t nValueReferences, const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues))
UNSUPPORTED(fmi3ActivateModelPartition, (fmi3Instance instance, fmi3ValueReference clockReference,
            fmi3Float64 activationTime))
#undef UNSUPPORTED
#pragma GCC diagnostic pop
