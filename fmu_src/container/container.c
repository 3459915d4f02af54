/* FMI 2.0 (and 3.0, at the end of this file) Co-Simulation container: a whole SSP scenario as one
   FMU (`orchestrate export`).

   The container is this shared library, a plan (resources/container.plan) and the scenario's
   FMUs unpacked under resources/fmus/<folder>/. It carries no interpreter of its own: each
   embedded FMU is loaded with dlopen as any C host would load it, so the project's FMUs start
   their own bundled Python through their shim (one interpreter per process, whatever the number
   of FMUs) or use the host's.

   The plan is everything the exporter (orchestrator/export/) computed from the engine's validated
   System: components, start values (SSD, SSV, --parameter-set, --set, units converted), the grid
   t_k = t0 + k h in integer nanoseconds, the value buffer laid out as the engine's master lays it
   out, and the master's operations. This file only replays them, making the same FMI calls with
   the same arguments in the same order as orchestrator/master.py:

   * instantiate every FMU in the scenario's order;
   * at fmi2EnterInitializationMode, per FMU: start values, fmi2SetupExperiment,
     fmi2EnterInitializationMode, start values again;
   * gauss-seidel: at fmi2ExitInitializationMode: propagate, exit every FMU, propagate; each step:
     every FMU's fmi2DoStep(t_k, t_k+1 - t_k), then propagate at t_k+1, where propagating runs the
     schedule's operations (read a component's outputs; transfer connections into some of its
     inputs, value = factor * source + offset, and write them);
   * jacobi: libcosim's algorithm (N sweeps of set, get, transfer in initialization mode; each
     step: set, step, get per FMU, then transfer all connections).

   A host's fmi2DoStep(t, H) runs the internal steps from the container's own count k up to the
   grid point t + H, so H must be a whole number of the scenario's steps; the time passed to the
   FMUs is always (t0 + k h) / 1e9, never the host's sum. Inputs the host sets are passed on at
   once; with gauss-seidel, outputs that depend on them are propagated again before they are read.

   Plan format: one record per line, space-separated tokens; reals as C99 hexadecimal floats
   (exact), strings percent-encoded. See orchestrator/export/plan.py, which writes it. */

#define _GNU_SOURCE
#include <dlfcn.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define EXPORT __attribute__((visibility("default")))
#define TEXT 4096
#define PLAN_VERSION "1"

#include "fmi2_types.h" /* the FMI 2.0 types, shared with the FMUs' shim */

static const char *STATUS[] = {"fmi2OK", "fmi2Warning", "fmi2Discard", "fmi2Error", "fmi2Fatal", "fmi2Pending"};

/* The functions of one embedded FMU the container calls. */
struct api {
    fmi2Component (*instantiate)(fmi2String, fmi2Type, fmi2String, fmi2String, const fmi2CallbackFunctions *,
                                 fmi2Boolean, fmi2Boolean);
    void (*free_instance)(fmi2Component);
    fmi2Status (*set_debug_logging)(fmi2Component, fmi2Boolean, size_t, const fmi2String[]);
    fmi2Status (*setup_experiment)(fmi2Component, fmi2Boolean, fmi2Real, fmi2Real, fmi2Boolean, fmi2Real);
    fmi2Status (*enter_initialization)(fmi2Component);
    fmi2Status (*exit_initialization)(fmi2Component);
    fmi2Status (*terminate)(fmi2Component);
    fmi2Status (*reset)(fmi2Component);
    fmi2Status (*get_real)(fmi2Component, const fmi2ValueReference[], size_t, fmi2Real[]);
    fmi2Status (*set_real)(fmi2Component, const fmi2ValueReference[], size_t, const fmi2Real[]);
    fmi2Status (*set_integer)(fmi2Component, const fmi2ValueReference[], size_t, const fmi2Integer[]);
    fmi2Status (*set_boolean)(fmi2Component, const fmi2ValueReference[], size_t, const fmi2Boolean[]);
    fmi2Status (*set_string)(fmi2Component, const fmi2ValueReference[], size_t, const fmi2String[]);
    fmi2Status (*do_step)(fmi2Component, fmi2Real, fmi2Real, fmi2Boolean);
};

/* One call setting start values of one type ('r', 'i', 'b', 's') on one component. */
struct starts {
    int component;
    char type;
    size_t n;
    fmi2ValueReference *vr;
    double *reals;    /* 'r' */
    int *ints;        /* 'i', 'b' */
    char **strings;   /* 's' */
};

