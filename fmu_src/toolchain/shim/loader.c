/* SPDX-License-Identifier: BSD-2-Clause */
/* The loader (shim.h): makes Python available in the process if the host has none, then opens
   pythonfmu's binary and resolves its FMI 2.0 functions; once per process, at the first
   instantiation. And the unload that works around pythonfmu's double free at exit. */

#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "shim.h"
#include "unpack.h"

/* pythonfmu's functions (shim.h). */
#define DEFINE_POINTER(name, params, args) fmi2Status(*inner_##name) params;
FMI2_FORWARDED(DEFINE_POINTER)
fmi2Component (*inner_fmi2Instantiate)(fmi2String, fmi2Type, fmi2String, fmi2String,
                                       const fmi2CallbackFunctions *, fmi2Boolean, fmi2Boolean);
void (*inner_fmi2FreeInstance)(fmi2Component);

#ifndef _WIN32
static void unload(void);
#endif

static ftc_mutex load_lock = FTC_MUTEX_INIT;
static int loaded;            /* 0: not tried, 1: pythonfmu's binary is ready, -1: failed */
static void *inner;           /* handle of <model>_pythonfmu.so */
char model[256];
static char failure[TEXT];    /* the one message of a failed load() */
char python_info[TEXT];
char fmu_root[TEXT];

#ifndef _WIN32
/* Loads a library of the runtime by soname, globally: one already in the process is reused, else
   the search reaches the shim's DT_RUNPATH ($ORIGIN/python/lib, holding libpython only) and then
   the system's folders; `fallback` (a path), if given, is loaded where that finds nothing. */
static void *load_runtime_library(const char *soname, const char *fallback) {
    void *handle = ftc_library_open(soname, 1);
    if (!handle && fallback) handle = ftc_library_open(fallback, 1);
    if (!handle) {
        const char *name = fallback ? fallback : soname;
        snprintf(failure, TEXT, "%s: cannot load the bundled %s: %s", model, soname, ftc_library_error(name));
    }
    return handle;
}

#endif

/* Whether `library` is an FMU's bundled libpython (<home>/lib/<libpython> beside <home>/python311.zip);
   if so, writes <home>. */
static int bundled_home(const char *library, char home[TEXT]) {
    const char *suffix = FTC_LIBPYTHON_DIR FTC_LIBPYTHON;
    size_t n = strlen(library), m = strlen(suffix);
    if (n <= m || n - m >= TEXT || strcmp(library + n - m, suffix) != 0) return 0;
    snprintf(home, TEXT, "%.*s", (int)(n - m), library);
    char zip[TEXT + 32];
    snprintf(zip, sizeof zip, "%s/python" FTC_TAG ".zip", home);
    return ftc_is_file(zip);
}

/* The shim's own file `self`, its folder `dir`, the model identifier and the FMU's folder. */
static int locate(char self[TEXT], char dir[TEXT]) {
    if (ftc_library_file((void *)&locate, self, TEXT) != 0) {
        snprintf(failure, TEXT, "fmi2 shim: cannot find its own file (dladdr failed)");
        return -1;
    }
    snprintf(dir, TEXT, "%s", self);
    char *slash = strrchr(dir, '/');
    snprintf(model, sizeof model, "%s", slash ? slash + 1 : dir);
    char *dot = strrchr(model, '.');
    if (dot && strcmp(dot, SHIM_SUFFIX) == 0) *dot = '\0';
    if (slash) *slash = '\0';
    else snprintf(dir, TEXT, ".");
    if (ftc_fmu_root(self, fmu_root, sizeof fmu_root) != 0) {
        snprintf(failure, TEXT, "%s: the shim %s is not in an unpacked FMU (binaries/<platform>/)", model, self);
        return -1;
    }
    return 0;
}

static int shared_runtime; /* 1: the runtime is an exported container's, shared by its FMUs */

/* The runtime folder: the FMU's own binaries/<platform>/python; for an FMU without one unpacked in
   an exported container (resources/fmus/<name>/, orchestrator/export/container.py), the one
   runtime the container carries for all its FMUs of that platform folder:
   resources/fmus/_runtime/<platform>/python. */
