/* SPDX-License-Identifier: BSD-2-Clause */
/* A hostile FMI host: makes the calls real hosts and careless users make (FMI 2.0 or 3.0
   Co-Simulation), each scenario in a child process of its own, so that a crash is seen as one.

   usage: fmu_hostile_host FMU_DIR VERSION IDENTIFIER TOKEN IN OUT PAR SCENARIO...

   FMU_DIR is the unpacked FMU, VERSION 2 or 3, IDENTIFIER its modelIdentifier, TOKEN its GUID or
   instantiation token; IN, OUT and PAR are value references of a Real (Float64) input, output and
   fixed parameter (-1: the FMU has none; its scenarios are skipped). For each SCENARIO the child
   prints one line

       SCENARIO name status=S instance=I messages=M nullcat=N extra=X | first message

   (S: the status of the call under test, -2 if skipped, I: 1 if the instance under test exists, M: messages the
   FMU logged, N: of them with a NULL category, X: a figure of the scenario) and the parent prints
   "EXIT name code" or "EXIT name signal N" when the child ends. Scenarios: see scenario() below;
   those with an argument: resources-other=LOCATION (another FMU's resources; extra: the output the
   short run ends on), cycles=N, cycles-distinct=N, cycles-alternating=N (extra: bytes kept per
   instantiate/free cycle, the instances named alike, anew each time, or two names in turn), and
   the NONSENSE calls (fmu_hostile_nonsense.c; extra: the messages the call under test logged).
   On Linux (tests/test_fmu_hostile.py) a child is a fork of the host after Python has started once.
   Cross-compiled with mingw-w64 (tests/test_fmu_windows.py, under wine) it loads
   binaries/win64/IDENTIFIER.dll (FMI 3.0: x86_64-windows), FMU_DIR is a C:/ path, and each scenario
   runs in a new process of the host itself (Windows has no fork), which starts the FMU's Python
   anew; the parent prints "EXIT name code" with the child's exit code, an NTSTATUS such as
   0xc0000005 when it crashed. */

#define _GNU_SOURCE
#include <math.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#ifdef _WIN32
#define NOGDI /* its ERROR would clash with the FMI status below */
#include <windows.h>
#include <psapi.h>
#define BINARIES (version == 2 ? "win64" : "x86_64-windows")
#define SUFFIX ".dll"
#define URI_PREFIX "file:///" /* FMU_DIR is C:/... */
typedef HANDLE thread;
static void *open_library(const char *path) {
    wchar_t w[4400];
    if (MultiByteToWideChar(CP_UTF8, 0, path, -1, w, 4400) <= 0) return NULL;
    return (void *)LoadLibraryExW(w, NULL, LOAD_WITH_ALTERED_SEARCH_PATH);
}
static void *symbol(void *l, const char *name) { return (void *)GetProcAddress((HMODULE)l, name); }
static const char *library_error(void) {
    static char text[64];
    snprintf(text, sizeof text, "LoadLibraryExW: error %lu", GetLastError());
    return text;
}
static DWORD WINAPI thread_main(void *arg);
static void start_thread(thread *t, void *arg) { *t = CreateThread(NULL, 0, thread_main, arg, 0, NULL); }
static void join_thread(thread t) { WaitForSingleObject(t, INFINITE), CloseHandle(t); }
#else
#include <dlfcn.h>
#include <pthread.h>
#include <sys/wait.h>
#include <unistd.h>
#define BINARIES (version == 2 ? "linux64" : "x86_64-linux")
#define SUFFIX ".so"
#define URI_PREFIX "file://" /* FMU_DIR is /... */
typedef pthread_t thread;
static void *open_library(const char *path) { return dlopen(path, RTLD_NOW | RTLD_LOCAL); }
static void *symbol(void *l, const char *name) { return dlsym(l, name); }
static const char *library_error(void) { return dlerror(); }
static void *thread_main(void *arg);
static void start_thread(thread *t, void *arg) { pthread_create(t, NULL, thread_main, arg); }
static void join_thread(thread t) { pthread_join(t, NULL); }
#endif