/* A connection: values[dst] = values[src] (scaled == 0) or factor * values[src] + offset. */
struct transfer {
    int scaled;
    size_t dst, src;
    double factor, offset;
};

/* A batch of value references of one component and the buffer slots they read or write. */
struct batch {
    int component;
    size_t n;
    fmi2ValueReference *vr;
    size_t *slot;
    double *tmp;
};

/* One operation of the propagation: read a component's outputs (ntransfers == 0, is_set == 0), or
   transfer connections into some of its inputs and write them. */
struct operation {
    int is_set;
    struct batch io;
    size_t ntransfers;
    struct transfer *transfers;
};

/* An exposed variable: the host's value reference -> a buffer slot (outputs, inputs) and, for
   inputs, the component's input; for parameters, a start value (call, position). */
struct exposed {
    fmi2ValueReference vr;
    char kind;   /* 'o' output, 'i' input, 'p' parameter */
    char type;   /* 'r', 'i', 'b' */
    size_t slot; /* 'o', 'i' */
    int component;            /* 'i' */
    fmi2ValueReference inner; /* 'i' */
    int feedthrough;          /* 'i': some exposed output depends on it (gauss-seidel re-propagates) */
    size_t call, position;    /* 'p' */
};

struct component {
    char *name, *folder, *identifier, *guid;
    void *library;
    struct api f;
    fmi2Component c;
    int broken; /* returned fmi2Fatal: no further call */
};

struct plan {
    char guid[256];
    int jacobi;
    int64_t t0, h; /* nanoseconds */
    size_t nvalues;
    double *initial;
    size_t ncomponents, nstarts, noperations, nexposed, njacobi_transfers;
    struct component *components;
    struct starts *starts;
    struct operation *operations;
    struct batch *jacobi_in, *jacobi_out; /* per component */
    struct transfer *jacobi_transfers;
    struct exposed *exposed;
};

enum state { INSTANTIATED, INITIALIZATION, STEPPING, TERMINATED, FAILED };