static void shared_runtime_folder(const char *dir, char runtime[TEXT + 16]) {
    char zip[TEXT + 64];
    snprintf(runtime, TEXT + 16, "%s/%s", dir, RUNTIME_DIR);
    snprintf(zip, sizeof zip, "%s/python" FTC_TAG ".zip", runtime);
    const char *platform = strrchr(dir, '/'), *name = strrchr(fmu_root, '/');
    if (ftc_is_file(zip) || !platform || !name) return;
    char shared[TEXT + 16];
    snprintf(shared, sizeof shared, "%.*s/_runtime%s/%s", (int)(name - fmu_root), fmu_root, platform, RUNTIME_DIR);
    snprintf(zip, sizeof zip, "%s/python" FTC_TAG ".zip", shared);
    if (!ftc_is_file(zip)) return; /* neither: the load names the FMU's own folder */
    snprintf(runtime, TEXT + 16, "%s", shared);
    shared_runtime = 1;
}

/* Where the runtime and pythonfmu's binary are loaded from: `runtime` (the python/ folder) and
   `inner_dir`. Windows: copies in the user's cache (see ftc_cached_copy), so that the host can
   delete the folder it unpacked once it has freed the instances and this library, the runtime's
   python311.dll.xz decoded there (unpack.c); where there is no cache, the unpacked folder `dir`
   itself, and the runtime decoded into a folder of %TEMP% (ftc_temporary_copy). POSIX: the
   unpacked folder (libpython3.11.so.1.0.xz is decoded by open_python, only where it is needed). */
static int runtime_folders(const char *dir, char runtime[TEXT + 16], char inner_dir[TEXT]) {
    shared_runtime_folder(dir, runtime);
    snprintf(inner_dir, TEXT, "%s", dir);
#ifdef _WIN32
    char file[TEXT + 64], cached_runtime[TEXT + 16], cached_inner[TEXT], why[TEXT];
    snprintf(file, sizeof file, "%s%s", model, INNER_SUFFIX);
    if (ftc_cached_copy_decoded(runtime, ftc_xz_decode, cached_runtime, sizeof cached_runtime, why, sizeof why) == 0) {
        if (ftc_cached_copy(dir, file, cached_inner, sizeof cached_inner) == 0)
            snprintf(inner_dir, TEXT, "%s", cached_inner);
        snprintf(runtime, TEXT + 16, "%s", cached_runtime);
        return 0;
    }
    snprintf(file, sizeof file, "%s/" FTC_LIBPYTHON FTC_XZ_SUFFIX, runtime);
    if (!why[0] && ftc_is_file(file) &&
        ftc_temporary_copy(runtime, ftc_xz_decode, cached_runtime, sizeof cached_runtime, why, sizeof why) == 0)
        snprintf(runtime, TEXT + 16, "%s", cached_runtime);
    else if (why[0] || ftc_is_file(file)) { /* `why` names the file */
        if (!why[0]) snprintf(why, sizeof why, "%s: no cache, and no folder of %%TEMP%% to decode it into", file);
        snprintf(failure, TEXT, "%s: cannot decode the bundled " FTC_LIBPYTHON ": %s", model, why);
        return -1;
    }
#endif
    return 0;
}

#ifdef _WIN32
/* Windows has no global symbol namespace: the bundled python311.dll is loaded by its full path
   where no module of the process exports Python (a Python host's own serves otherwise); then what
   pythonfmu's binary imports by name and the process lacks: the stable-ABI forwarder python3.dll
   (to whichever python311.dll is loaded) and the MSVC runtime. A DLL of that name already in the
   process is the one every import binds to. `*python`: the library (NULL: the process's). */
