/* SPDX-License-Identifier: BSD-2-Clause */
/* The engine's C portability layer (platform.h): POSIX and Windows. */

#ifndef _WIN32
#define _GNU_SOURCE
#endif
#include "platform.h"

#include <stdio.h>

#ifndef _WIN32 /* ---------------------------------------------------------------- POSIX */

#include <dlfcn.h>

/* A shared library loaded with its symbols kept to itself (RTLD_LOCAL); NULL on failure. */
void *ftc_library_open(const char *path) { return dlopen(path, RTLD_NOW | RTLD_LOCAL); }

void *ftc_library_symbol(void *library, const char *name) { return dlsym(library, name); }

/* Why the last ftc_library_open failed, in `out`. */
const char *ftc_library_error(char *out, size_t size) {
    const char *error = dlerror();
    snprintf(out, size, "%s", error ? error : "unknown error");
    return out;
}

/* The file of the shared library that holds `address` (a function of it); 0 on success. */
int ftc_library_file(const void *address, char *out, size_t size) {
    Dl_info info;
    if (!dladdr(address, &info) || !info.dli_fname || !info.dli_fname[0]) return -1;
    return (size_t)snprintf(out, size, "%s", info.dli_fname) < size ? 0 : -1;
}

FILE *ftc_fopen(const char *path, const char *mode) { return fopen(path, mode); }

#else /* ---------------------------------------------------------------------- Windows */

#include <windows.h>

#define FTC_WIDE 4096

/* UTF-8 -> UTF-16 ('/' kept: Windows accepts both separators); NULL if invalid or too long. */
static wchar_t *ftc_wide(const char *path, wchar_t *out, int size) {
    if (!path || MultiByteToWideChar(CP_UTF8, MB_ERR_INVALID_CHARS, path, -1, out, size) == 0) return NULL;
    return out;
}

void *ftc_library_open(const char *path) {
    wchar_t w[FTC_WIDE];
    if (!ftc_wide(path, w, FTC_WIDE)) {
        SetLastError(ERROR_BAD_PATHNAME);
        return NULL;
    }
    /* an absolute path: the DLL's own folder is searched first for what it imports */
    return (void *)LoadLibraryExW(w, NULL, LOAD_WITH_ALTERED_SEARCH_PATH);
}

void *ftc_library_symbol(void *library, const char *name) {
    return (void *)GetProcAddress((HMODULE)library, name);
}

const char *ftc_library_error(char *out, size_t size) {
    DWORD code = GetLastError();
    DWORD n = FormatMessageA(FORMAT_MESSAGE_FROM_SYSTEM | FORMAT_MESSAGE_IGNORE_INSERTS, NULL, code, 0, out,
                             (DWORD)size, NULL);
    while (n && (out[n - 1] == '\n' || out[n - 1] == '\r' || out[n - 1] == ' ' || out[n - 1] == '.'))
        out[--n] = '\0';
    if (!n) snprintf(out, size, "Windows error %lu", (unsigned long)code);
    return out;
}

/* The module holding `address`, its file name in UTF-8 with '\' turned into '/'. */
int ftc_library_file(const void *address, char *out, size_t size) {
    HMODULE module;
    if (!GetModuleHandleExW(GET_MODULE_HANDLE_EX_FLAG_FROM_ADDRESS | GET_MODULE_HANDLE_EX_FLAG_UNCHANGED_REFCOUNT,
                            (LPCWSTR)address, &module))
        return -1;
    wchar_t w[FTC_WIDE];
    DWORD n = GetModuleFileNameW(module, w, FTC_WIDE);
    if (n == 0 || n >= FTC_WIDE) return -1;
    if (WideCharToMultiByte(CP_UTF8, 0, w, -1, out, (int)size, NULL, NULL) == 0) return -1;
    for (char *p = out; *p; p++)
        if (*p == '\\') *p = '/';
    return 0;
}

FILE *ftc_fopen(const char *path, const char *mode) {
    wchar_t w[FTC_WIDE], m[16];
    if (!ftc_wide(path, w, FTC_WIDE) || !ftc_wide(mode, m, 16)) return NULL;
    return _wfopen(w, m);
}

#endif

