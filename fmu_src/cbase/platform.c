/* SPDX-License-Identifier: BSD-2-Clause */
/* The project's portability layer (platform.h): POSIX and Windows. */

#ifndef _WIN32
#define _GNU_SOURCE
#endif
#include "platform.h"

#include <stdio.h>
#include <string.h>

#ifndef _WIN32 /* ---------------------------------------------------------------- POSIX */

#include <dlfcn.h>
#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

void *ftc_library_open(const char *path, int global) {
    return dlopen(path, RTLD_NOW | (global ? RTLD_GLOBAL : RTLD_LOCAL));
}

void *ftc_library_symbol(void *library, const char *name) { return dlsym(library ? library : RTLD_DEFAULT, name); }

void ftc_library_close(void *library) { dlclose(library); }

const char *ftc_library_error(const char *path) {
    const char *error = dlerror();
    size_t n = path ? strlen(path) : 0;
    if (!error) return "unknown error";
    if (n && strncmp(error, path, n) == 0 && strncmp(error + n, ": ", 2) == 0) return error + n + 2;
    return error;
}

void *ftc_library_loaded(const char *name) { return dlopen(name, RTLD_NOW | RTLD_NOLOAD); }

int ftc_library_file(const void *address, char *out, size_t size) {
    Dl_info info;
    if (!dladdr(address, &info) || !info.dli_fname || !info.dli_fname[0]) return -1;
    return (size_t)snprintf(out, size, "%s", info.dli_fname) < size ? 0 : -1;
}

int ftc_is_file(const char *path) {
    struct stat info;
    return path && stat(path, &info) == 0 && S_ISREG(info.st_mode);
}

int ftc_is_dir(const char *path) {
    struct stat info;
    return path && stat(path, &info) == 0 && S_ISDIR(info.st_mode);
}

FILE *ftc_fopen(const char *path, const char *mode) { return fopen(path, mode); }

int ftc_file_lock(const char *path) {
    int lock = open(path, O_RDONLY | O_CLOEXEC);
    if (lock >= 0) flock(lock, LOCK_EX);
    return lock;
}

void ftc_file_unlock(int lock) {
    if (lock >= 0) close(lock); /* releases the lock */
}

int ftc_ascii_path(const char *path, char *out, size_t size) {
    return (size_t)snprintf(out, size, "%s", path) < size ? 0 : -1;
}

void ftc_standard_streams(void *python, int saved[3]) {
    (void)python;
    saved[0] = saved[1] = saved[2] = -1;
}

void ftc_standard_streams_done(int saved[3]) { (void)saved; }

#else /* ---------------------------------------------------------------------- Windows */

#include <stdint.h>
#include <stdlib.h>
#include <wchar.h>
#include <windows.h>
#include <psapi.h>

void ftc_lock(ftc_mutex *mutex) { AcquireSRWLockExclusive((PSRWLOCK)mutex); }
void ftc_unlock(ftc_mutex *mutex) { ReleaseSRWLockExclusive((PSRWLOCK)mutex); }

/* UTF-8 -> UTF-16 (with '/' kept: Windows accepts both separators); NULL if invalid or too long. */
static wchar_t *wide(const char *path, wchar_t *out, int size) {
    if (!path || MultiByteToWideChar(CP_UTF8, MB_ERR_INVALID_CHARS, path, -1, out, size) == 0) return NULL;
    return out;
}

/* UTF-16 -> UTF-8 with '\' turned into '/'; 0 on success. */
static int narrow(const wchar_t *path, char *out, size_t size) {
    if (WideCharToMultiByte(CP_UTF8, 0, path, -1, out, (int)size, NULL, NULL) == 0) return -1;
    for (char *p = out; *p; p++)
        if (*p == '\\') *p = '/';
    return 0;
}

static char error_text[FTC_PLATFORM_TEXT];