static int open_python(const char *runtime, void **python) {
    char file[TEXT + 64];
    if (!ftc_library_symbol(NULL, "Py_IsInitialized")) {
        snprintf(file, sizeof file, "%s/%s", runtime, FTC_LIBPYTHON);
        if (!(*python = ftc_library_open(file, 1))) {
            snprintf(failure, TEXT, "%s: cannot load the bundled %s: %s", model, file, ftc_library_error(file));
            return -1;
        }
    }
    static const char *const imported[] = {"vcruntime140.dll", "vcruntime140_1.dll", "msvcp140.dll", "python3.dll"};
    for (size_t k = 0; k < sizeof imported / sizeof imported[0]; k++) {
        snprintf(file, sizeof file, "%s/%s", runtime, imported[k]);
        if (!ftc_library_loaded(imported[k]) && !ftc_library_open(file, 1)) {
            snprintf(failure, TEXT, "%s: cannot load the bundled %s: %s", model, file, ftc_library_error(file));
            return -1;
        }
    }
    return 0;
}
#else
static char decoded[TEXT];  /* the libpython this shim decoded and loaded, if any */
static int decoded_temporary; /* 1: it is in a private folder of TMPDIR, removed once started */

/* The runtime's libpython3.11.so.1.0.xz decoded (into the user's cache, else a private folder;
   ftc_decoded_file) and loaded by its path; NULL and the message where it cannot be. */
static void *load_decoded(const char *packed) {
    char why[TEXT];
    if (ftc_decoded_file(packed, FTC_LIBPYTHON, ftc_xz_decode, decoded, sizeof decoded, &decoded_temporary, why,
                         sizeof why) != 0) {
        snprintf(failure, TEXT, "%s: cannot decode the bundled %s: %s", model, FTC_LIBPYTHON, why);
        decoded[0] = '\0';
        return NULL;
    }
    void *handle = ftc_library_open(decoded, 1);
    if (!handle) {
        snprintf(failure, TEXT, "%s: cannot load the bundled %s (decoded from %s): %s", model, decoded, packed,
                 ftc_library_error(decoded));
        if (decoded_temporary) ftc_remove_temporary(decoded);
        decoded[0] = '\0';
    }
    return handle;
}

/* libpython where the process has no Python, zlib and expat (which it links) before it. The
   runtime carries it xz-compressed: one another FMU's shim is loading is taken by its soname,
   else it is decoded and loaded by its path (load_decoded); an uncompressed one (an FMU of an
   earlier build) by its path. `*python`: the library (NULL: every library of the process). */
static int open_python(const char *runtime, void **python) {
    if (ftc_library_symbol(NULL, "Py_IsInitialized")) return 0;
    char zlib[TEXT + 64], expat[TEXT + 64];
    snprintf(zlib, sizeof zlib, "%s/fallback/libz.so.1", runtime);
    snprintf(expat, sizeof expat, "%s/fallback/libexpat.so.1", runtime);
    char library[TEXT + 64], packed[TEXT + 64];
    snprintf(library, sizeof library, "%s" FTC_LIBPYTHON_DIR FTC_LIBPYTHON, runtime);
    snprintf(packed, sizeof packed, "%s" FTC_XZ_SUFFIX, library);
    if (!load_runtime_library("libz.so.1", zlib) || !load_runtime_library("libexpat.so.1", expat)) return -1;
    if (!ftc_is_file(library) && ftc_is_file(packed)) {
        /* FMUs instantiated in parallel threads: one decodes and loads it, the others then find
           it by soname (decoded files of other folders would be other libpythons) */
        int lock = ftc_process_lock();
        *python = ftc_library_loaded(FTC_LIBPYTHON) ? load_runtime_library(FTC_LIBPYTHON, NULL) : load_decoded(packed);
        ftc_process_unlock(lock);
        return *python ? 0 : -1;
    }
    /* an uncompressed runtime: the FMU's own libpython by soname (the shim's DT_RUNPATH finds it),
       a container's shared one by its path (a system's libpython3.11 must not serve instead) */
    return (*python = load_runtime_library(shared_runtime ? library : FTC_LIBPYTHON, NULL)) ? 0 : -1;
}
#endif

/* Whether `library` is a libpython the shim of an FMU decoded (ftc_decoded_file): named
   libpython3.11.so.1.0 in a folder <16 hex digits> of .../fixed-time-cosim/runtime, or in a
   private folder ftc-runtime-XXXXXX. */
