/* SPDX-License-Identifier: BSD-2-Clause */
/* Start-up of the FMU's own CPython runtime (start_python.c). */
#ifndef FTC_START_PYTHON_H
#define FTC_START_PYTHON_H

#include <stddef.h>

/* The runtime's version tag, as in "python311.zip" and "libpython3.11.so.1.0"; the interpreter
   library and its folder below the runtime's home. */
#define FTC_TAG "311"
#ifdef _WIN32
#define FTC_LIBPYTHON "python311.dll"
#define FTC_LIBPYTHON_DIR "/"
#else
#define FTC_LIBPYTHON "libpython3.11.so.1.0"
#define FTC_LIBPYTHON_DIR "/lib/"
#endif

/* Initializes the libpython `python` (a dlopen handle) isolated, with `home` (the runtime's folder)
   as its only module source, then releases the GIL. 0 on success; else -1 and a message. */
int ftc_start_python(void *python, const char *home, char *failure, size_t size);

#endif