void *ftc_library_open(const char *path, int global) {
    (void)global; /* a DLL's exports are always its own */
    wchar_t w[FTC_PLATFORM_TEXT];
    if (!wide(path, w, FTC_PLATFORM_TEXT)) {
        SetLastError(ERROR_BAD_PATHNAME);
        return NULL;
    }
    /* an absolute path: the DLL's own folder is searched first for what it imports */
    return (void *)LoadLibraryExW(w, NULL, LOAD_WITH_ALTERED_SEARCH_PATH);
}

void *ftc_library_symbol(void *library, const char *name) {
    if (library) return (void *)GetProcAddress((HMODULE)library, name);
    HMODULE modules[1024];
    DWORD needed = 0;
    if (!K32EnumProcessModules(GetCurrentProcess(), modules, sizeof modules, &needed)) return NULL;
    DWORD n = needed / sizeof modules[0];
    for (DWORD k = 0; k < n && k < 1024; k++) {
        FARPROC found = GetProcAddress(modules[k], name);
        if (found) return (void *)found;
    }
    return NULL;
}

void ftc_library_close(void *library) { FreeLibrary((HMODULE)library); }

const char *ftc_library_error(const char *path) {
    (void)path;
    DWORD code = GetLastError();
    DWORD n = FormatMessageA(FORMAT_MESSAGE_FROM_SYSTEM | FORMAT_MESSAGE_IGNORE_INSERTS, NULL, code, 0, error_text,
                             sizeof error_text, NULL);
    while (n && (error_text[n - 1] == '\n' || error_text[n - 1] == '\r' || error_text[n - 1] == ' '))
        error_text[--n] = '\0';
    if (!n) snprintf(error_text, sizeof error_text, "Windows error %lu", (unsigned long)code);
    return error_text;
}

void *ftc_library_loaded(const char *name) {
    wchar_t w[FTC_PLATFORM_TEXT];
    return wide(name, w, FTC_PLATFORM_TEXT) ? (void *)GetModuleHandleW(w) : NULL;
}

int ftc_library_file(const void *address, char *out, size_t size) {
    HMODULE module;
    if (!GetModuleHandleExW(GET_MODULE_HANDLE_EX_FLAG_FROM_ADDRESS | GET_MODULE_HANDLE_EX_FLAG_UNCHANGED_REFCOUNT,
                            (LPCWSTR)address, &module))
        return -1;
    wchar_t w[FTC_PLATFORM_TEXT];
    DWORD n = GetModuleFileNameW(module, w, FTC_PLATFORM_TEXT);
    if (n == 0 || n >= FTC_PLATFORM_TEXT) return -1;
    return narrow(w, out, size);
}

static DWORD attributes(const char *path) {
    wchar_t w[FTC_PLATFORM_TEXT];
    return wide(path, w, FTC_PLATFORM_TEXT) ? GetFileAttributesW(w) : INVALID_FILE_ATTRIBUTES;
}

int ftc_is_file(const char *path) {
    DWORD a = attributes(path);
    return a != INVALID_FILE_ATTRIBUTES && !(a & FILE_ATTRIBUTE_DIRECTORY);
}

int ftc_is_dir(const char *path) {
    DWORD a = attributes(path);
    return a != INVALID_FILE_ATTRIBUTES && (a & FILE_ATTRIBUTE_DIRECTORY);
}

FILE *ftc_fopen(const char *path, const char *mode) {
    wchar_t w[FTC_PLATFORM_TEXT], m[16];
    if (!wide(path, w, FTC_PLATFORM_TEXT) || !wide(mode, m, 16)) return NULL;
    return _wfopen(w, m);
}

int ftc_file_lock(const char *path) {
    wchar_t w[FTC_PLATFORM_TEXT];
    if (!wide(path, w, FTC_PLATFORM_TEXT)) return -1;
    HANDLE file = CreateFileW(w, GENERIC_READ, FILE_SHARE_READ | FILE_SHARE_WRITE | FILE_SHARE_DELETE, NULL,
                              OPEN_EXISTING, FILE_ATTRIBUTE_NORMAL, NULL);
    if (file == INVALID_HANDLE_VALUE) return -1;
    OVERLAPPED whole = {0};
    LockFileEx(file, LOCKFILE_EXCLUSIVE_LOCK, 0, 1, 0, &whole);
    return (int)(intptr_t)file;
}