static int decoded_library(const char *library) {
#ifdef _WIN32
    (void)library;
    return 0;
#else
    const char *slash = strrchr(library, '/');
    if (!slash || strcmp(slash + 1, FTC_LIBPYTHON) != 0) return 0;
    const char *folder = slash;
    while (folder > library && folder[-1] != '/') folder--;
    if (strncmp(folder, "ftc-runtime-", 12) == 0) return 1;
    const char *parent = "/fixed-time-cosim/runtime/";
    size_t m = strlen(parent);
    return slash - folder == 16 && (size_t)(folder - library) >= m && strncmp(folder - m, parent, m) == 0;
#endif
}

/* Starts the interpreter `python` if nobody has: the FMU's bundled runtime isolated
   (start_python.c), a host's own libpython as a host would. `*own`: Python is an FMU's bundled
   runtime (this one's or another's), not the host's. */
static int start(void **python, int (*is_initialized)(void), int *own, const char *runtime) {
    /* The shims of two FMUs may start at once in different threads: the second may find the
       libpython the first loaded before the first started it. So whether Python is an FMU's own
       runtime is decided by the file that defines it (<home>/lib/libpython... beside
       <home>/python311.zip), whoever loaded it, and a lock on that file makes the first start it
       completely before the other looks. */
    char library[TEXT], home[TEXT], reason[TEXT];
    if (ftc_library_file((void *)is_initialized, library, sizeof library) != 0)
        snprintf(library, sizeof library, "%s", FTC_LIBPYTHON);
#ifdef _WIN32
    if (!*python) *python = ftc_library_loaded(library); /* the host's: symbols are per DLL */
#endif
    *own = bundled_home(library, home);
    if (!*own && decoded_library(library)) { /* decoded from a runtime: its home is the runtime's folder */
        *own = 1;
        snprintf(home, TEXT, "%s", runtime);
    }
    int lock = ftc_file_lock(library);
    int status = 0;
    if (!is_initialized() && *own) {
        status = ftc_start_python(*python, home, reason, sizeof reason);
        if (status != 0) snprintf(failure, TEXT, "%s: cannot start the bundled Python in %s: %s", model, home, reason);
    } else if (!is_initialized()) { /* the host loaded a libpython of its own without starting it */
        void (*initialize)(int) = (void (*)(int))ftc_library_symbol(*python, "Py_InitializeEx");
        void *(*save_thread)(void) = (void *(*)(void))ftc_library_symbol(*python, "PyEval_SaveThread");
        if (initialize && save_thread) {
            initialize(0); /* 0: keep the host's signal handlers */
            save_thread();
        }
        status = is_initialized() ? 0 : -1;
        if (status != 0) snprintf(failure, TEXT, "%s: cannot initialize the host's Python (%s)", model, library);
    }
    ftc_file_unlock(lock);
    return status;
}

/* Opens pythonfmu's binary from `inner_dir` and resolves its FMI 2.0 functions. */
static int open_inner(const char *self, const char *inner_dir, const char *runtime) {
    char path[TEXT + 300];
    snprintf(path, sizeof path, "%s/%s%s", inner_dir, model, INNER_SUFFIX);
#ifdef _WIN32
    int first = !ftc_library_loaded(path); /* else a former load of this folder kept its files */
#endif
    inner = ftc_library_open(path, 0);
    if (!inner) {
        snprintf(failure, TEXT, "%s: cannot load pythonfmu's binary %s: %s", model, path, ftc_library_error(path));
        return -1;
    }
#ifdef _WIN32
    if (first) { /* the cache's files, or those of the unpacked folder where there is no cache */
        ftc_keep_files(inner_dir);
        ftc_keep_files(runtime);
    }
    ftc_keep_own_file(self);
#else
    (void)self, (void)runtime;
#endif
    inner_fmi2Instantiate = (fmi2Component(*)(fmi2String, fmi2Type, fmi2String, fmi2String,
                                               const fmi2CallbackFunctions *, fmi2Boolean, fmi2Boolean))
        ftc_library_symbol(inner, "fmi2Instantiate");
    inner_fmi2FreeInstance = (void (*)(fmi2Component))ftc_library_symbol(inner, "fmi2FreeInstance");
    int complete = inner_fmi2Instantiate && inner_fmi2FreeInstance;
#define RESOLVE(name, params, args) complete &= (*(void **)(&inner_##name) = ftc_library_symbol(inner, #name)) != NULL;
    FMI2_FORWARDED(RESOLVE)
#undef RESOLVE
    if (!complete) {
        snprintf(failure, TEXT, "%s: %s lacks an FMI 2.0 function", model, path);
        return -1;
    }
    return 0;
}

