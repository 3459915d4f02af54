/* SPDX-License-Identifier: BSD-2-Clause */
/* The guard's knowledge of its FMU (guard.h): the model description, read without an XML library
   (the file is the build's own: fmu_src/toolchain/build.py and fmu_src/toolchain/fmi3.py write it), and the
   resources folder. */

#include "guard.h"

#include <ctype.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "platform.h"

#define MAX_DESCRIPTION (16u << 20) /* bytes: far above any FMU of the project */

static char *read_text(const char *path, char *why, size_t size) {
    FILE *f = ftc_fopen(path, "rb");
    if (!f) {
        snprintf(why, size, "cannot read %s", path);
        return NULL;
    }
    long length = fseek(f, 0, SEEK_END) == 0 ? ftell(f) : -1;
    char *text = length >= 0 && length <= (long)MAX_DESCRIPTION ? malloc((size_t)length + 1) : NULL;
    size_t n = text && fseek(f, 0, SEEK_SET) == 0 ? fread(text, 1, (size_t)length, f) : 0;
    fclose(f);
    if (!text || n != (size_t)length) {
        free(text);
        snprintf(why, size, "%s: %s", path, length > (long)MAX_DESCRIPTION ? "larger than 16 MB" : "cannot read it");
        return NULL;
    }
    text[n] = '\0';
    return text;
}

/* The value of attribute `name` in the tag starting at `tag` (up to its '>'), XML entities of
   the five predefined kinds decoded; 1 if found. */
static int attribute(const char *tag, const char *name, char *out, size_t size) {
    const char *end = strchr(tag, '>');
    size_t n = strlen(name);
    for (const char *p = tag + 1; end && p < end; p++) {
        if ((p[-1] == ' ' || p[-1] == '\n' || p[-1] == '\t') && strncmp(p, name, n) == 0 && p[n] == '=' &&
            (p[n + 1] == '"' || p[n + 1] == '\'')) {
            const char quote = p[n + 1], *v = p + n + 2;
            size_t j = 0;
            while (*v && *v != quote && j + 1 < size) {
                static const char *const entities[][2] = {
                    {"&amp;", "&"}, {"&lt;", "<"}, {"&gt;", ">"}, {"&quot;", "\""}, {"&apos;", "'"}};
                size_t k = 0;
                for (; k < 5; k++)
                    if (strncmp(v, entities[k][0], strlen(entities[k][0])) == 0) break;
                if (k < 5) {
                    out[j++] = entities[k][1][0];
                    v += strlen(entities[k][0]);
                } else
                    out[j++] = *v++;
            }
            out[j] = '\0';
            return 1;
        }
    }
    return 0;
}

/* Whether boolean attribute `name` of the tag at `tag` is "true" (or "1"). */
static int flag(const char *tag, const char *name) {
    char value[16];
    return attribute(tag, name, value, sizeof value) && (strcmp(value, "true") == 0 || strcmp(value, "1") == 0);
}

static char code(const char *value, const char *const names[], const char *codes) {
    for (size_t k = 0; names[k]; k++)
        if (strcmp(value, names[k]) == 0) return codes[k];
    return 0;
}

static const char *const TYPES[] = {"Real", "Float64", "Integer", "Int32", "Boolean", "String", NULL};
static const char *const CAUSALITIES[] = {"parameter", "calculatedParameter", "input", "output", "local",
                                          "independent", "structuralParameter", NULL};
static const char *const VARIABILITIES[] = {"constant", "fixed", "tunable", "discrete", "continuous", NULL};
static const char *const INITIALS[] = {"exact", "approx", "calculated", NULL};
/* FMI 3.0's variable elements (FMI 2.0's are ScalarVariable with a typed child). */
static const char *const ELEMENTS3[] = {"Float32", "Float64", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32",
                                        "Int64", "UInt64", "Boolean", "String", "Binary", "Enumeration", "Clock",
                                        NULL};

static int by_vr(const void *a, const void *b) {
    unsigned x = ((const struct ftc_variable *)a)->vr, y = ((const struct ftc_variable *)b)->vr;
    return (x > y) - (x < y);
}

/* Fills `v` from the variable's tag (FMI 3.0: the typed element itself; FMI 2.0: ScalarVariable,
   whose typed child `typed` gives the type). */
