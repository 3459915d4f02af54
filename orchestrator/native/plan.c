/* SPDX-License-Identifier: BSD-2-Clause */
/* The plan reader: the text orchestrator/plan.py writes (Plan.text), one record per line,
   space-separated tokens; reals as C99 hexadecimal floats (exact), strings "=" and percent-encoded.

     plan 4 =<guid>                       version and the container's GUID
     master gauss-seidel|jacobi
     grid <t0 ns> <h ns> <n steps>
     sizes <values> <components> <start calls> <propagation calls> <exposed variables>
     value <slot> <real>                  initial values (others 0)
     component =<name> =<folder> =<model identifier> =<guid> <FMI major version>
     starts <component> r|i|b|s <n> (<vr> <value>)*
     get|set <batch> <n> (<dst> <src> <factor> <offset>)*     the gauss-seidel propagation
     io <inputs batch> <outputs batch> <driven batch>         one per component, in order
     transfers <n> (<dst> <src> <factor> <offset>)*           every connection (jacobi)
     clocks <n> (<component> <vr> <interval ns> <shift ns>)*  periodic input clocks (FMI 3.0)
     exposed <vr> o|i|p ...                                   the container's variables

   A batch is <component> <first slot> <n> <integers among them, last> <vr>*. Every index is checked against the sizes, so a
   damaged plan is one message naming its line, never an access outside an array. */

#define _GNU_SOURCE
#include "plan.h"
#include "platform.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define LIMIT 10000000

struct reader {
    char *next;
    int number;
    int error;
    int header;                                    /* the "plan" record was read */
    size_t components, starts, calls, io, exposed; /* records of each kind read so far */
};

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