void ftc_file_unlock(int lock) {
    if (lock == -1) return;
    HANDLE file = (HANDLE)(intptr_t)lock;
    OVERLAPPED whole = {0};
    UnlockFileEx(file, 0, 1, 0, &whole);
    CloseHandle(file);
}

void ftc_keep_files(const char *dir) {
    wchar_t folder[FTC_PLATFORM_TEXT], pattern[FTC_PLATFORM_TEXT], file[FTC_PLATFORM_TEXT];
    if (!wide(dir, folder, FTC_PLATFORM_TEXT) || _snwprintf(pattern, FTC_PLATFORM_TEXT, L"%ls/*", folder) < 0) return;
    WIN32_FIND_DATAW found;
    HANDLE search = FindFirstFileW(pattern, &found);
    if (search == INVALID_HANDLE_VALUE) return;
    do {
        const wchar_t *dot = wcsrchr(found.cFileName, L'.');
        if ((found.dwFileAttributes & FILE_ATTRIBUTE_DIRECTORY) || !dot ||
            (_wcsicmp(dot, L".dll") != 0 && _wcsicmp(dot, L".pyd") != 0) ||
            _snwprintf(file, FTC_PLATFORM_TEXT, L"%ls/%ls", folder, found.cFileName) < 0)
            continue;
        /* kept open on purpose: the handle lives as long as the module it guards */
        CreateFileW(file, GENERIC_READ, FILE_SHARE_READ | FILE_SHARE_WRITE, NULL, OPEN_EXISTING,
                    FILE_ATTRIBUTE_NORMAL, NULL);
    } while (FindNextFileW(search, &found));
    FindClose(search);
}

/* ---- the user's cache of runtime files (ftc_cached_copy) ---- */

#define CACHE_FILES 4096

static int by_name(const void *a, const void *b) { return wcscmp(*(wchar_t *const *)a, *(wchar_t *const *)b); }

/* FNV-1a, 64 bits, over `n` bytes. */
static unsigned long long fnv(unsigned long long h, const void *bytes, size_t n) {
    for (const unsigned char *p = bytes; n--; p++) h = (h ^ *p) * 1099511628211ull;
    return h;
}

static int hash_file(const wchar_t *path, unsigned long long *h) {
    enum { BLOCK = 1 << 16 };
    unsigned char *block = malloc(BLOCK); /* hosts instantiate from any thread */
    HANDLE f = block ? CreateFileW(path, GENERIC_READ, FILE_SHARE_READ | FILE_SHARE_WRITE | FILE_SHARE_DELETE, NULL,
                                   OPEN_EXISTING, FILE_ATTRIBUTE_NORMAL, NULL)
                     : INVALID_HANDLE_VALUE;
    DWORD got = 0;
    BOOL ok = f != INVALID_HANDLE_VALUE;
    while (ok && (ok = ReadFile(f, block, BLOCK, &got, NULL)) && got) *h = fnv(*h, block, got);
    if (f != INVALID_HANDLE_VALUE) CloseHandle(f);
    free(block);
    return ok ? 0 : -1;
}

/* Creates each missing folder of `path` (and the one of its last separator when `parent_only`);
   0 if it then exists. */
static int make_folders(wchar_t *path, int parent_only) {
    for (wchar_t *p = path + 3; *p; p++)
        if (*p == L'/' || *p == L'\\') {
            wchar_t kept = *p;
            *p = L'\0';
            CreateDirectoryW(path, NULL);
            *p = kept;
        }
    if (parent_only) return 0;
    CreateDirectoryW(path, NULL);
    DWORD a = GetFileAttributesW(path);
    return a != INVALID_FILE_ATTRIBUTES && (a & FILE_ATTRIBUTE_DIRECTORY) ? 0 : -1;
}