static int variable(const char *tag, const char *typed, size_t typed_length, struct ftc_variable *v) {
    char value[128], type[32];
    if (!attribute(tag, "valueReference", value, sizeof value)) return -1;
    v->vr = (unsigned)strtoul(value, NULL, 10);
    snprintf(type, sizeof type, "%.*s", (int)typed_length, typed);
    v->type = code(type, TYPES, "rriibs");
    if (!v->type) v->type = 'e';
    v->causality = attribute(tag, "causality", value, sizeof value) ? code(value, CAUSALITIES, "pciolts") : 'l';
    v->variability = attribute(tag, "variability", value, sizeof value) ? code(value, VARIABILITIES, "cftdC")
                                                                         : (v->type == 'r' ? 'C' : 'd');
    v->initial = attribute(tag, "initial", value, sizeof value) ? code(value, INITIALS, "eac") : 0;
    if (!attribute(tag, "name", v->name, sizeof v->name)) snprintf(v->name, sizeof v->name, "?");
    return 0;
}

int ftc_read_model(const char *binary, struct ftc_model *model, char *why, size_t size) {
    memset(model, 0, sizeof *model);
    snprintf(model->root, sizeof model->root, "%s", binary);
    for (int up = 0; up < 3; up++) { /* <root>/binaries/<platform>/<model>.so */
        char *slash = strrchr(model->root, '/');
        if (!slash) {
            snprintf(why, size, "the shim %s is not in an unpacked FMU (binaries/<platform>/)", binary);
            return -1;
        }
        *slash = '\0';
    }
    /* The build's copy beside the binary first (hosts such as fmpy's simulate_fmu unpack only
       binaries/ and resources/), else the FMU's own. */
    char path[4096 + 32];
    snprintf(path, sizeof path, "%s", binary);
    char *dot = strrchr(path, '.');
    if (dot && dot > strrchr(path, '/')) *dot = '\0';
    strncat(path, DESCRIPTION_SUFFIX, sizeof path - strlen(path) - 1);
    if (!ftc_is_file(path)) snprintf(path, sizeof path, "%s/modelDescription.xml", model->root);
    char *text = read_text(path, why, size);
    if (!text) return -1;
    const char *root = strstr(text, "<fmiModelDescription");
    const char *vars = strstr(text, "<ModelVariables");
    const char *vars_end = vars ? strstr(vars, "</ModelVariables>") : NULL;
    if (!root || !(attribute(root, "guid", model->token, sizeof model->token) ||
                   attribute(root, "instantiationToken", model->token, sizeof model->token))) {
        snprintf(why, size, "%s: no guid or instantiationToken", path);
        free(text);
        return -1;
    }
    const char *cs = strstr(text, "<CoSimulation");
    if (cs) { /* FMI 2.0 spells FMUstate, FMI 3.0 FMUState */
        model->can_get_and_set_state = flag(cs, "canGetAndSetFMUstate") || flag(cs, "canGetAndSetFMUState");
        model->can_serialize_state = flag(cs, "canSerializeFMUstate") || flag(cs, "canSerializeFMUState");
        model->directional_derivatives =
            flag(cs, "providesDirectionalDerivative") || flag(cs, "providesDirectionalDerivatives");
        model->interpolate_inputs = flag(cs, "canInterpolateInputs");
        char order[32];
        model->output_derivative_order =
            attribute(cs, "maxOutputDerivativeOrder", order, sizeof order) ? atoi(order) : 0;
    }
    size_t capacity = 0;
    int failed = 0;
    for (const char *p = vars ? strchr(vars, '>') : NULL; p && vars_end && (p = strchr(p, '<')) && p < vars_end;
         p++) {
        const char *name = p + 1, *typed = NULL, *tag = p;
        size_t length = strcspn(name, " \t\n/>");
        if (length == 14 && strncmp(name, "ScalarVariable", 14) == 0) { /* FMI 2.0 */
            const char *child = strchr(p, '>');
            if (child && child[-1] != '/' && (child = strchr(child, '<'))) typed = child + 1;
            if (!typed) continue;
        } else {
            char element[32];
            snprintf(element, sizeof element, "%.*s", (int)(length < 31 ? length : 31), name);
            if (!code(element, ELEMENTS3, "xxxxxxxxxxxxxxx")) continue; /* Start, Dimension, ... */
            typed = name;
        }
        if (model->n == capacity) {
            capacity = capacity ? 2 * capacity : 64;
            struct ftc_variable *grown = realloc(model->variables, capacity * sizeof *grown);
            if (!grown) {
                failed = 1;
                break;
            }
            model->variables = grown;
        }
        if (variable(tag, typed, strcspn(typed, " \t\n/>"), &model->variables[model->n]) == 0) model->n++;
    }
    free(text);
    if (failed || !vars || !vars_end) {
        snprintf(why, size, "%s: %s", path, failed ? "out of memory" : "no ModelVariables");
        free(model->variables);
        model->variables = NULL;
        return -1;
    }
    qsort(model->variables, model->n, sizeof *model->variables, by_vr);
    return 0;
}

