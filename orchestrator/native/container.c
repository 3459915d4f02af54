/* SPDX-License-Identifier: BSD-2-Clause */
/* FMI 2.0 and 3.0 Co-Simulation container: a whole SSP scenario as one FMU (`orchestrate export`).

   The container is this shared library, a plan (resources/container.plan) and the scenario's
   FMUs unpacked under resources/fmus/<folder>/. It carries no interpreter of its own: each
   embedded FMU (FMI 2.0 or 3.0 Co-Simulation) is loaded (platform.c) as any C host would load it,
   so the project's FMUs start their own bundled Python through their shim (one interpreter per
   process, whatever the number of FMUs) or use the host's.

   The plan is the engine's own (orchestrator/plan.py, read by plan.c): components, start values
   (SSD, SSV, --parameter-set, --set, units converted), the grid t_k = t0 + k h in integer
   nanoseconds, the value buffer and the master's operations, plus the container's variables. The
   core (core.c) replays it, making the same FMI calls with the same arguments in the same order as
   the engine's executors; container_fmi2.c and container_fmi3.c are the FMI APIs around it, this
   file what they share (loading, messages, the host's inputs):

   * fmi2Instantiate instantiates every FMU in the scenario's order;
   * fmi2EnterInitializationMode: per FMU start values, setup, initialization mode, start values
     again (core_enter_initialization); fmi2ExitInitializationMode: the master's initialization
     (core_exit_initialization);
   * fmi2DoStep(t, H) runs the internal steps from the container's own count k up to the grid point
     t + H, so H must be a whole number of the scenario's steps; the time passed to the FMUs is
     always (t0 + k h) / 1e9, never the host's sum. Inputs the host sets are passed on at once;
     with gauss-seidel, outputs that depend on them are propagated again before they are read;
   * an embedded FMU with periodic input clocks is instantiated with eventModeUsed; its clocks'
     intervals are asked in fmi2ExitInitializationMode before the master's initialization (a
     fixed clock's, core_ask_clocks), and the core ticks them inside fmi2DoStep: the host sees
     plain Co-Simulation. */

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "container.h"
#include "platform.h"

/* ---- messages -------------------------------------------------------------------------------- */