/* The files under `root`/`relative` (relative paths with '/'), appended to `names`; 0, or -1. */
static int collect(const wchar_t *root, const wchar_t *relative, wchar_t **names, size_t *n) {
    wchar_t pattern[FTC_PLATFORM_TEXT], path[FTC_PLATFORM_TEXT];
    if (_snwprintf(pattern, FTC_PLATFORM_TEXT, L"%ls%ls%ls/*", root, relative[0] ? L"/" : L"", relative) < 0)
        return -1;
    WIN32_FIND_DATAW found;
    HANDLE search = FindFirstFileW(pattern, &found);
    if (search == INVALID_HANDLE_VALUE) return -1;
    int failed = 0;
    do {
        if (!wcscmp(found.cFileName, L".") || !wcscmp(found.cFileName, L"..")) continue;
        if (_snwprintf(path, FTC_PLATFORM_TEXT, L"%ls%ls%ls", relative, relative[0] ? L"/" : L"", found.cFileName) < 0)
            failed = 1;
        else if (found.dwFileAttributes & FILE_ATTRIBUTE_DIRECTORY) failed = collect(root, path, names, n);
        else if (*n < CACHE_FILES && (names[*n] = _wcsdup(path))) ++*n;
        else failed = 1;
    } while (!failed && FindNextFileW(search, &found));
    FindClose(search);
    return failed ? -1 : 0;
}

/* A folder of ours that did not become the cache's: its files and folders removed (best effort). */
static void remove_copy(const wchar_t *folder, wchar_t **names, size_t n) {
    wchar_t path[FTC_PLATFORM_TEXT];
    for (size_t k = 0; k < n; k++)
        if (_snwprintf(path, FTC_PLATFORM_TEXT, L"%ls/%ls", folder, names[k]) > 0) DeleteFileW(path);
    if (_snwprintf(path, FTC_PLATFORM_TEXT, L"%ls/.complete", folder) > 0) DeleteFileW(path);
    for (size_t k = n; k-- > 0;) /* the subfolders, deepest first (names are sorted) */
        for (wchar_t *slash = wcsrchr(names[k], L'/'); slash; slash = wcsrchr(names[k], L'/')) {
            *slash = L'\0';
            if (_snwprintf(path, FTC_PLATFORM_TEXT, L"%ls/%ls", folder, names[k]) > 0) RemoveDirectoryW(path);
        }
    RemoveDirectoryW(folder);
}

/* The files to copy (`only`, or every file under `source`), sorted, in `names` (`*n` of them), and
   the FNV-1a hash of their names and bytes in `*h`; 0, or -1. */
static int listed_and_hashed(const wchar_t *source, const wchar_t *only, wchar_t **names, size_t *n,
                             unsigned long long *h) {
    wchar_t from[FTC_PLATFORM_TEXT];
    int failed = 0;
    if (only) failed = !(names[(*n)++] = _wcsdup(only));
    else failed = collect(source, L"", names, n);
    if (failed) return -1;
    qsort(names, *n, sizeof *names, by_name);
    for (size_t k = 0; k < *n && !failed; k++) {
        *h = fnv(*h, names[k], (wcslen(names[k]) + 1) * sizeof(wchar_t));
        failed = _snwprintf(from, FTC_PLATFORM_TEXT, L"%ls/%ls", source, names[k]) < 0 || hash_file(from, h);
    }
    return failed ? -1 : 0;
}

/* The files `names` of `source` copied into a folder of this thread, marked complete and renamed
   to `final`; 0 when `final` then holds them (ours, or another process's that was first). */