const struct ftc_variable *ftc_variable(const struct ftc_model *model, unsigned vr) {
    size_t low = 0, high = model->n;
    while (low < high) {
        size_t mid = low + (high - low) / 2;
        if (model->variables[mid].vr == vr) return &model->variables[mid];
        if (model->variables[mid].vr < vr) low = mid + 1;
        else high = mid;
    }
    return NULL;
}

/* The native path of a file URI (file:///p, file:/p, file://localhost/p; percent-decoded) or of
   an absolute native path; 0 on success. */
static int native_path(const char *given, char *out, size_t size) {
    const char *p = given;
    if (strncmp(p, "file:", 5) == 0) {
        p += 5;
        if (strncmp(p, "//localhost/", 12) == 0) p += 11;
        else if (strncmp(p, "///", 3) == 0) p += 2;
        else if (strncmp(p, "//", 2) == 0) return -1; /* another host */
    }
#ifdef _WIN32 /* file:///C:/p, or C:/p or C:\p (FMI 3.0's native path); '/' in the result */
    if (p[0] == '/' && isalpha((unsigned char)p[1]) && p[2] == ':') p++;
    if (!isalpha((unsigned char)p[0]) || p[1] != ':' || (p[2] != '/' && p[2] != '\\')) return -1;
#else
    if (p[0] != '/') return -1;
#endif
    size_t j = 0;
    for (; *p && j + 1 < size; p++) {
        unsigned hex;
        if (p[0] == '%' && sscanf(p + 1, "%2x", &hex) == 1 && p[1] && p[2]) {
            out[j++] = (char)hex;
            p += 2;
        } else
            out[j++] = *p == '\\' ? '/' : *p;
    }
    out[j] = '\0';
    while (j > 1 && out[j - 1] == '/') out[--j] = '\0';
    return *p ? -1 : 0;
}

static int holds_resources(const char *folder) {
    char marker[4096 + 32];
    snprintf(marker, sizeof marker, "%s/slavemodule.txt", folder);
    return ftc_is_file(marker);
}

/* The identity the resources folder records (IDENTITY_FILE, its first line) in `out`; 0, or -1 if
   it records none. */
static int identity(const char *folder, char *out, size_t size) {
    char path[4096 + 32];
    snprintf(path, sizeof path, "%s/" IDENTITY_FILE, folder);
    FILE *f = ftc_fopen(path, "rb");
    if (!f) return -1;
    size_t n = fread(out, 1, size - 1, f);
    fclose(f);
    out[n] = '\0';
    out[strcspn(out, "\r\n")] = '\0';
    return n ? 0 : -1;
}

int ftc_resources(const struct ftc_model *model, const char *given, char *out, size_t size, char *note,
                  size_t note_size) {
    char path[4096], found[160], other[sizeof found + 96];
    const char *problem = NULL;
    if (!given) problem = "is not given";
    else if (!given[0]) problem = "is empty";
    else if (native_path(given, path, sizeof path) != 0) problem = "is not a file URI or absolute path";
    else if (!ftc_is_dir(path)) problem = "does not exist";
    else if (!holds_resources(path)) problem = "is not this FMU's resources folder (no slavemodule.txt)";
    else if (identity(path, found, sizeof found) != 0)
        problem = "is not this FMU's resources folder (no " IDENTITY_FILE " naming its model)";
    else if (strcmp(found, model->token) != 0) {
        snprintf(other, sizeof other, "is another FMU's resources folder (of %s, not this FMU's %s)", found,
                 model->token);
        problem = other;
    }
    if (!problem) {
        snprintf(out, size, "%s", path);
        return 0;
    }
    char own[4096 + 16], shown[4096 + 8];
    snprintf(own, sizeof own, "%s/resources", model->root);
    snprintf(shown, sizeof shown, given ? "'%s'" : "(NULL)", given);
    if (holds_resources(own)) {
        snprintf(out, size, "%s", own);
        snprintf(note, note_size, "the resource location %s %s: using the FMU's own resources folder %s", shown,
                 problem, own);
        return 1;
    }
    snprintf(note, note_size, "the resource location %s %s, and the FMU's own %s does not hold its resources", shown,
             problem, own);
    return -1;
}