/* Makes Python available if needed, then opens pythonfmu's binary. Called once, under load_lock. */
static int load(void) {
    char self[TEXT], dir[TEXT], runtime[TEXT + 16], inner_dir[TEXT];
    if (locate(self, dir) != 0 || runtime_folders(dir, runtime, inner_dir) != 0) return -1;
    void *python = NULL; /* NULL: every library of the process */
    if (open_python(runtime, &python) != 0) return -1;
    int (*is_initialized)(void) = (int (*)(void))ftc_library_symbol(python, "Py_IsInitialized");
    int own = 0, started = -1;
    if (!is_initialized)
        snprintf(failure, TEXT, "%s: %s has no Py_IsInitialized: not a libpython", model, FTC_LIBPYTHON);
    else started = start(&python, is_initialized, &own, runtime);
#ifndef _WIN32
    if (decoded_temporary) ftc_remove_temporary(decoded); /* loaded and started: Linux keeps the mapping */
#endif
    if (started != 0 || open_inner(self, inner_dir, runtime) != 0) return -1;
#ifndef _WIN32 /* the double free below is pythonfmu's on Linux (its binary cannot be unloaded there) */
    atexit(unload); /* after pythonfmu's static destructors were registered: runs before them */
#endif
    resolve_python_api(python);
    const char *(*get_version)(void) = (const char *(*)(void))ftc_library_symbol(python, "Py_GetVersion");
    snprintf(python_info, TEXT, "Python %.*s %s", get_version ? (int)strcspn(get_version(), " ") : 1,
             get_version ? get_version() : "?", own ? "bundled with the FMU" : "of the host process");
    return 0;
}

int ftc_load(const char **why) {
    ftc_lock(&load_lock);
    if (loaded == 0) loaded = load() == 0 ? 1 : -1;
    ftc_unlock(&load_lock);
    *why = failure;
    return loaded > 0 ? 0 : -1;
}

#ifndef _WIN32
/* Releases pythonfmu's binary when the shim is unloaded and at exit, whichever comes first.

   pythonfmu 0.7.0 releases its global std::shared_ptr<PyState> twice when its binary is still
   loaded at exit: the C++ static destructor (an exit handler) frees the PyState, then its ELF
   destructor finalizePythonInterpreter() assigns nullptr to the destroyed pointer and frees it
   again: heap corruption, "free(): corrupted unsorted chunks" (NTNU-IHB/PythonFMU#228, #229; seen
   here in fmpy and C hosts alike). dlclose cannot unload that binary (its STB_GNU_UNIQUE symbols
   make it NODELETE), so the shim calls finalizePythonInterpreter() itself while the pointer is
   alive: the PyState is freed once, and the later destructors see nullptr. The exit handler is
   registered after pythonfmu's static destructors (at load), so it runs before them. Python itself
   stays: an interpreter cannot be unloaded. The pool is emptied first while Python is there (a
   Python host has finalized its interpreter before the exit handlers run: then the components
   are left to the end of the process). */
static void unload(void) {
    if (!inner) return;
    if (python_alive()) empty_pool();
    void (*finalize)(void) = (void (*)(void))ftc_library_symbol(inner, "finalizePythonInterpreter");
    if (finalize) finalize();
    ftc_library_close(inner);
    inner = NULL;
}

__attribute__((destructor)) static void unload_with_shim(void) { unload(); }
#endif