static int copy_into_place(const wchar_t *source, const wchar_t *final, const wchar_t *marker_path,
                           wchar_t **names, size_t n) {
    wchar_t work[FTC_PLATFORM_TEXT], from[FTC_PLATFORM_TEXT], to[FTC_PLATFORM_TEXT];
    if (_snwprintf(work, FTC_PLATFORM_TEXT, L"%ls.part-%lu-%lu", final, GetCurrentProcessId(),
                   GetCurrentThreadId()) < 0 || make_folders(work, 0) != 0)
        return -1;
    int copied = 1;
    for (size_t k = 0; k < n && copied; k++)
        copied = _snwprintf(from, FTC_PLATFORM_TEXT, L"%ls/%ls", source, names[k]) > 0 &&
                 _snwprintf(to, FTC_PLATFORM_TEXT, L"%ls/%ls", work, names[k]) > 0 && make_folders(to, 1) == 0 &&
                 CopyFileW(from, to, TRUE);
    HANDLE marker = INVALID_HANDLE_VALUE;
    if (copied && _snwprintf(to, FTC_PLATFORM_TEXT, L"%ls/.complete", work) > 0)
        marker = CreateFileW(to, GENERIC_WRITE, 0, NULL, CREATE_NEW, FILE_ATTRIBUTE_NORMAL, NULL);
    if (marker != INVALID_HANDLE_VALUE) CloseHandle(marker);
    /* into place complete, or another process was first: its copy serves */
    if (marker != INVALID_HANDLE_VALUE && MoveFileExW(work, final, 0)) return 0;
    remove_copy(work, names, n);
    return GetFileAttributesW(marker_path) != INVALID_FILE_ATTRIBUTES ? 0 : -1;
}

int ftc_cached_copy(const char *folder, const char *only, char *out, size_t size) {
    wchar_t source[FTC_PLATFORM_TEXT], path[FTC_PLATFORM_TEXT], base[FTC_PLATFORM_TEXT], final[FTC_PLATFORM_TEXT];
    if (!wide(folder, source, FTC_PLATFORM_TEXT) || (only && !wide(only, path, FTC_PLATFORM_TEXT))) return -1;
    DWORD n_base = GetEnvironmentVariableW(L"LOCALAPPDATA", base, FTC_PLATFORM_TEXT);
    if (n_base == 0 || n_base >= FTC_PLATFORM_TEXT - 64) return -1;
    wchar_t **names = calloc(CACHE_FILES, sizeof *names);
    size_t n = 0;
    unsigned long long h = 14695981039346656037ull;
    int status = -1;
    if (names && listed_and_hashed(source, only ? path : NULL, names, &n, &h) == 0 && n > 0 &&
        _snwprintf(final, FTC_PLATFORM_TEXT, L"%ls/fixed-time-cosim/runtime/%016llx", base, h) > 0 &&
        _snwprintf(path, FTC_PLATFORM_TEXT, L"%ls/.complete", final) > 0) {
        if (GetFileAttributesW(path) != INVALID_FILE_ATTRIBUTES) status = 0; /* made before */
        else status = copy_into_place(source, final, path, names, n);
    }
    for (size_t k = 0; names && k < n; k++) free(names[k]);
    free(names);
    if (status == 0 && narrow(final, out, size) != 0) status = -1;
    return status;
}

/* The shim's own file, opened without FILE_SHARE_DELETE while the shim is loaded (ftc_keep_own_file):
   closed when the host unloads it. */
static HANDLE own_file = INVALID_HANDLE_VALUE;

void ftc_keep_own_file(const char *path) {
    wchar_t w[FTC_PLATFORM_TEXT];
    if (own_file == INVALID_HANDLE_VALUE && wide(path, w, FTC_PLATFORM_TEXT))
        own_file = CreateFileW(w, GENERIC_READ, FILE_SHARE_READ | FILE_SHARE_WRITE, NULL, OPEN_EXISTING,
                               FILE_ATTRIBUTE_NORMAL, NULL);
}

BOOL WINAPI DllMain(HINSTANCE instance, DWORD reason, LPVOID reserved);
BOOL WINAPI DllMain(HINSTANCE instance, DWORD reason, LPVOID reserved) {
    (void)instance, (void)reserved;
    if (reason == DLL_PROCESS_DETACH && own_file != INVALID_HANDLE_VALUE) { /* CloseHandle: safe here */
        CloseHandle(own_file);
        own_file = INVALID_HANDLE_VALUE;
    }
    return TRUE;
}

