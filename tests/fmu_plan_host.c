/* SPDX-License-Identifier: BSD-2-Clause */
/* A C host for FMI 2.0 and FMI 3.0 Co-Simulation FMUs, for Windows (cross-compiled with mingw-w64,
   run under wine in the tests; console or GUI subsystem) and Linux alike: the same source on both
   gives the same calls, so the two platforms' outputs can be compared line by line.

   usage: fmu_plan_host PLAN OUTPUT

   PLAN (UTF-8, one item a line, fields separated by tabs):
     python <path of a python3XY library>   the host embeds its own Python first (loads it, starts
                                             it with Py_InitializeEx(0), releases the GIL), as an
                                             application with a Python console does; at the end it
                                             writes the names of the FMU modules (ftc_*) that
                                             Python imported to OUTPUT.python
     fmu <label> <2|3> <unpacked FMU folder> <model identifier> <guid or token> <steps> <step size>
         <VR=VALUE ...> <VR ...>            every FMU of the plan is loaded and instantiated in
                                             this one process (one label, one instance; the same
                                             folder twice is two instances of one FMU), the
                                             VR=VALUE set after instantiation, then all are stepped
                                             in turn, and after each step the listed VRs are read.
   OUTPUT: "label time value..." per instance and step (%.17g), then "done"; the FMUs' messages as
   "# " lines. The resource location is the folder's file URI (FMI 2.0: file:///C:/Users/J%C3%BCrgen/...,
   percent-encoded) or native path (FMI 3.0).

   Compiled with -DGUI_HOST and -mwindows it is a GUI-subsystem program: it has no console, and its
   standard handles are those of a program started from Explorer, none (set to NULL before any FMU
   is loaded, whatever the starting shell gave).

   Exit status: 0 all calls OK; 2 a library or function is missing; 3 an instantiation returned
   NULL; 4 the plan or the output cannot be read or written; else the OR of the FMI statuses
   (1 warning, 2 discard, 3 error, 4 fatal, as bits 1<<status). */
#define _CRT_SECURE_NO_WARNINGS
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef _WIN32
#include <windows.h>
typedef HMODULE library;
static wchar_t *wide(const char *utf8) {
    int n = MultiByteToWideChar(CP_UTF8, 0, utf8, -1, NULL, 0);
    wchar_t *w = malloc(sizeof(wchar_t) * (size_t)(n > 0 ? n : 1));
    if (!w || MultiByteToWideChar(CP_UTF8, 0, utf8, -1, w, n) <= 0) exit(4);
    return w;
}
static char *utf8(const wchar_t *w) {
    int n = WideCharToMultiByte(CP_UTF8, 0, w, -1, NULL, 0, NULL, NULL);
    char *s = malloc((size_t)(n > 0 ? n : 1));
    if (!s || WideCharToMultiByte(CP_UTF8, 0, w, -1, s, n, NULL, NULL) <= 0) exit(4);
    return s;
}
static library open_library(const char *path) {
    wchar_t *w = wide(path);
    library l = LoadLibraryExW(w, NULL, LOAD_WITH_ALTERED_SEARCH_PATH);
    free(w);
    return l;
}
static void *find(library l, const char *name) { return (void *)GetProcAddress(l, name); }
static FILE *open_file(const char *path, const char *mode) {
    wchar_t *w = wide(path), *m = wide(mode);
    FILE *f = _wfopen(w, m);
    free(w), free(m);
    return f;
}
#define BINARY_DIR (fmi3 ? "x86_64-windows" : "win64")
#define BINARY_SUFFIX ".dll"
#else
#include <dlfcn.h>
typedef void *library;
static library open_library(const char *path) { return dlopen(path, RTLD_NOW | RTLD_LOCAL); }
static void *find(library l, const char *name) { return dlsym(l, name); }
static FILE *open_file(const char *path, const char *mode) { return fopen(path, mode); }
#define BINARY_DIR (fmi3 ? "x86_64-linux" : "linux64")
#define BINARY_SUFFIX ".so"
#endif