#include "fmu_hostile_host.h" /* with the official FMI 2.0 types (fmu_src/cbase/fmi) */

int version;
static void *library;
static char dir[4096], token[256], resources[4200];
static int in_vr, par_vr;
int out_vr;
int messages, null_categories;
char first[512];
static double last_output; /* the output at the end of the last short run (run()) */
int messages_of_call; /* the messages of a nonsense call, when others follow it */

/* ---- the host's loggers: count, keep the first message of status warning or worse ---------- */

static void note(int status, const char *category, const char *text) {
    messages++;
    if (!category) null_categories++;
    if (status >= 1 && !first[0]) {
        snprintf(first, sizeof first, "%s", text ? text : "(NULL message)");
        for (char *p = first; *p; p++)
            if (*p == '\n') *p = ' ';
    }
}

static void logger2(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                    fmi2String message, ...) {
    (void)env, (void)name;
    char text[2048] = "";
    if (message) {
        va_list args;
        va_start(args, message);
        vsnprintf(text, sizeof text, message, args);
        va_end(args);
    }
    note(status, category, message ? text : NULL);
}

static void logger3(void *env, int status, const char *category, const char *message) {
    (void)env;
    note(status, category, message);
}

static fmi2CallbackFunctions functions = {logger2, calloc, free, NULL, NULL};
static fmi2CallbackFunctions no_logger = {NULL, calloc, free, NULL, NULL};

/* ---- the FMI calls, for either version ------------------------------------------------------- */

void *fn(const char *name) {
    void *f = symbol(library, name);
    if (!f) {
        printf("dlsym %s failed\n", name);
        exit(2);
    }
    return f;
}

enum { LOGGER, NO_LOGGER, NO_FUNCTIONS };

static component instantiate(const char *name, const char *where, const char *guid, int how) {
    if (version == 2) {
        component (*f)(const char *, int, const char *, const char *, const fmi2CallbackFunctions *, int, int) =
            fn("fmi2Instantiate");
        return f(name, 1, guid, where, how == LOGGER ? &functions : how == NO_LOGGER ? &no_logger : NULL, 0, 1);
    }
    component (*f)(const char *, const char *, const char *, bool, bool, bool, bool, const uint32_t *, size_t,
                   void *, void *, void *) = fn("fmi3InstantiateCoSimulation");
    return f(name, guid, where, false, true, false, false, NULL, 0, NULL, how == LOGGER ? (void *)logger3 : NULL,
             NULL);
}

component fresh(const char *name) { return instantiate(name, resources, token, LOGGER); }

int initialize(component c) {
    if (version == 2) {
        int (*setup)(component, int, double, double, int, double) = fn("fmi2SetupExperiment");
        int (*enter)(component) = fn("fmi2EnterInitializationMode");
        int (*exit_)(component) = fn("fmi2ExitInitializationMode");
        int s = setup(c, 0, 0.0, 0.0, 0, 0.0);
        if (s > WARNING) return s;
        s = enter(c);
        return s > WARNING ? s : exit_(c);
    }
    int (*enter)(component, bool, double, double, bool, double) = fn("fmi3EnterInitializationMode");
    int (*exit_)(component) = fn("fmi3ExitInitializationMode");
    int s = enter(c, false, 0.0, 0.0, false, 0.0);
    return s > WARNING ? s : exit_(c);
}

static int step(component c, double t, double h) {
    if (version == 2) {
        int (*f)(component, double, double, int) = fn("fmi2DoStep");
        return f(c, t, h, 1);
    }
    int (*f)(component, double, double, bool, bool *, bool *, bool *, double *) = fn("fmi3DoStep");
    bool event, terminate, early;
    double last;
    return f(c, t, h, true, &event, &terminate, &early, &last);
}

static int get_real(component c, unsigned vr, double *value) {
    int (*f)(component, const unsigned *, size_t, double *, size_t) =
        fn(version == 2 ? "fmi2GetReal" : "fmi3GetFloat64");
    return f(c, &vr, 1, value, 1); /* FMI 2.0's fmi2GetReal ignores the fifth argument */
}