static size_t count(struct reader *r, size_t limit) { /* 0 .. limit */
    long long v = integer(r);
    if (v < 0 || (unsigned long long)v > limit) r->error = 1;
    return v < 0 || (unsigned long long)v > limit ? 0 : (size_t)v;
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

static void read_batch(struct reader *r, const struct plan *p, struct batch *b) {
    b->component = (int)count(r, p->ncomponents ? p->ncomponents - 1 : 0);
    b->start = count(r, p->nvalues);
    b->n = count(r, p->nvalues - b->start);
    b->ints = count(r, b->n);
    b->vr = array(b->n, sizeof *b->vr, r);
    for (size_t j = 0; j < b->n && !r->error; j++) b->vr[j] = (unsigned int)count(r, UINT32_MAX);
}

static struct transfer *read_transfers(struct reader *r, const struct plan *p, size_t *n) {
    *n = count(r, LIMIT);
    struct transfer *t = array(*n, sizeof *t, r);
    for (size_t j = 0; j < *n && !r->error; j++) {
        t[j].dst = count(r, p->nvalues - 1);
        t[j].src = count(r, p->nvalues - 1);
        t[j].factor = real(r);
        t[j].offset = real(r);
    }
    return t;
}

/* ---- one function per record ------------------------------------------------------------------ */

static void plan_record(struct reader *r, struct plan *p) {
    if (strcmp(token(r), PLAN_VERSION)) r->error = 1;
    r->header = 1;
    char *guid = text(r);
    snprintf(p->guid, sizeof p->guid, "%s", guid ? guid : "");
    free(guid);
}

static void master_record(struct reader *r, struct plan *p) {
    char *name = token(r);
    p->jacobi = !strcmp(name, "jacobi");
    if (!p->jacobi && strcmp(name, "gauss-seidel")) r->error = 1;
}

static void grid_record(struct reader *r, struct plan *p) {
    p->t0 = integer(r);
    p->h = integer(r);
    p->n = integer(r);
    if (p->h <= 0 || p->n < 0) r->error = 1;
}

static void sizes_record(struct reader *r, struct plan *p) {
    if (p->components) r->error = 1; /* once */
    p->nvalues = count(r, LIMIT);
    p->ncomponents = count(r, 100000);
    p->nstarts = count(r, LIMIT);
    p->ncalls = count(r, LIMIT);
    p->nexposed = count(r, LIMIT);
    if (!p->nvalues) r->error = 1; /* time, at least */
    p->initial = array(p->nvalues, sizeof *p->initial, r);
    p->components = array(p->ncomponents, sizeof *p->components, r);
    p->starts = array(p->nstarts, sizeof *p->starts, r);
    p->calls = array(p->ncalls, sizeof *p->calls, r);
    p->exposed = array(p->nexposed, sizeof *p->exposed, r);
}

static void value_record(struct reader *r, struct plan *p) {
    size_t slot = count(r, p->nvalues - 1);
    p->initial[slot] = real(r);
}

static void component_record(struct reader *r, struct plan *p) {
    if (r->components >= p->ncomponents) {
        r->error = 1;
        return;
    }
    struct part *c = &p->components[r->components++];
    c->name = text(r);
    c->folder = text(r);
    c->identifier = text(r);
    c->guid = text(r);
    c->version = (int)integer(r);
    if (c->version != 2 && c->version != 3) r->error = 1;
}

static void starts_record(struct reader *r, struct plan *p) {
    if (r->starts >= p->nstarts) {
        r->error = 1;
        return;
    }
    struct starts *s = &p->starts[r->starts++];
    s->component = (int)count(r, p->ncomponents - 1);
    s->type = token(r)[0];
    s->n = count(r, LIMIT);
    s->vr = array(s->n, sizeof *s->vr, r);
    if (s->type == 'r') s->reals = array(s->n, sizeof *s->reals, r);
    else if (s->type == 'i' || s->type == 'b') s->ints = array(s->n, sizeof *s->ints, r);
    else if (s->type == 's') s->strings = array(s->n, sizeof *s->strings, r);
    else r->error = 1;
    for (size_t j = 0; j < s->n && !r->error; j++) {
        s->vr[j] = (unsigned int)count(r, UINT32_MAX);
        if (s->reals) s->reals[j] = real(r);
        else if (s->ints) s->ints[j] = (int)integer(r);
        else if (s->strings) s->strings[j] = text(r);
    }
}

static void call_record(struct reader *r, struct plan *p, int is_set) {
    if (r->calls >= p->ncalls) {
        r->error = 1;
        return;
    }
    struct call *c = &p->calls[r->calls++];
    c->is_set = is_set;
    read_batch(r, p, &c->io);
    c->transfers = read_transfers(r, p, &c->ntransfers);
    if (!is_set && c->ntransfers) r->error = 1;
}

static void get_record(struct reader *r, struct plan *p) { call_record(r, p, 0); }

static void set_record(struct reader *r, struct plan *p) { call_record(r, p, 1); }

static void io_record(struct reader *r, struct plan *p) {
    if (r->io >= p->ncomponents) {
        r->error = 1;
        return;
    }
    struct part *c = &p->components[r->io];
    read_batch(r, p, &c->inputs);
    read_batch(r, p, &c->outputs);
    read_batch(r, p, &c->driven);
    int i = (int)r->io++;
    if (c->inputs.component != i || c->outputs.component != i || c->driven.component != i) r->error = 1;
    p->ndriven += c->driven.n;
}

static void transfers_record(struct reader *r, struct plan *p) {
    if (p->transfers) r->error = 1; /* once */
    p->transfers = read_transfers(r, p, &p->ntransfers);
}

static void clocks_record(struct reader *r, struct plan *p) {
    if (p->clocks) r->error = 1; /* once */
    p->nclocks = count(r, MAX_CLOCKS);
    p->clocks = array(p->nclocks, sizeof *p->clocks, r);
    for (size_t j = 0; j < p->nclocks && !r->error; j++) {
        struct clock *c = &p->clocks[j];
        c->component = (int)count(r, p->ncomponents - 1);
        c->vr = (unsigned int)count(r, UINT32_MAX);
        c->interval = integer(r);
        c->shift = integer(r);
        if (c->interval < 0 || c->shift < 0 || (j && c->component < p->clocks[j - 1].component)) r->error = 1;
    }
}

static void exposed_record(struct reader *r, struct plan *p) {
    if (r->exposed >= p->nexposed) {
        r->error = 1;
        return;
    }
    struct exposed *e = &p->exposed[r->exposed++];
    e->vr = (unsigned int)count(r, UINT32_MAX);
    e->kind = token(r)[0];
    e->type = token(r)[0];
    if (e->kind == 'o') {
        e->slot = count(r, p->nvalues - 1);
    } else if (e->kind == 'i') {
        e->slot = count(r, p->nvalues - 1);
        e->component = (int)count(r, p->ncomponents - 1);
        e->inner = (unsigned int)count(r, UINT32_MAX);
        e->feedthrough = (int)integer(r);
    } else if (e->kind == 'p') {
        e->call = count(r, p->nstarts - 1);
        e->position = count(r, LIMIT);
        if (e->call < p->nstarts && e->position >= p->starts[e->call].n) r->error = 1;
    } else {
        r->error = 1;
    }
}

struct kind {
    const char *name;
    void (*read)(struct reader *, struct plan *);
    int after_sizes; /* only once the sizes are known */
};

static const struct kind KINDS[] = {
    {"plan", plan_record, 0},           {"master", master_record, 0}, {"grid", grid_record, 0},
    {"sizes", sizes_record, 0},         {"value", value_record, 1},   {"component", component_record, 1},
    {"starts", starts_record, 1},       {"get", get_record, 1},       {"set", set_record, 1},
    {"io", io_record, 1},               {"transfers", transfers_record, 1},
    {"clocks", clocks_record, 1},       {"exposed", exposed_record, 1},
};

static void record(struct reader *r, struct plan *p, char *line) {
    line[strcspn(line, "\r\n")] = '\0';
    char *kind = strtok_r(line, " \t", &r->next);
    if (!kind || kind[0] == '#') return;
    for (size_t j = 0; j < sizeof KINDS / sizeof KINDS[0]; j++) {
        if (!strcmp(kind, KINDS[j].name)) {
            if (KINDS[j].after_sizes && !p->components) r->error = 1; /* "sizes" comes first */
            else KINDS[j].read(r, p);
            if (strtok_r(NULL, " \t", &r->next)) r->error = 1; /* nothing after the record */
            return;
        }
    }
    r->error = 1;
}

int plan_read(const char *text, const char *label, struct plan *p, char *why, size_t size) {
    memset(p, 0, sizeof *p);
    struct reader r = {0};
    char *copy = strdup(text ? text : "");
    if (!copy) {
        snprintf(why, size, "%s: out of memory", label);
        return -1;
    }
    /* line by line (strsep's splitting, which Windows' C runtime lacks) */
    for (char *line = copy, *end; line && !r.error; line = end ? end + 1 : NULL) {
        end = strchr(line, '\n');
        if (end) *end = '\0';
        r.number++;
        record(&r, p, line);
    }
    free(copy);
    int whole = r.components == p->ncomponents && r.starts == p->nstarts && r.calls == p->ncalls &&
                r.io == p->ncomponents && r.exposed == p->nexposed && p->transfers && p->clocks && r.header;
    if (!r.error && (!p->components || !whole)) r.error = 1, r.number++;
    if (r.error) {
        snprintf(why, size, "%s: line %d is not a valid plan record (plan version " PLAN_VERSION ")", label,
                 r.number);
        return -1;
    }
    return 0;
}

int plan_load(const char *path, struct plan *p, char *why, size_t size) {
    memset(p, 0, sizeof *p);
    FILE *file = ftc_fopen(path, "rb");
    char *text = NULL;
    size_t length = 0, capacity = 0;
    int ok = file != NULL;
    /* the whole file, NUL-terminated, in a buffer doubled as it fills (no open_memstream on Windows) */
    for (size_t n = 1; ok && n > 0; length += n) {
        if (length + 1 >= capacity) {
            char *grown = realloc(text, capacity = capacity ? 2 * capacity : 1 << 16);
            if (!grown) {
                ok = 0;
                break;
            }
            text = grown;
        }
        n = fread(text + length, 1, capacity - length - 1, file);
        if (n == 0 && ferror(file)) ok = 0;
    }
    if (text) text[length] = '\0';
    if (file) fclose(file);
    if (!ok || !text) {
        free(text);
        snprintf(why, size, "cannot read the container's plan %s", path);
        return -1;
    }
    int result = plan_read(text, path, p, why, size);
    free(text);
    return result;
}

static void free_batch(struct batch *b) { free(b->vr); }

void plan_free(struct plan *p) {
    for (size_t i = 0; p->components && i < p->ncomponents; i++) {
        struct part *c = &p->components[i];
        free(c->name), free(c->folder), free(c->identifier), free(c->guid);
        free_batch(&c->inputs), free_batch(&c->outputs), free_batch(&c->driven);
    }
    for (size_t i = 0; p->starts && i < p->nstarts; i++) {
        struct starts *s = &p->starts[i];
        for (size_t j = 0; s->strings && j < s->n; j++) free(s->strings[j]);
        free(s->vr), free(s->reals), free(s->ints), free(s->strings);
    }
    for (size_t i = 0; p->calls && i < p->ncalls; i++) {
        free_batch(&p->calls[i].io);
        free(p->calls[i].transfers);
    }
    free(p->initial), free(p->components), free(p->starts), free(p->calls), free(p->transfers);
    free(p->exposed), free(p->clocks);
    memset(p, 0, sizeof *p);
}

double plan_time(const struct plan *p, int64_t k) { return (double)(p->t0 + p->h * k) / 1e9; }

int plan_clocked(const struct plan *p, int i) {
    for (size_t j = 0; j < p->nclocks; j++)
        if (p->clocks[j].component == i) return 1;
    return 0;
}