#define MAX_FMUS 16
#define MAX_VRS 32

#include "fmi2FunctionTypes.h" /* the official FMI 2.0 types (fmu_src/cbase/fmi) */

struct fmu {
    char label[64];
    int fmi3;
    library lib;
    void *instance;
    int steps;
    double h;
    unsigned set_vr[MAX_VRS], get_vr[MAX_VRS];
    double set_value[MAX_VRS];
    int n_set, n_get;
    /* FMI 2.0 */
    void *(*instantiate2)(const char *, int, const char *, const char *, const fmi2CallbackFunctions *, int, int);
    int (*setup2)(void *, int, double, double, int, double);
    int (*enter2)(void *), (*exit2)(void *), (*terminate2)(void *);
    int (*set2)(void *, const unsigned *, size_t, const double *);
    int (*get2)(void *, const unsigned *, size_t, double *);
    int (*step2)(void *, double, double, int);
    void (*free2)(void *);
    /* FMI 3.0 */
    void *(*instantiate3)(const char *, const char *, const char *, int, int, int, int, const unsigned *, size_t,
                          void *, void (*)(void *, int, const char *, const char *), void *);
    int (*enter3)(void *, int, double, double, int, double);
    int (*exit3)(void *), (*terminate3)(void *);
    int (*set3)(void *, const unsigned *, size_t, const double *, size_t);
    int (*get3)(void *, const unsigned *, size_t, double *, size_t);
    int (*step3)(void *, double, double, int, int *, int *, int *, double *);
    void (*free3)(void *);
};

static FILE *out;
static int result;

static void logger2(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                    fmi2String message, ...) {
    (void)env;
    va_list args;
    va_start(args, message);
    fprintf(out, "# [%s status %d %s] ", name, status, category ? category : "");
    vfprintf(out, message, args);
    fprintf(out, "\n");
    va_end(args);
}

static void logger3(void *env, int status, const char *category, const char *message) {
    fprintf(out, "# [%s status %d %s] %s\n", (const char *)env, status, category ? category : "", message);
}

static void status(int s) {
    if (s) result |= 1 << s;
}

static void *need(library l, const char *name) {
    void *f = find(l, name);
    if (!f) {
        fprintf(out, "# missing function %s\n", name);
        fclose(out);
        exit(2);
    }
    return f;
}

