/* SPDX-License-Identifier: BSD-2-Clause */
/* The engine's C portability layer: every call to the operating system the container and the core
   make (loading an embedded FMU's library, finding a symbol, the last loader error, finding the
   container's own file, opening the plan) goes through these few functions, so container.c, core.c
   and plan.c have no branch per platform. Two branches: POSIX (Linux, glibc) and Windows (64-bit,
   cross-compiled with mingw-w64). Paths are UTF-8 with '/' on both: the Windows branch converts to
   and from UTF-16 at the system call. Modelled on the FMU shim's own layer
   (fmu_src/toolchain/shim/platform.c), which the engine does not import. */

#ifndef FTC_NATIVE_PLATFORM_H
#define FTC_NATIVE_PLATFORM_H

#include <stddef.h>
#include <stdio.h>

/* A shared library loaded with its symbols kept to itself (POSIX: RTLD_LOCAL; Windows: an absolute
   path, whose folder is searched first for what the library imports); NULL on failure. */
void *ftc_library_open(const char *path);
void *ftc_library_symbol(void *library, const char *name);

/* Why the last ftc_library_open failed, written into `out` (returned). */
const char *ftc_library_error(char *out, size_t size);

/* The file of the shared library that holds `address` (a function of it); 0 on success. */
int ftc_library_file(const void *address, char *out, size_t size);

/* fopen for a UTF-8 path. */
FILE *ftc_fopen(const char *path, const char *mode);

#endif