static int set_real(component c, unsigned vr, double value) {
    int (*f)(component, const unsigned *, size_t, const double *, size_t) =
        fn(version == 2 ? "fmi2SetReal" : "fmi3SetFloat64");
    return f(c, &vr, 1, &value, 1);
}

static int call(component c, const char *name2, const char *name3) {
    int (*f)(component) = fn(version == 2 ? name2 : name3);
    return f(c);
}

void free_instance(component c) {
    void (*f)(component) = fn(version == 2 ? "fmi2FreeInstance" : "fmi3FreeInstance");
    f(c);
}

static int worst(int a, int b) { return a > b ? a : b; }

/* A short run: initialize, 10 steps with a varying input, read the output (last_output); its worst status. */
static int run(component c) {
    int s = initialize(c);
    for (int k = 0; k < 10 && s <= WARNING; k++) {
        if (in_vr >= 0) s = worst(s, set_real(c, (unsigned)in_vr, 0.1 * (k + 1)));
        s = worst(s, step(c, k * 1e-3, 1e-3));
    }
    last_output = NAN;
    if (out_vr >= 0 && s <= WARNING) s = worst(s, get_real(c, (unsigned)out_vr, &last_output));
    return s;
}

/* ---- scenarios ---------------------------------------------------------------------------------- */


/* Instantiation with the resource location `where` (the call under test: the short run after it;
   extra: the output it ends with, which tells which model ran). */
static struct result with_resources(const char *where) {
    component c = instantiate("r", where, token, LOGGER);
    struct result r = {c ? run(c) : ERROR, c != NULL, 0};
    r.extra = last_output;
    if (c) free_instance(c);
    return r;
}

static struct result instantiate_only(const char *where, const char *guid, int how) {
    component c = instantiate("g", where, guid, how);
    struct result r = {c ? OK : ERROR, c != NULL, 0};
    if (c) free_instance(c);
    return r;
}

/* An initialized instance, then `f` makes the call under test. */
static struct result initialized(int (*f)(component)) {
    component c = fresh("s");
    if (!c) return (struct result){ERROR, 0, 0};
    int s = initialize(c);
    struct result r = {s <= WARNING ? f(c) : s, 1, 0};
    free_instance(c);
    return r;
}

static int step_nan(component c) { return step(c, 0.0, NAN); }
static int step_negative(component c) { return step(c, 0.0, -1e-3); }
static int step_zero(component c) { return step(c, 0.0, 0.0); }
static int step_infinite(component c) { return step(c, 0.0, INFINITY); }
static int get_unknown(component c) {
    double v;
    return get_real(c, 99999, &v);
}
static int set_output(component c) { return set_real(c, (unsigned)out_vr, 1.0); }
static int set_output_twice(component c) { return worst(set_output(c), set_output(c)); }
static int set_fixed_after_init(component c) { return set_real(c, (unsigned)par_vr, 1.0); }
static int step_after_terminate(component c) {
    call(c, "fmi2Terminate", "fmi3Terminate");
    return step(c, 0.0, 1e-3);
}
/* After an error (an unknown value reference) every later call but a getter, reset and free is
   refused; a second failing call must not crash (before: it did, after a fatal). */
static int after_error(component c) {
    get_unknown(c);
    int s = step(c, 0.0, 1e-3);
    get_unknown(c);
    return s;
}
/* fmi2Reset after an error: the instance runs again. */
static int reset_after_error(component c) {
    get_unknown(c);
    int s = call(c, "fmi2Reset", "fmi3Reset");
    return s > WARNING ? s : run(c);
}

/* The model itself fails: a NaN parameter makes its exit_initialization_mode raise (pythonfmu:
   fatal). The call under test is the step after it; then a second failing call and the free. */