/* The file URI of a folder (absolute path, '/' or '\'), RFC 3986 percent-encoded. */
static void file_uri(const char *folder, char *uri, size_t size) {
    size_t j = (size_t)snprintf(uri, size, "file://%s", folder[0] == '/' ? "" : "/");
    for (const unsigned char *p = (const unsigned char *)folder; *p && j + 4 < size; p++) {
        unsigned char c = *p == '\\' ? '/' : *p;
        if ((c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || strchr("/-._~:", c))
            uri[j++] = (char)c;
        else
            j += (size_t)snprintf(uri + j, size - j, "%%%02X", c);
    }
    uri[j] = '\0';
}

/* Splits `line` at tabs into at most `n` fields; their count. */
static int fields(char *line, char **field, int n) {
    int k = 0;
    line[strcspn(line, "\r\n")] = '\0';
    for (char *p = line; k < n;) {
        field[k++] = p;
        p = strchr(p, '\t');
        if (!p) break;
        *p++ = '\0';
    }
    return k;
}

static library python;          /* the host's own Python, if the plan asks for one */
static const char *report = ""; /* OUTPUT */

static void embed_python(const char *path) {
    python = open_library(path);
    if (!python) {
        fprintf(out, "# cannot load %s\n", path);
        exit(2);
    }
    void (*initialize)(int) = (void (*)(int))need(python, "Py_InitializeEx");
    int (*run)(const char *) = (int (*)(const char *))need(python, "PyRun_SimpleString");
    void *(*save)(void) = (void *(*)(void))need(python, "PyEval_SaveThread");
    initialize(0);
    char code[8192]; /* where the modules the FMUs imported into this Python are listed at the end */
    snprintf(code, sizeof code, "import sys; sys.host_report = r\"\"\"%s.python\"\"\"", report);
    run(code);
    save();
    fprintf(out, "# host python %s\n", path);
}

static void load(struct fmu *f, char **field, int n) {
    char binary[4096], resources[4096], uri[12288];
    const char *folder = field[3], *model = field[4];
    int fmi3 = f->fmi3;
    snprintf(binary, sizeof binary, "%s/binaries/%s/%s%s", folder, BINARY_DIR, model, BINARY_SUFFIX);
    f->lib = open_library(binary);
    if (!f->lib) {
        fprintf(out, "# cannot load %s\n", binary);
        exit(2);
    }
    f->steps = atoi(field[6]);
    f->h = atof(field[7]);
    for (char *item = n > 8 ? strtok(field[8], " ") : NULL; item && f->n_set < MAX_VRS; item = strtok(NULL, " ")) {
        f->set_vr[f->n_set] = (unsigned)strtoul(item, &item, 10);
        f->set_value[f->n_set++] = atof(item + 1);
    }
    for (char *item = n > 9 ? strtok(field[9], " ") : NULL; item && f->n_get < MAX_VRS; item = strtok(NULL, " "))
        f->get_vr[f->n_get++] = (unsigned)strtoul(item, NULL, 10);
    if (!fmi3) {
        static fmi2CallbackFunctions callbacks = {logger2, calloc, free, NULL, NULL};
        f->instantiate2 = need(f->lib, "fmi2Instantiate");
        f->setup2 = need(f->lib, "fmi2SetupExperiment");
        f->enter2 = need(f->lib, "fmi2EnterInitializationMode");
        f->exit2 = need(f->lib, "fmi2ExitInitializationMode");
        f->terminate2 = need(f->lib, "fmi2Terminate");
        f->set2 = need(f->lib, "fmi2SetReal");
        f->get2 = need(f->lib, "fmi2GetReal");
        f->step2 = need(f->lib, "fmi2DoStep");
        f->free2 = need(f->lib, "fmi2FreeInstance");
        snprintf(resources, sizeof resources, "%s/resources", folder);
        file_uri(resources, uri, sizeof uri);
        f->instance = f->instantiate2(f->label, 1 /* fmi2CoSimulation */, field[5], uri, &callbacks, 0, 1);
    } else {
        f->instantiate3 = need(f->lib, "fmi3InstantiateCoSimulation");
        f->enter3 = need(f->lib, "fmi3EnterInitializationMode");
        f->exit3 = need(f->lib, "fmi3ExitInitializationMode");
        f->terminate3 = need(f->lib, "fmi3Terminate");
        f->set3 = need(f->lib, "fmi3SetFloat64");
        f->get3 = need(f->lib, "fmi3GetFloat64");
        f->step3 = need(f->lib, "fmi3DoStep");
        f->free3 = need(f->lib, "fmi3FreeInstance");
#ifdef _WIN32
        snprintf(resources, sizeof resources, "%s\\resources\\", folder);
        for (char *p = resources; *p; p++)
            if (*p == '/') *p = '\\';
#else
        snprintf(resources, sizeof resources, "%s/resources/", folder);
#endif
        f->instance = f->instantiate3(f->label, field[5], resources, 0, 1, 0, 0, NULL, 0, f->label, logger3, NULL);
    }
    if (!f->instance) {
        fprintf(out, "# instantiation of %s returned NULL\n", f->label);
        fclose(out);
        exit(3);
    }
}

static int run(int argc, char **argv) {
    if (argc != 3) {
        fprintf(stderr, "usage: fmu_plan_host PLAN OUTPUT\n");
        return 4;
    }
    out = open_file(argv[2], "w");
    report = argv[2];
    FILE *plan = open_file(argv[1], "r");
    if (!out || !plan) return 4;
#if defined _WIN32 && defined GUI_HOST
    fprintf(out, "# GUI host: console window %s, standard output handle was %s\n",
            GetConsoleWindow() ? "present" : "none", GetStdHandle(STD_OUTPUT_HANDLE) ? "set" : "none");
    SetStdHandle(STD_INPUT_HANDLE, NULL);
    SetStdHandle(STD_OUTPUT_HANDLE, NULL);
    SetStdHandle(STD_ERROR_HANDLE, NULL);
#endif
    static struct fmu fmus[MAX_FMUS];
    int count = 0;
    char line[16384], *field[10];
    while (fgets(line, sizeof line, plan)) {
        int n = fields(line, field, 10);
        if (strcmp(field[0], "python") == 0 && n == 2) embed_python(field[1]);
        if (strcmp(field[0], "fmu") != 0 || n < 8 || count == MAX_FMUS) continue;
        struct fmu *f = &fmus[count++];
        snprintf(f->label, sizeof f->label, "%s", field[1]);
        f->fmi3 = strcmp(field[2], "3") == 0;
        load(f, field, n);
    }
    fclose(plan);
    for (int k = 0; k < count; k++) {
        struct fmu *f = &fmus[k];
        if (f->fmi3) {
            status(f->set3(f->instance, f->set_vr, (size_t)f->n_set, f->set_value, (size_t)f->n_set));
            status(f->enter3(f->instance, 0, 0.0, 0.0, 0, 0.0));
            status(f->exit3(f->instance));
        } else {
            status(f->set2(f->instance, f->set_vr, (size_t)f->n_set, f->set_value));
            status(f->setup2(f->instance, 0, 0.0, 0.0, 0, 0.0));
            status(f->enter2(f->instance));
            status(f->exit2(f->instance));
        }
    }
    double values[MAX_VRS];
    for (int step = 0;; step++) {
        int more = 0;
        for (int k = 0; k < count; k++) {
            struct fmu *f = &fmus[k];
            if (step >= f->steps) continue;
            more = 1;
            double t = step * f->h;
            if (f->fmi3) {
                int event = 0, terminate = 0, early = 0;
                double last = 0.0;
                status(f->step3(f->instance, t, f->h, 1, &event, &terminate, &early, &last));
                status(f->get3(f->instance, f->get_vr, (size_t)f->n_get, values, (size_t)f->n_get));
            } else {
                status(f->step2(f->instance, t, f->h, 1));
                status(f->get2(f->instance, f->get_vr, (size_t)f->n_get, values));
            }
            fprintf(out, "%s %.17g", f->label, (step + 1) * f->h);
            for (int v = 0; v < f->n_get; v++) fprintf(out, " %.17g", values[v]);
            fprintf(out, "\n");
        }
        if (!more) break;
    }
    for (int k = 0; k < count; k++) {
        struct fmu *f = &fmus[k];
        if (f->fmi3) {
            status(f->terminate3(f->instance));
            f->free3(f->instance);
        } else {
            status(f->terminate2(f->instance));
            f->free2(f->instance);
        }
    }
    if (python) { /* which FMU modules this Python imported: the FMUs ran on the host's interpreter */
        int (*ensure)(void) = (int (*)(void))need(python, "PyGILState_Ensure");
        void (*release)(int) = (void (*)(int))need(python, "PyGILState_Release");
        int (*run_code)(const char *) = (int (*)(const char *))need(python, "PyRun_SimpleString");
        int gil = ensure();
        run_code("import sys\nwith open(sys.host_report, 'w', encoding='utf-8') as f:\n"
                 "    f.write(' '.join(sorted(m for m in sys.modules if m.startswith('ftc_'))))");
        release(gil);
    }
    fprintf(out, "done\n");
    fclose(out);
    return result;
}

#ifdef _WIN32
int wmain(int argc, wchar_t **wargv) {
    char **argv = malloc(sizeof(char *) * (size_t)(argc + 1));
    if (!argv) return 4;
    for (int k = 0; k < argc; k++) argv[k] = utf8(wargv[k]);
    argv[argc] = NULL;
    return run(argc, argv);
}
#else
int main(int argc, char **argv) { return run(argc, argv); }
#endif