void say(struct container *x, fmi2Status status, const char *format, ...) {
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
fmi2Status failed(struct container *x) {
    const struct failure *f = &x->core.failure;
    const struct part *c = &x->plan.components[f->component];
    say(x, f->status >= fmi2Error ? (fmi2Status)f->status : fmi2Error, "%s: %s returned %s at t=%.3f s", c->name,
        fmu_function(c->version, f->function), fmu_status(c->version, f->status), f->time);
    x->state = FAILED;
    return f->status >= fmi2Fatal ? fmi2Fatal : fmi2Error;
}

/* The core's result as the container's status. */
/* ---- loading the embedded FMUs ------------------------------------------------------------- */

/* The embedded FMUs' binaries: this library's platform (FMI 2.0 name, FMI 3.0 tuple) and suffix. */
#ifdef _WIN32 /* cross-compiled with mingw-w64 */
#define PLATFORM2 "win64"
#define PLATFORM3 "x86_64-windows"
#define SUFFIX ".dll"
#else
#define PLATFORM2 "linux64"
#define PLATFORM3 "x86_64-linux"
#define SUFFIX ".so"
#endif

/* The container's resources folder: ../../resources from this library (binaries/<platform>/X.so). */
static int own_resources(char *out, size_t size) {
    if (ftc_library_file((const void *)&own_resources, out, size) != 0) return -1;
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

/* file:// URI of a path, percent-encoding what is not unreserved or '/' (Windows: C:/x is
   file:///C:/x, the drive's colon kept). */
static void file_uri(const char *path, char *out, size_t size) {
    size_t j = (size_t)snprintf(out, size, "file://%s", path[0] == '/' ? "" : "/");
    for (const unsigned char *p = (const unsigned char *)path; *p && j + 4 < size; p++) {
        if ((*p >= 'a' && *p <= 'z') || (*p >= 'A' && *p <= 'Z') || (*p >= '0' && *p <= '9') ||
            strchr("/-._~", *p) || (*p == ':' && p == (const unsigned char *)path + 1))
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
        return f->instantiate3(c->name, c->guid, resources, fmi3False, x->logging != 0, f->event_mode != 0,
                               fmi3False, NULL, 0, &x->relays[i], relay3, NULL);
    }
    file_uri(resources, uri, sizeof uri);
    return f->instantiate2(c->name, fmi2CoSimulation, c->guid, uri, &x->inner, fmi2False, x->logging);
}

#ifdef _WIN32
/* `fmus`, the container's resources/fmus (the embedded FMUs and the one runtime per platform they
   share, resources/fmus/_runtime), replaced by its copy in the user's cache (ftc_cached_copy: keyed
   by names and bytes, never rewritten), which the FMUs' libraries are loaded from: they stay
   loaded (see release), and a host must be able to delete the folder it unpacked once it has
   unloaded the container, as with any C FMU. The whole folder, not each FMU's binaries: an FMU's
   shim finds the shared runtime beside its own folder. The resource location given an FMU is still
   the unpacked one (the project's shim checks it and copies it to the cache in turn). No cache:
   the unpacked folder, as before. The container's folder does not change while it is loaded, so it
   is hashed once per load (about 50 ms per 10 MB), not at every instantiation. */
static struct {
    char *source, *copy;
} memo;
static ftc_mutex memo_lock = FTC_MUTEX_INIT;

static void cached_fmus(char *fmus, size_t size) {
    char cached[2 * TEXT];
    ftc_lock(&memo_lock);
    if (memo.copy && strcmp(memo.source, fmus) == 0) {
        snprintf(fmus, size, "%s", memo.copy);
    } else if (ftc_cached_copy(fmus, NULL, cached, sizeof cached) == 0) {
        free(memo.source);
        free(memo.copy);
        memo.source = strdup(fmus);
        memo.copy = memo.source ? strdup(cached) : NULL;
        snprintf(fmus, size, "%s", cached);
    }
    ftc_unlock(&memo_lock);
}
#endif

static int load_component(struct container *x, size_t i, char *why, size_t size) {
    const struct part *c = &x->plan.components[i];
    char fmus[2 * TEXT], path[3 * TEXT], reason[TEXT];
    snprintf(fmus, sizeof fmus, "%s/fmus", x->resources);
#ifdef _WIN32
    cached_fmus(fmus, sizeof fmus);
#endif
    snprintf(path, sizeof path, "%s/%s/binaries/%s/%s" SUFFIX, fmus, c->folder,
             c->version == 3 ? PLATFORM3 : PLATFORM2, c->identifier);
    x->libraries[i] = ftc_library_open(path, 0);
    if (!x->libraries[i]) {
        snprintf(why, size, "%s: cannot load %s: %s", c->name, path, ftc_library_error(path));
        return -1;
    }
    if (fmu_bind(&x->core.fmus[i], x->libraries[i], c->version, 1, reason, sizeof reason) != 0 ||
        (plan_clocked(&x->plan, (int)i) &&
         fmu_bind_clocks(&x->core.fmus[i], x->libraries[i], reason, sizeof reason) != 0)) {
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

void release(struct container *x) {
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
fmi2Status apply_inputs(struct container *x, double t) {
    for (size_t j = 0; j < x->plan.nexposed; j++) {
        struct exposed *e = &x->plan.exposed[j];
        if (e->kind != 'i' || !x->input_set[j]) continue;
        if (core_set_input(&x->core, e->component, e->inner, &x->values[e->slot], t)) return failed(x);
    }
    return fmi2OK;
}

fmi2Status propagate(struct container *x, double t) {
    fmi2Status s = CORE(x, core_propagate(&x->core, t));
    if (s == fmi2OK) x->dirty = 0;
    return s;
}

/* The plan read and the value buffer made as it lays it out; -1 after one message. */
static int read_own_plan(struct container *x, const char *function) {
    char why[2 * TEXT], path[TEXT + 32];
    snprintf(path, sizeof path, "%s/container.plan", x->resources);
    if (plan_load(path, &x->plan, why, sizeof why) != 0) {
        say(x, fmi2Error, "%s: %s", function, why);
        return -1;
    }
    x->core.plan = &x->plan;
    x->core.clocks = x->plan.clocks; /* those without an interval: asked in Initialization Mode */
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
struct container *create(struct container *x, const char *function, const char *token) {
    x->inner.logger = relay;
    if (!x->inner.allocateMemory) x->inner.allocateMemory = calloc;
    if (!x->inner.freeMemory) x->inner.freeMemory = free;
    x->inner.componentEnvironment = x;
    char why[2 * TEXT];
    if (own_resources(x->resources, sizeof x->resources) != 0) {
        say(x, fmi2Error, "%s: cannot find the container's own file (its loader does not say)", function);
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