static struct result model_fails(void) {
    component c = fresh("f");
    if (!c) return (struct result){ERROR, 0, 0};
    set_real(c, (unsigned)par_vr, NAN);
    int s = initialize(c);
    int after = step(c, 0.0, 1e-3);
    get_unknown(c);
    free_instance(c);
    return (struct result){after, 1, s};
}

static struct result before_init(int get) {
    component c = fresh("b");
    if (!c) return (struct result){ERROR, 0, 0};
    double v;
    int s = get ? get_real(c, (unsigned)out_vr, &v) : step(c, 0.0, 1e-3);
    free_instance(c);
    return (struct result){s, 1, 0};
}

static long resident_bytes(void) {
#ifdef _WIN32
    PROCESS_MEMORY_COUNTERS counters;
    return GetProcessMemoryInfo(GetCurrentProcess(), &counters, sizeof counters) ? (long)counters.WorkingSetSize
                                                                                 : 0;
#else
    FILE *f = fopen("/proc/self/statm", "r");
    long pages = 0, resident = 0;
    if (f) {
        if (fscanf(f, "%ld %ld", &pages, &resident) != 2) resident = 0;
        fclose(f);
    }
    return resident * sysconf(_SC_PAGESIZE);
#endif
}

/* Memory kept per instantiate/free cycle (extra: bytes per cycle over `n` cycles after WARM_UP,
   which fill the caches of Python and the allocator: after 200, ManipulatorPlant kept 1.1 KB a
   cycle over the next 1000, 0.39 KB over the next 3000, bounded; after 500, 0.56 KB). The instances are named as `naming` says: 's' the
   same name, 'd' a new one each time (run0, run1, ... as campaign tools and FMPy do), 'a' two
   names in turn. */
#ifndef WARM_UP
#define WARM_UP 500
#endif
static struct result cycles(int n, char naming) {
    int s = OK;
    long start = 0;
    for (int k = -WARM_UP; k < n && s == OK; k++) {
        if (k == 0) start = resident_bytes();
        char name[32] = "cycle";
        if (naming == 'd') snprintf(name, sizeof name, "run%d", k + WARM_UP);
        else if (naming == 'a') snprintf(name, sizeof name, "%s", k % 2 ? "odd" : "even");
        component c = fresh(name);
        if (!c) s = ERROR;
        else free_instance(c);
    }
    return (struct result){s, 1, (double)(resident_bytes() - start) / n};
}

/* 50 instances alive at once, each initialized and stepped. */
static struct result fifty(void) {
    component c[50];
    int s = OK, made = 0;
    for (int k = 0; k < 50; k++) {
        char name[16];
        snprintf(name, sizeof name, "i%d", k);
        if ((c[k] = fresh(name))) made++;
        else s = ERROR;
    }
    for (int k = 0; k < 50; k++)
        if (c[k]) s = worst(s, run(c[k]));
    for (int k = 0; k < 50; k++)
        if (c[k]) free_instance(c[k]);
    return (struct result){s, made == 50, made};
}

/* Two threads stepping two instances at once; extra: 1 if both end with the output a lone
   instance gives. */
struct job {
    component c;
    int status;
    double y;
};

static void stepping(struct job *j) {
    j->status = initialize(j->c);
    for (int k = 0; k < 300 && j->status <= WARNING; k++) {
        if (in_vr >= 0) set_real(j->c, (unsigned)in_vr, 0.1 * sin(k * 1e-2));
        j->status = worst(j->status, step(j->c, k * 1e-3, 1e-3));
    }
    if (j->status <= WARNING) j->status = worst(j->status, get_real(j->c, (unsigned)out_vr, &j->y));
}

#ifdef _WIN32
static DWORD WINAPI thread_main(void *arg) {
    stepping(arg);
    return 0;
}
#else
static void *thread_main(void *arg) {
    stepping(arg);
    return NULL;
}
#endif