static int is_ascii(const char *text) {
    for (; *text; text++)
        if ((unsigned char)*text > 127) return 0;
    return 1;
}

int ftc_ascii_path(const char *path, char *out, size_t size) {
    if (is_ascii(path)) return (size_t)snprintf(out, size, "%s", path) < size ? 0 : -1;
    wchar_t w[FTC_PLATFORM_TEXT], s[FTC_PLATFORM_TEXT];
    DWORD n = wide(path, w, FTC_PLATFORM_TEXT) ? GetShortPathNameW(w, s, FTC_PLATFORM_TEXT) : 0;
    if (n == 0 || n >= FTC_PLATFORM_TEXT || narrow(s, out, size) != 0) return -1;
    return is_ascii(out) ? 0 : -1;
}

/* The Universal C Runtime's descriptor functions (the CRT python311.dll uses; the shim's own is
   msvcrt.dll, whose descriptors are others). */
typedef void (*ftc_iph)(const wchar_t *, const wchar_t *, const wchar_t *, unsigned, uintptr_t);
static void ignore_parameter(const wchar_t *a, const wchar_t *b, const wchar_t *c, unsigned d, uintptr_t e) {
    (void)a, (void)b, (void)c, (void)d, (void)e;
}
static struct {
    intptr_t (*get_handle)(int);
    int (*open_w)(const wchar_t *, int, ...);
    int (*dup)(int);
    int (*dup2)(int, int);
    int (*close)(int);
    ftc_iph (*set_handler)(ftc_iph);
} crt;

static int find_crt(void) {
    HMODULE m = GetModuleHandleW(L"ucrtbase.dll");
    if (!m) return 0;
#define CRT(field, name) *(void **)&crt.field = (void *)GetProcAddress(m, name)
    CRT(get_handle, "_get_osfhandle");
    CRT(open_w, "_wopen");
    CRT(dup, "_dup");
    CRT(dup2, "_dup2");
    CRT(close, "_close");
    CRT(set_handler, "_set_thread_local_invalid_parameter_handler");
#undef CRT
    return crt.get_handle && crt.open_w && crt.dup && crt.dup2 && crt.close && crt.set_handler;
}

/* What CPython's start asks of a standard descriptor (_Py_fstat: GetFileType, and for a file
   GetFileInformationByHandle): 0 absent (a GUI process), 1 unusable at start (a console
   process's file under wine, opened without the right to read its attributes), 2 usable. */
static int usable(intptr_t h) {
    if (h == -1 || h == -2 || h == 0) return 0;
    SetLastError(0);
    DWORD type = GetFileType((HANDLE)h);
    if (type == FILE_TYPE_UNKNOWN && GetLastError() != 0) return 0;
    BY_HANDLE_FILE_INFORMATION info;
    if (type == FILE_TYPE_DISK && !GetFileInformationByHandle((HANDLE)h, &info)) return 1;
    return 2;
}

void ftc_standard_streams(void *python, int saved[3]) {
    (void)python;
    saved[0] = saved[1] = saved[2] = -1;
    if (!find_crt()) return;
    ftc_iph previous = crt.set_handler(ignore_parameter); /* a closed descriptor must not end the process */
    for (int fd = 0; fd < 3; fd++) {
        int state = usable(crt.get_handle(fd));
        if (state == 2) continue;
        if (state == 1) saved[fd] = crt.dup(fd); /* given back after the start */
        int null = crt.open_w(L"NUL", fd == 0 ? 0 /* _O_RDONLY */ : 1 /* _O_WRONLY */);
        if (null < 0) continue;
        if (null != fd) {
            crt.dup2(null, fd);
            crt.close(null);
        }
    }
    crt.set_handler(previous);
}

void ftc_standard_streams_done(int saved[3]) {
    for (int fd = 0; fd < 3; fd++)
        if (saved[fd] >= 0) {
            crt.dup2(saved[fd], fd); /* Python's sys.stdout writes to descriptor 1: the host's again */
            crt.close(saved[fd]);
        }
}

#endif