struct container {
    struct plan plan;
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

/* The embedded FMUs' logger: their message, formatted, to the host's logger under the container's
   name (an embedded FMU's instance name is its component name, which the message starts with). */
static void relay(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status, fmi2String category,
                  fmi2String message, ...) {
    struct container *x = env;
    char text[TEXT], escaped[2 * TEXT + 300];
    va_list args;
    va_start(args, message);
    vsnprintf(text, sizeof text, message ? message : "", args);
    va_end(args);
    if (x && x->log3) {
        snprintf(escaped, sizeof escaped, "%s: %s", instance ? instance : "?", text);
        x->log3(x->env3, (int)status, category ? category : "logAll", escaped);
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
    x->host.logger(x->host.componentEnvironment, x->name, status, category ? category : "logAll", escaped);
}

/* A failed call of an embedded FMU: one line as `orchestrate run` reports it; the container's status. */
static fmi2Status failed(struct container *x, int i, const char *function, fmi2Status status, double t) {
    struct component *c = &x->plan.components[i];
    if (status >= fmi2Fatal) c->broken = 1;
    say(x, status >= fmi2Error ? status : fmi2Error, "%s: %s returned %s at t=%.3f s", c->name, function,
        STATUS[status <= fmi2Pending ? status : fmi2Error], t);
    x->state = FAILED;
    return status >= fmi2Fatal ? fmi2Fatal : fmi2Error;
}

#define CHECK(x, i, function, call, t)                                                                       \
    do {                                                                                                     \
        fmi2Status status_ = (call);                                                                         \
        if (status_ >= fmi2Discard) return failed((x), (i), (function), status_, (t));                       \
    } while (0)

/* ---- the plan -------------------------------------------------------------------------------- */

static void decode(char *s) { /* percent-decoding in place */
    char *out = s;
    for (char *p = s; *p; p++) {
        if (p[0] == '%' && p[1] && p[2]) {
            char hex[3] = {p[1], p[2], 0};
            *out++ = (char)strtol(hex, NULL, 16);
            p += 2;
        } else {
            *out++ = *p;
        }
    }
    *out = '\0';
}

struct reader {
    char *line;
    char *next;
    int number;
    int error;
};

static char *token(struct reader *r) {
    char *t = strtok_r(NULL, " \t", &r->next);
    if (!t) r->error = 1;
    return t ? t : "0";
}

static long long integer(struct reader *r) {
    char *end, *t = token(r);
    long long v = strtoll(t, &end, 10);
    if (*end) r->error = 1;
    return v;
}

static size_t count(struct reader *r, size_t limit) {
    long long v = integer(r);
    if (v < 0 || (size_t)v > limit) r->error = 1;
    return v < 0 || (size_t)v > limit ? 0 : (size_t)v;
}

static double real(struct reader *r) {
    char *end, *t = token(r);
    double v = strtod(t, &end);
    if (*end) r->error = 1;
    return v;
}

static char *text(struct reader *r) { /* "=" and the text, percent-encoded */
    char *word = token(r);
    if (word[0] != '=') r->error = 1;
    char *t = strdup(word[0] == '=' ? word + 1 : word);
    if (t) decode(t);
    else r->error = 1;
    return t;
}

static void *array(size_t n, size_t size, struct reader *r) {
    void *p = calloc(n ? n : 1, size);
    if (!p) r->error = 1;
    return p;
}

#define LIMIT 10000000

static void read_transfers(struct reader *r, struct plan *p, size_t n, struct transfer *t) {
    for (size_t j = 0; j < n && !r->error; j++) {
        t[j].scaled = (int)integer(r);
        t[j].dst = count(r, p->nvalues - 1);
        t[j].src = count(r, p->nvalues - 1);
        t[j].factor = real(r);
        t[j].offset = real(r);
    }
}

static void read_batch(struct reader *r, struct plan *p, struct batch *b) {
    b->component = (int)count(r, p->ncomponents - 1);
    b->n = count(r, LIMIT);
    b->vr = array(b->n, sizeof *b->vr, r);
    b->slot = array(b->n, sizeof *b->slot, r);
    b->tmp = array(b->n, sizeof *b->tmp, r);
    for (size_t j = 0; j < b->n && !r->error; j++) {
        b->vr[j] = (fmi2ValueReference)count(r, UINT32_MAX);
        b->slot[j] = count(r, p->nvalues - 1);
    }
}

/* Reads the plan; returns 0, or -1 with `why` filled. */
static int read_plan(const char *path, struct plan *p, char *why, size_t size) {
    FILE *file = fopen(path, "r");
    if (!file) {
        snprintf(why, size, "cannot open the container's plan %s", path);
        return -1;
    }
    memset(p, 0, sizeof *p);
    struct reader r = {0};
    char *line = NULL;
    size_t capacity = 0;
    size_t ci = 0, si = 0, oi = 0, ei = 0;
    while (!r.error && getline(&line, &capacity, file) >= 0) {
        r.number++;
        line[strcspn(line, "\r\n")] = '\0';
        char *kind = strtok_r(line, " \t", &r.next);
        if (!kind || kind[0] == '#') continue;
        if (!strcmp(kind, "container")) {
            if (strcmp(token(&r), PLAN_VERSION)) r.error = 1;
            char *guid = text(&r);
            snprintf(p->guid, sizeof p->guid, "%s", guid ? guid : "");
            free(guid);
        } else if (!strcmp(kind, "master")) {
            p->jacobi = !strcmp(token(&r), "jacobi");
        } else if (!strcmp(kind, "grid")) {
            p->t0 = integer(&r);
            p->h = integer(&r);
            if (p->h <= 0) r.error = 1;
        } else if (!strcmp(kind, "sizes")) { /* values components starts operations exposed */
            p->nvalues = count(&r, LIMIT) + 1;
            p->ncomponents = count(&r, 100000);
            p->nstarts = count(&r, LIMIT);
            p->noperations = count(&r, LIMIT);
            p->nexposed = count(&r, LIMIT);
            p->initial = array(p->nvalues, sizeof *p->initial, &r);
            p->components = array(p->ncomponents, sizeof *p->components, &r);
            p->starts = array(p->nstarts, sizeof *p->starts, &r);
            p->operations = array(p->noperations, sizeof *p->operations, &r);
            p->jacobi_in = array(p->ncomponents, sizeof *p->jacobi_in, &r);
            p->jacobi_out = array(p->ncomponents, sizeof *p->jacobi_out, &r);
            p->exposed = array(p->nexposed, sizeof *p->exposed, &r);
        } else if (!p->components) {
            r.error = 1; /* "sizes" comes first */
        } else if (!strcmp(kind, "value")) {
            size_t slot = count(&r, p->nvalues - 1);
            p->initial[slot] = real(&r);
        } else if (!strcmp(kind, "component") && ci < p->ncomponents) {
            struct component *c = &p->components[ci++];
            c->name = text(&r);
            c->folder = text(&r);
            c->identifier = text(&r);
            c->guid = text(&r);
        } else if (!strcmp(kind, "starts") && si < p->nstarts) {
            struct starts *s = &p->starts[si++];
            s->component = (int)count(&r, p->ncomponents - 1);
            s->type = token(&r)[0];
            s->n = count(&r, LIMIT);
            s->vr = array(s->n, sizeof *s->vr, &r);
            if (s->type == 'r') s->reals = array(s->n, sizeof *s->reals, &r);
            else if (s->type == 'i' || s->type == 'b') s->ints = array(s->n, sizeof *s->ints, &r);
            else if (s->type == 's') s->strings = array(s->n, sizeof *s->strings, &r);
            else r.error = 1;
            for (size_t j = 0; j < s->n && !r.error; j++) {
                s->vr[j] = (fmi2ValueReference)count(&r, UINT32_MAX);
                if (s->reals) s->reals[j] = real(&r);
                else if (s->ints) s->ints[j] = (int)integer(&r);
                else if (s->strings) s->strings[j] = text(&r);
            }
        } else if (!strcmp(kind, "get") && oi < p->noperations) {
            struct operation *o = &p->operations[oi++];
            read_batch(&r, p, &o->io);
        } else if (!strcmp(kind, "set") && oi < p->noperations) {
            struct operation *o = &p->operations[oi++];
            o->is_set = 1;
            read_batch(&r, p, &o->io);
            o->ntransfers = count(&r, LIMIT);
            o->transfers = array(o->ntransfers, sizeof *o->transfers, &r);
            read_transfers(&r, p, o->ntransfers, o->transfers);
        } else if (!strcmp(kind, "jacobi-in") || !strcmp(kind, "jacobi-out")) {
            struct batch b;
            read_batch(&r, p, &b);
            if (!r.error) (kind[7] == 'i' ? p->jacobi_in : p->jacobi_out)[b.component] = b;
        } else if (!strcmp(kind, "jacobi-transfers")) {
            p->njacobi_transfers = count(&r, LIMIT);
            p->jacobi_transfers = array(p->njacobi_transfers, sizeof *p->jacobi_transfers, &r);
            read_transfers(&r, p, p->njacobi_transfers, p->jacobi_transfers);
        } else if (!strcmp(kind, "exposed") && ei < p->nexposed) {
            struct exposed *e = &p->exposed[ei++];
            e->vr = (fmi2ValueReference)count(&r, UINT32_MAX);
            e->kind = token(&r)[0];
            e->type = token(&r)[0];
            if (e->kind == 'o') {
                e->slot = count(&r, p->nvalues - 1);
            } else if (e->kind == 'i') {
                e->slot = count(&r, p->nvalues - 1);
                e->component = (int)count(&r, p->ncomponents - 1);
                e->inner = (fmi2ValueReference)count(&r, UINT32_MAX);
                e->feedthrough = (int)integer(&r);
            } else if (e->kind == 'p') {
                e->call = count(&r, p->nstarts - 1);
                e->position = count(&r, LIMIT);
                if (e->call < p->nstarts && e->position >= p->starts[e->call].n) r.error = 1;
            } else {
                r.error = 1;
            }
        } else {
            r.error = 1;
        }
    }
    free(line);
    fclose(file);
    if (!r.error && (ci != p->ncomponents || si != p->nstarts || oi != p->noperations || ei != p->nexposed))
        r.error = 1, r.number++;
    if (r.error || !p->components) {
        snprintf(why, size, "%s: line %d is not a valid plan record (plan version " PLAN_VERSION ")", path,
                 r.number);
        return -1;
    }
    return 0;
}

static void free_batch(struct batch *b) {
    free(b->vr);
    free(b->slot);
    free(b->tmp);
}

static void free_plan(struct plan *p) {
    for (size_t i = 0; p->components && i < p->ncomponents; i++) {
        struct component *c = &p->components[i];
        free(c->name), free(c->folder), free(c->identifier), free(c->guid);
        if (p->jacobi_in) free_batch(&p->jacobi_in[i]);
        if (p->jacobi_out) free_batch(&p->jacobi_out[i]);
    }
    for (size_t i = 0; p->starts && i < p->nstarts; i++) {
        struct starts *s = &p->starts[i];
        for (size_t j = 0; s->strings && j < s->n; j++) free(s->strings[j]);
        free(s->vr), free(s->reals), free(s->ints), free(s->strings);
    }
    for (size_t i = 0; p->operations && i < p->noperations; i++) {
        free_batch(&p->operations[i].io);
        free(p->operations[i].transfers);
    }
    free(p->initial), free(p->components), free(p->starts), free(p->operations), free(p->jacobi_in);
    free(p->jacobi_out), free(p->jacobi_transfers), free(p->exposed);
    memset(p, 0, sizeof *p);
}

/* ---- loading the embedded FMUs ------------------------------------------------------------- */

/* The container's resources folder: ../../resources from this library (binaries/linux64/X.so). */
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

static int load_component(struct container *x, struct component *c, char *why, size_t size) {
    char path[2 * TEXT];
    snprintf(path, sizeof path, "%s/fmus/%s/binaries/linux64/%s.so", x->resources, c->folder, c->identifier);
    c->library = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!c->library) {
        snprintf(why, size, "%s: cannot load %s: %s", c->name, path, dlerror());
        return -1;
    }
    int ok = 1;
#define FIND(field, symbol) ok &= (*(void **)(&c->f.field) = dlsym(c->library, symbol)) != NULL
    FIND(instantiate, "fmi2Instantiate");
    FIND(free_instance, "fmi2FreeInstance");
    FIND(set_debug_logging, "fmi2SetDebugLogging");
    FIND(setup_experiment, "fmi2SetupExperiment");
    FIND(enter_initialization, "fmi2EnterInitializationMode");
    FIND(exit_initialization, "fmi2ExitInitializationMode");
    FIND(terminate, "fmi2Terminate");
    FIND(reset, "fmi2Reset");
    FIND(get_real, "fmi2GetReal");
    FIND(set_real, "fmi2SetReal");
    FIND(set_integer, "fmi2SetInteger");
    FIND(set_boolean, "fmi2SetBoolean");
    FIND(set_string, "fmi2SetString");
    FIND(do_step, "fmi2DoStep");
#undef FIND
    if (!ok) {
        snprintf(why, size, "%s: %s lacks an FMI 2.0 Co-Simulation function", c->name, path);
        return -1;
    }
    char resources[2 * TEXT], uri[6 * TEXT];
    snprintf(resources, sizeof resources, "%s/fmus/%s/resources", x->resources, c->folder);
    file_uri(resources, uri, sizeof uri);
    c->c = c->f.instantiate(c->name, fmi2CoSimulation, c->guid, uri, &x->inner, 0, x->logging);
    if (!c->c) {
        snprintf(why, size, "%s: fmi2Instantiate returned NULL", c->name);
        return -1;
    }
    return 0;
}

static void release(struct container *x) {
    for (size_t i = x->plan.ncomponents; i-- > 0;) {
        struct component *c = &x->plan.components[i];
        if (c->c && !c->broken) c->f.free_instance(c->c);
        c->c = NULL;
        /* The library stays loaded (no dlclose): the next container instance finds it, and the
           project's FMUs then reuse their pythonfmu components (see the shim's "Pool"), whose
           construction leaks in pythonfmu; unloaded, 80 KB per instantiate/free cycle were lost. */
        c->library = NULL;
    }
    free_plan(&x->plan);
    free(x->values);
    free(x->input_set);
    free(x);
}

/* ---- the master -------------------------------------------------------------------------------- */

static double grid_time(const struct container *x, int64_t k) {
    return (double)(x->plan.t0 + x->plan.h * k) / 1e9;
}

static void transfer(double *v, const struct transfer *t, size_t n) {
    for (size_t j = 0; j < n; j++)
        if (!t[j].scaled) v[t[j].dst] = v[t[j].src];
    for (size_t j = 0; j < n; j++)
        if (t[j].scaled) v[t[j].dst] = t[j].factor * v[t[j].src] + t[j].offset;
}

static fmi2Status get_batch(struct container *x, const struct batch *b, double t) {
    struct component *c = &x->plan.components[b->component];
    CHECK(x, b->component, "fmi2GetReal", c->f.get_real(c->c, b->vr, b->n, b->tmp), t);
    for (size_t j = 0; j < b->n; j++) x->values[b->slot[j]] = b->tmp[j];
    return fmi2OK;
}

static fmi2Status set_batch(struct container *x, const struct batch *b, double t) {
    struct component *c = &x->plan.components[b->component];
    for (size_t j = 0; j < b->n; j++) b->tmp[j] = x->values[b->slot[j]];
    CHECK(x, b->component, "fmi2SetReal", c->f.set_real(c->c, b->vr, b->n, b->tmp), t);
    return fmi2OK;
}

/* gauss-seidel at a communication point: the schedule's reads and writes in dependency order. */
static fmi2Status propagate(struct container *x, double t) {
    for (size_t j = 0; j < x->plan.noperations; j++) {
        const struct operation *o = &x->plan.operations[j];
        fmi2Status s;
        if (o->is_set) {
            transfer(x->values, o->transfers, o->ntransfers);
            s = set_batch(x, &o->io, t);
        } else {
            s = o->io.n ? get_batch(x, &o->io, t) : fmi2OK;
        }
        if (s != fmi2OK) return s;
    }
    x->dirty = 0;
    return fmi2OK;
}

static fmi2Status jacobi_write(struct container *x, size_t i, double t) {
    return x->plan.jacobi_in[i].n ? set_batch(x, &x->plan.jacobi_in[i], t) : fmi2OK;
}

static fmi2Status jacobi_read(struct container *x, size_t i, double t) {
    return x->plan.jacobi_out[i].n ? get_batch(x, &x->plan.jacobi_out[i], t) : fmi2OK;
}

static fmi2Status apply_starts(struct container *x, size_t i, double t) {
    struct component *c = &x->plan.components[i];
    for (size_t j = 0; j < x->plan.nstarts; j++) {
        struct starts *s = &x->plan.starts[j];
        if (s->component != (int)i) continue;
        switch (s->type) {
        case 'r': CHECK(x, (int)i, "fmi2SetReal", c->f.set_real(c->c, s->vr, s->n, s->reals), t); break;
        case 'i': CHECK(x, (int)i, "fmi2SetInteger", c->f.set_integer(c->c, s->vr, s->n, s->ints), t); break;
        case 'b': CHECK(x, (int)i, "fmi2SetBoolean", c->f.set_boolean(c->c, s->vr, s->n, s->ints), t); break;
        default:
            CHECK(x, (int)i, "fmi2SetString",
                  c->f.set_string(c->c, s->vr, s->n, (const fmi2String *)s->strings), t);
        }
    }
    return fmi2OK;
}

/* The host's inputs set so far, passed on (after the start values, which they override). */
static fmi2Status apply_inputs(struct container *x, double t) {
    for (size_t j = 0; j < x->plan.nexposed; j++) {
        struct exposed *e = &x->plan.exposed[j];
        if (e->kind != 'i' || !x->input_set[j]) continue;
        struct component *c = &x->plan.components[e->component];
        CHECK(x, e->component, "fmi2SetReal", c->f.set_real(c->c, &e->inner, 1, &x->values[e->slot]), t);
    }
    return fmi2OK;
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

/* A new container: the plan read, every FMU loaded and instantiated; NULL after one message. `x` comes
   with its name, logging and host callbacks set; `function` names the host's call in messages. */
static struct container *create(struct container *x, const char *function, const char *token) {
    x->inner.logger = relay;
    if (!x->inner.allocateMemory) x->inner.allocateMemory = calloc;
    if (!x->inner.freeMemory) x->inner.freeMemory = free;
    x->inner.componentEnvironment = x;
    char why[2 * TEXT], path[TEXT + 32];
    if (own_resources(x->resources, sizeof x->resources) != 0) {
        say(x, fmi2Error, "%s: cannot find the container's own file (dladdr failed)", function);
        free(x);
        return NULL;
    }
    snprintf(path, sizeof path, "%s/container.plan", x->resources);
    if (read_plan(path, &x->plan, why, sizeof why) != 0) {
        say(x, fmi2Error, "%s: %s", function, why);
        free_plan(&x->plan);
        free(x);
        return NULL;
    }
    if (!token || strcmp(token, x->plan.guid) != 0) {
        say(x, fmi2Error, "%s: GUID %s does not match the container's %s", function, token ? token : "(NULL)",
            x->plan.guid);
        release(x);
        return NULL;
    }
    x->values = calloc(x->plan.nvalues, sizeof *x->values);
    x->input_set = calloc(x->plan.nexposed ? x->plan.nexposed : 1, sizeof *x->input_set);
    if (!x->values || !x->input_set) {
        release(x);
        return NULL;
    }
    memcpy(x->values, x->plan.initial, x->plan.nvalues * sizeof *x->values);
    for (size_t i = 0; i < x->plan.ncomponents; i++) {
        if (load_component(x, &x->plan.components[i], why, sizeof why) != 0) {
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
    fmi2Status worst = fmi2OK;
    for (size_t i = 0; i < x->plan.ncomponents; i++) {
        struct component *k = &x->plan.components[i];
        fmi2Status s = k->f.set_debug_logging(k->c, on, n, categories);
        if (s > worst) worst = s;
    }
    return worst > fmi2Warning ? fmi2Warning : worst;
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
    double t0 = grid_time(x, 0);
    x->values[0] = t0;
    for (size_t i = 0; i < x->plan.ncomponents; i++) {
        struct component *k = &x->plan.components[i];
        fmi2Status s = apply_starts(x, i, t0);
        if (s != fmi2OK) return s;
        CHECK(x, (int)i, "fmi2SetupExperiment",
              k->f.setup_experiment(k->c, 0, 0.0, t0, x->stop_defined, x->stop), t0);
        CHECK(x, (int)i, "fmi2EnterInitializationMode", k->f.enter_initialization(k->c), t0);
        s = apply_starts(x, i, t0);
        if (s != fmi2OK) return s;
    }
    fmi2Status s = apply_inputs(x, t0);
    if (s != fmi2OK) return s;
    x->state = INITIALIZATION;
    x->dirty = 1;
    return fmi2OK;
}

/* jacobi in initialization mode: N sweeps of (set, get) per FMU, then transfer all. */
static fmi2Status jacobi_sweeps(struct container *x, double t0) {
    for (size_t sweep = 0; sweep < x->plan.ncomponents; sweep++) {
        for (size_t i = 0; i < x->plan.ncomponents; i++) {
            fmi2Status s = sweep ? jacobi_write(x, i, t0) : fmi2OK;
            if (s == fmi2OK) s = jacobi_read(x, i, t0);
            if (s != fmi2OK) return s;
        }
        transfer(x->values, x->plan.jacobi_transfers, x->plan.njacobi_transfers);
    }
    x->dirty = 0;
    return fmi2OK;
}

EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    CONTAINER(c, 1 << INITIALIZATION);
    double t0 = grid_time(x, 0);
    fmi2Status s = x->plan.jacobi ? jacobi_sweeps(x, t0) : propagate(x, t0);
    if (s != fmi2OK) return s;
    for (size_t i = 0; i < x->plan.ncomponents; i++) {
        struct component *k = &x->plan.components[i];
        if (x->plan.jacobi && (s = jacobi_write(x, i, t0)) != fmi2OK) return s;
        CHECK(x, (int)i, "fmi2ExitInitializationMode", k->f.exit_initialization(k->c), t0);
        if (x->plan.jacobi && (s = jacobi_read(x, i, t0)) != fmi2OK) return s;
    }
    if (x->plan.jacobi) {
        transfer(x->values, x->plan.jacobi_transfers, x->plan.njacobi_transfers);
        x->dirty = 0;
    } else if ((s = propagate(x, t0)) != fmi2OK) {
        return s;
    }
    x->state = STEPPING;
    x->k = 0;
    return fmi2OK;
}

static fmi2Status one_step(struct container *x) {
    double t = grid_time(x, x->k), t_next = grid_time(x, x->k + 1), h = t_next - t;
    size_t n = x->plan.ncomponents;
    if (x->plan.jacobi) {
        for (size_t i = 0; i < n; i++) {
            struct component *k = &x->plan.components[i];
            struct batch *out = &x->plan.jacobi_out[i];
            fmi2Status s = jacobi_write(x, i, t);
            if (s != fmi2OK) return s;
            CHECK(x, (int)i, "fmi2DoStep", k->f.do_step(k->c, t, h, 1), t);
            CHECK(x, (int)i, "fmi2GetReal", k->f.get_real(k->c, out->vr, out->n, out->tmp), t);
            for (size_t j = 0; j < out->n; j++) x->values[out->slot[j]] = out->tmp[j];
        }
        x->values[0] = t_next;
        transfer(x->values, x->plan.jacobi_transfers, x->plan.njacobi_transfers);
        x->k++;
        return fmi2OK;
    }
    for (size_t i = 0; i < n; i++) {
        struct component *k = &x->plan.components[i];
        CHECK(x, (int)i, "fmi2DoStep", k->f.do_step(k->c, t, h, 1), t);
    }
    x->values[0] = t_next;
    x->k++;
    return propagate(x, t_next);
}

EXPORT fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                             fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    CONTAINER(c, 1 << STEPPING);
    (void)noSetFMUStatePriorToCurrentPoint;
    const struct plan *p = &x->plan;
    double now = (double)(p->t0 + p->h * x->k);
    double start = currentCommunicationPoint * 1e9, end = (currentCommunicationPoint + communicationStepSize) * 1e9;
    double steps = (end - (double)p->t0) / (double)p->h;
    int64_t target = llround(steps);
    /* The host's time may be a sum of steps: within a thousandth of a step of the grid counts as on it. */
    double slack = 1e-3 * (double)p->h;
    if (!(fabs(start - now) <= slack) || !(fabs(end - (double)(p->t0 + p->h * target)) <= slack) ||
        target <= x->k) {
        say(x, fmi2Error,
            "fmi2DoStep(t=%.17g s, h=%.17g s): the container steps on its scenario's grid t0 + k*%.9g s and is at "
            "t=%.17g s: the communication points must be on that grid and the step a positive multiple of %.9g s",
            currentCommunicationPoint, communicationStepSize, (double)p->h / 1e9, now / 1e9, (double)p->h / 1e9);
        return fmi2Error;
    }
    if (!p->jacobi && x->dirty) { /* an input set since the last propagation feeds other inputs */
        fmi2Status s = propagate(x, grid_time(x, x->k));
        if (s != fmi2OK) return s;
    }
    while (x->k < target) {
        fmi2Status s = one_step(x);
        if (s != fmi2OK) return s;
    }
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
        fmi2Status s = propagate(x, grid_time(x, x->k));
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
        if (x->state == INITIALIZATION || x->state == STEPPING) {
            struct component *k = &x->plan.components[e->component];
            CHECK(x, e->component, "fmi2SetReal", k->f.set_real(k->c, &e->inner, 1, &value[j]),
                  grid_time(x, x->k));
        }
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
    fmi2Status worst = fmi2OK;
    double t = grid_time(x, x->k);
    for (size_t i = 0; i < x->plan.ncomponents; i++) {
        struct component *k = &x->plan.components[i];
        fmi2Status s = k->f.terminate(k->c);
        if (s >= fmi2Discard) worst = failed(x, (int)i, "fmi2Terminate", s, t);
    }
    if (worst == fmi2OK) x->state = TERMINATED;
    return worst;
}

EXPORT fmi2Status fmi2Reset(fmi2Component c) {
    CONTAINER(c, ANY_OR_FAILED);
    for (size_t i = 0; i < x->plan.ncomponents; i++) {
        struct component *k = &x->plan.components[i];
        CHECK(x, (int)i, "fmi2Reset", k->f.reset(k->c), grid_time(x, x->k));
    }
    /* Start values as exported: the plan is read again. */
    char path[TEXT + 32], why[2 * TEXT];
    struct plan fresh;
    snprintf(path, sizeof path, "%s/container.plan", x->resources);
    if (read_plan(path, &fresh, why, sizeof why) != 0) {
        free_plan(&fresh);
        say(x, fmi2Error, "fmi2Reset: %s", why);
        x->state = FAILED;
        return fmi2Error;
    }
    for (size_t i = 0; i < fresh.ncomponents; i++) {
        fresh.components[i].library = x->plan.components[i].library;
        fresh.components[i].f = x->plan.components[i].f;
        fresh.components[i].c = x->plan.components[i].c;
        x->plan.components[i].library = NULL;
    }
    free_plan(&x->plan);
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
        *value = grid_time(x, x->k);
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
   fmiVersion 3.0; the FMUs inside stay FMI 2.0): each function maps onto its FMI 2.0 counterpart
   above (fmi3EnterInitializationMode = fmi2SetupExperiment + fmi2EnterInitializationMode,
   Float64 = Real, Int32 = Integer), scalar variables only, no event mode. Compiled against the
   FMI 3.0 headers FMPy ships (fmpy/c-code), so every signature is the standard's. */

#include "fmi3Functions.h"

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
        *lastSuccessfulTime = grid_time(x, x->k);
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