static struct result two_threads(void) {
    struct job alone = {fresh("alone"), 0, 0}, a = {fresh("a"), 0, 0}, b = {fresh("b"), 0, 0};
    if (!alone.c || !a.c || !b.c) return (struct result){ERROR, 0, 0};
    stepping(&alone);
    thread ta, tb;
    start_thread(&ta, &a);
    start_thread(&tb, &b);
    join_thread(ta);
    join_thread(tb);
    free_instance(alone.c), free_instance(a.c), free_instance(b.c);
    int same = a.y == alone.y && b.y == alone.y;
    return (struct result){worst(alone.status, worst(a.status, b.status)), 1, same};
}

/* The scenarios on an initialized instance: name, the calls made on it. */
static const struct {
    const char *name;
    int (*calls)(component);
} INITIALIZED[] = {
    {"step-nan", step_nan},         {"step-negative", step_negative},
    {"step-zero", step_zero},       {"step-infinite", step_infinite},
    {"unknown-vr", get_unknown},    {"set-output", set_output},
    {"set-output-twice", set_output_twice}, {"set-fixed-after-init", set_fixed_after_init},
    {"step-after-terminate", step_after_terminate}, {"after-error", after_error},
    {"reset-after-error", reset_after_error}};

/* The instantiation scenarios (resource locations, GUIDs, callbacks); 1 if `name` is one. */
static int instantiation_scenario(const char *name, struct result *r) {
    char missing[4300];
    snprintf(missing, sizeof missing, version == 2 ? URI_PREFIX "%s/no-such-folder" : "%s/no-such-folder/", dir);
    if (!strcmp(name, "ok")) *r = with_resources(resources);
    else if (!strcmp(name, "resources-missing")) *r = with_resources(missing);
    else if (!strcmp(name, "resources-empty")) *r = with_resources("");
    else if (!strcmp(name, "resources-null")) *r = with_resources(NULL);
    else if (!strcmp(name, "resources-not-a-file-uri")) *r = with_resources("http://example.org/resources");
    else if (!strncmp(name, "resources-other=", 16)) *r = with_resources(name + 16);
    else if (!strcmp(name, "guid-wrong")) *r = instantiate_only(resources, "{00000000-0000-0000-0000-000000000000}", LOGGER);
    else if (!strcmp(name, "guid-null")) *r = instantiate_only(resources, NULL, LOGGER);
    else if (!strcmp(name, "no-callbacks")) *r = instantiate_only(resources, token, NO_FUNCTIONS);
    else if (!strcmp(name, "no-logger")) {
        component c = instantiate("n", resources, token, NO_LOGGER);
        *r = (struct result){c ? get_unknown(c) : ERROR, c != NULL, 0};
        if (c) free_instance(c);
    } else
        return 0;
    return 1;
}

static struct result scenario(const char *name) {
    const struct result skipped = {-2, 0, 0}; /* the FMU has no variable the scenario needs */
    if ((par_vr < 0 && (!strcmp(name, "set-fixed-after-init") || !strcmp(name, "model-fails"))) ||
        (out_vr < 0 && !strncmp(name, "set-output", 10)))
        return skipped;
    struct result r;
    if (instantiation_scenario(name, &r)) return r;
    for (size_t k = 0; k < sizeof INITIALIZED / sizeof INITIALIZED[0]; k++)
        if (!strcmp(name, INITIALIZED[k].name)) return initialized(INITIALIZED[k].calls);
    if (!strcmp(name, "step-before-init")) return before_init(0);
    if (!strcmp(name, "get-before-init")) return before_init(1);
    if (!strcmp(name, "model-fails")) return model_fails();
    if (!strcmp(name, "fifty")) return fifty();
    if (!strcmp(name, "two-threads")) return two_threads();
    if (!strncmp(name, "cycles", 6)) { /* cycles=N (one name), cycles-distinct=N, cycles-alternating=N */
        const char *count = strchr(name, '=');
        return cycles(count ? atoi(count + 1) : 1000, name[6] == '-' ? name[7] : 's');
    }
    if (is_nonsense(name)) return nonsense(name);
    printf("unknown scenario %s\n", name);
    exit(2);
}

