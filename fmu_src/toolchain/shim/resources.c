/* SPDX-License-Identifier: BSD-2-Clause */
/* Where the FMU is (description.h): its unpacked folder, the variable of a value reference in the
   generated table, and the resources folder to give the model (checked by identity). */

#include "description.h"

#include <ctype.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "platform.h"

int ftc_fmu_root(const char *binary, char *root, size_t size) {
    snprintf(root, size, "%s", binary);
    for (int up = 0; up < 3; up++) { /* <root>/binaries/<platform>/<model>.so */
        char *slash = strrchr(root, '/');
        if (!slash) return -1;
        *slash = '\0';
    }
    return 0;
}

const struct ftc_variable *ftc_variable(const struct ftc_model *model, unsigned vr) {
    /* pythonfmu numbers its variables 0, 1, 2 ...: the table's entry vr is mostly vr's own */
    if (vr < model->n && model->variables[vr].vr == vr) return &model->variables[vr];
    size_t low = 0, high = model->n;
    while (low < high) {
        size_t mid = low + (high - low) / 2;
        if (model->variables[mid].vr == vr) return &model->variables[mid];
        if (model->variables[mid].vr < vr) low = mid + 1;
        else high = mid;
    }
    return NULL;
}

/* The absolute path a file URI (file:///p, file:/p, file://localhost/p) or a native path names,
   still percent-encoded; NULL for another host or a relative path. */
static const char *path_part(const char *given) {
    const char *p = given;
    if (strncmp(p, "file:", 5) == 0) {
        p += 5;
        if (strncmp(p, "//localhost/", 12) == 0) p += 11;
        else if (strncmp(p, "///", 3) == 0) p += 2;
        else if (strncmp(p, "//", 2) == 0) return NULL; /* another host */
    }
#ifdef _WIN32 /* file:///C:/p, or C:/p or C:\p (FMI 3.0's native path); '/' in the result */
    if (p[0] == '/' && isalpha((unsigned char)p[1]) && p[2] == ':') p++;
    if (!isalpha((unsigned char)p[0]) || p[1] != ':' || (p[2] != '/' && p[2] != '\\')) return NULL;
#else
    if (p[0] != '/') return NULL;
#endif
    return p;
}

/* The native path of a file URI or of an absolute native path (percent-decoded, '/' for '\',
   no trailing '/'); 0 on success. */
static int native_path(const char *given, char *out, size_t size) {
    const char *p = path_part(given);
    if (!p) return -1;
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

int ftc_resources(const struct ftc_model *model, const char *root, const char *given, char *out, size_t size,
                  char *note, size_t note_size) {
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
    snprintf(own, sizeof own, "%s/resources", root);
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
