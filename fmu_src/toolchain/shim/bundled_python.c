/* SPDX-License-Identifier: BSD-2-Clause */
/* The FMUs' bundled CPython as a command, for the build only (fmu_src/toolchain/runtime.py, Runtime.run):

       bundled_python LIBPYTHON FALLBACK_DIR [python arguments...]

   The build compiles the FMUs' bytecode and finds their standard-library closure with the very
   interpreter the FMUs carry, never with the Python that runs the build: the same sources then
   give the same bytes whether the build runs on Python 3.10, 3.11, 3.12 or 3.13. Debian's
   packages have no python3.11 command beside the shared libpython, so this one is it: it loads
   zlib and expat as the shim does (the machine's own, else FALLBACK_DIR's from the packages),
   then LIBPYTHON globally, and hands the remaining arguments to Py_BytesMain. Linux only, like
   the build; it links no libpython, so it needs no Python headers. */

#include <dlfcn.h>
#include <stdio.h>

static void *load(const char *soname, const char *folder) {
    void *handle = dlopen(soname, RTLD_NOW | RTLD_GLOBAL);
    if (!handle) {
        char path[4096];
        snprintf(path, sizeof path, "%s/%s", folder, soname);
        handle = dlopen(path, RTLD_NOW | RTLD_GLOBAL);
    }
    if (!handle) fprintf(stderr, "bundled_python: cannot load %s: %s\n", soname, dlerror());
    return handle;
}

int main(int argc, char **argv) {
    if (argc < 3) {
        fprintf(stderr, "usage: bundled_python LIBPYTHON FALLBACK_DIR [python arguments...]\n");
        return 2;
    }
    if (!load("libz.so.1", argv[2]) || !load("libexpat.so.1", argv[2])) return 2;
    void *python = dlopen(argv[1], RTLD_NOW | RTLD_GLOBAL);
    if (!python) {
        fprintf(stderr, "bundled_python: cannot load %s\n", dlerror());
        return 2;
    }
    int (*bytes_main)(int, char **) = (int (*)(int, char **))dlsym(python, "Py_BytesMain");
    if (!bytes_main) {
        fprintf(stderr, "bundled_python: %s has no Py_BytesMain\n", argv[1]);
        return 2;
    }
    argv[2] = argv[0]; /* Python sees: <this command> [python arguments...] */
    return bytes_main(argc - 2, argv + 2);
}