static void report(const char *name) {
    struct result r = scenario(name);
    printf("SCENARIO %s status=%d instance=%d messages=%d nullcat=%d extra=%g | %s\n", name, r.status, r.instance,
           messages, null_categories, r.extra, first);
    fflush(stdout);
}

#ifdef _WIN32
/* One scenario in a new process of this host (the same arguments, the one scenario last); its exit code. */
static DWORD child(int argc, wchar_t **wargv, int k) {
    static wchar_t line[32768];
    size_t used = 0;
    for (int a = 0; a < 8; a++) /* every argument quoted: none holds a quote or ends with a backslash */
        used += (size_t)swprintf(line + used, 32768 - used, L"\"%ls\" ", wargv[a]);
    swprintf(line + used, 32768 - used, L"\"%ls\"", wargv[k]);
    (void)argc;
    STARTUPINFOW start = {.cb = sizeof start};
    PROCESS_INFORMATION process;
    if (!CreateProcessW(NULL, line, NULL, NULL, TRUE, 0, NULL, NULL, &start, &process)) return 0xFFFFFFFFu;
    WaitForSingleObject(process.hProcess, INFINITE);
    DWORD code = 0xFFFFFFFFu;
    GetExitCodeProcess(process.hProcess, &code);
    CloseHandle(process.hProcess), CloseHandle(process.hThread);
    return code;
}
#endif

#ifdef _WIN32
int wmain(int argc, wchar_t **wargv) {
    SetErrorMode(SEM_FAILCRITICALERRORS | SEM_NOGPFAULTERRORBOX); /* a crash ends the child, no dialog */
    char *argv[64];
    if (argc > 64) argc = 64;
    for (int k = 0; k < argc; k++) {
        static char text[64][4400];
        WideCharToMultiByte(CP_UTF8, 0, wargv[k], -1, text[k], sizeof text[k], NULL, NULL);
        argv[k] = text[k];
    }
#else
int main(int argc, char **argv) {
#endif
    if (argc < 9) {
        fprintf(stderr, "usage: %s FMU_DIR VERSION IDENTIFIER TOKEN IN OUT PAR SCENARIO...\n", argv[0]);
        return 2;
    }
    snprintf(dir, sizeof dir, "%s", argv[1]);
    version = atoi(argv[2]);
    snprintf(token, sizeof token, "%s", argv[4]);
    in_vr = atoi(argv[5]), out_vr = atoi(argv[6]), par_vr = atoi(argv[7]);
    char binary[4400];
    snprintf(binary, sizeof binary, "%s/binaries/%s/%s" SUFFIX, dir, BINARIES, argv[3]);
    snprintf(resources, sizeof resources, version == 2 ? URI_PREFIX "%s/resources" : "%s/resources/", dir);
#ifdef _WIN32
    if (argc > 9) { /* the parent: each scenario in a child process */
        for (int k = 8; k < argc; k++) {
            fflush(stdout);
            DWORD code = child(argc, wargv, k);
            if (code >= 0xC0000000u) printf("EXIT %s exception 0x%08lx\n", argv[k], (unsigned long)code);
            else printf("EXIT %s %lu\n", argv[k], (unsigned long)code);
        }
        return 0;
    }
#endif
    library = open_library(binary);
    if (!library) {
        printf("dlopen failed: %s\n", library_error());
        return 2;
    }
#ifdef _WIN32
    report(argv[8]); /* the child (or a lone scenario): run in this process */
    return 0;
#else
    component warm = fresh("warm-up"); /* Python started once: every child inherits it */
    if (warm) free_instance(warm);
    messages = null_categories = 0, first[0] = '\0';
    for (int k = 8; k < argc; k++) {
        fflush(stdout);
        pid_t child = fork();
        if (child == 0) {
            report(argv[k]);
            _exit(0);
        }
        int how = 0;
        waitpid(child, &how, 0);
        if (WIFSIGNALED(how)) printf("EXIT %s signal %d\n", argv[k], WTERMSIG(how));
        else printf("EXIT %s %d\n", argv[k], WEXITSTATUS(how));
    }
    return 0;
#endif
}
