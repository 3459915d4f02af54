/* SPDX-License-Identifier: BSD-2-Clause */
/* The project's portability layer (platform.h): POSIX and Windows. */

#ifndef _WIN32
#define _GNU_SOURCE
#endif
#include "platform.h"

#include <stdio.h>
#include <string.h>

#ifndef _WIN32 /* ---------------------------------------------------------------- POSIX */

#include <dirent.h>
#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <stddef.h>
#include <stdlib.h>
#include <sys/file.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <time.h>
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

/* ---- decoded files in the user's cache (ftc_decoded_file) ---- */

/* FNV-1a, 64 bits, over the bytes of the file `path` (as ftc_cached_copy's key on Windows). */
static int hash_file(const char *path, unsigned long long *h) {
    enum { BLOCK = 1 << 16 };
    unsigned char *block = malloc(BLOCK);
    FILE *f = block ? fopen(path, "rbe") : NULL;
    size_t got;
    while (f && (got = fread(block, 1, BLOCK, f)) > 0)
        for (size_t k = 0; k < got; k++) *h = (*h ^ block[k]) * 1099511628211ull;
    int ok = f && !ferror(f);
    if (f) fclose(f);
    free(block);
    return ok ? 0 : -1;
}

/* The cache's folder for decoded files: $XDG_CACHE_HOME (absolute, as the XDG specification
   wants), else $HOME/.cache; 0, or -1 when neither is set. */
static int cache_base(char *out, size_t size) {
    const char *xdg = getenv("XDG_CACHE_HOME"), *home = getenv("HOME");
    int n = -1;
    if (xdg && xdg[0] == '/') n = snprintf(out, size, "%s/fixed-time-cosim/runtime", xdg);
    else if (home && home[0] == '/') n = snprintf(out, size, "%s/.cache/fixed-time-cosim/runtime", home);
    return n > 0 && (size_t)n < size ? 0 : -1;
}

/* Creates each missing folder of `path` (mode 0700, as a cache's); 0 if it then is a folder. */
static int make_folders(char *path) {
    for (char *p = path + 1; *p; p++)
        if (*p == '/') {
            *p = '\0';
            mkdir(path, 0700);
            *p = '/';
        }
    mkdir(path, 0700);
    return ftc_is_dir(path) ? 0 : -1;
}

/* `packed` decoded into the open file `fd` (closed here), flushed to the disk; 0, -1 or -2 as the
   decoder returns. */
static int decode_into(const char *packed, int fd, ftc_decoder decode, char *why, size_t size) {
    FILE *in = fopen(packed, "rbe"), *out = fdopen(fd, "wb");
    int status;
    if (!in) status = -1, snprintf(why, size, "cannot read it: %s", strerror(errno));
    else if (!out) status = -2, snprintf(why, size, "cannot write the decoded file: %s", strerror(errno));
    else status = decode(in, out, why, size);
    if (status == 0 && fsync(fileno(out)) != 0) /* complete on the disk before its name exists */
        status = -2, snprintf(why, size, "cannot write the decoded file: %s", strerror(errno));
    if (in) fclose(in);
    if (out) {
        if (fclose(out) != 0 && status == 0)
            status = -2, snprintf(why, size, "cannot write the decoded file: %s", strerror(errno));
    } else close(fd);
    return status;
}

/* What a process killed while it decoded leaves (a decode takes a fraction of a second, and a
   private folder of TMPDIR lives until Python has started): the user's own entries of `dir` whose
   names begin with `prefix`, unchanged for STALE_SECONDS, are removed. `inner`: they are folders
   holding only that file (else they are files). So the disk a killed process left is taken back
   by the next decode there. */
enum { STALE_SECONDS = 600 };
static void remove_stale(const char *dir, const char *prefix, const char *inner) {
    DIR *folder = opendir(dir);
    if (!folder) return;
    time_t now = time(NULL);
    size_t n = strlen(prefix);
    struct dirent *entry;
    while ((entry = readdir(folder)) != NULL) {
        char path[FTC_PLATFORM_TEXT], file[FTC_PLATFORM_TEXT];
        struct stat st;
        if (strncmp(entry->d_name, prefix, n) != 0 ||
            (size_t)snprintf(path, sizeof path, "%s/%s", dir, entry->d_name) >= sizeof path ||
            lstat(path, &st) != 0 || st.st_uid != getuid() || now - st.st_mtime < STALE_SECONDS)
            continue;
        if (!inner && S_ISREG(st.st_mode)) unlink(path);
        else if (inner && S_ISDIR(st.st_mode) && (size_t)snprintf(file, sizeof file, "%s/%s", path, inner) < sizeof file) {
            unlink(file);
            rmdir(path); /* only if that was all it held */
        }
    }
    closedir(folder);
}

/* `packed` decoded into <dir>/<name> through a temporary file of `dir`; 0 when <dir>/<name> then
   holds it (ours, or another process's that was first), -1 or -2 as decode_into. */
static int decode_into_cache(const char *packed, const char *name, ftc_decoder decode, char *dir,
                             char *final, size_t size, char *why, size_t why_size) {
    if ((size_t)snprintf(final, size, "%s/%s", dir, name) >= size) return -2;
    if (ftc_is_file(final)) return 0; /* decoded before */
    char part[FTC_PLATFORM_TEXT];
    if (make_folders(dir) != 0 || (size_t)snprintf(part, sizeof part, "%s/.%s.XXXXXX", dir, name) >= sizeof part)
        return -2;
    int fd = mkostemp(part, O_CLOEXEC);
    if (fd < 0) return -2;
    int status = decode_into(packed, fd, decode, why, why_size);
    if (status == 0 && link(part, final) != 0 && errno != EEXIST) /* EEXIST: another was first */
        status = ftc_is_file(final) || rename(part, final) == 0 ? 0 : -2; /* a file system without links */
    unlink(part);
    part[strlen(part) - 6] = '\0'; /* .<name>. : the temporary files of other processes */
    remove_stale(dir, strrchr(part, '/') + 1, NULL);
    return status;
}

int ftc_decoded_file(const char *packed, const char *name, ftc_decoder decode, char *out, size_t size,
                     int *temporary, char *why, size_t why_size) {
    char reason[FTC_PLATFORM_TEXT] = "", dir[FTC_PLATFORM_TEXT], final[FTC_PLATFORM_TEXT];
    unsigned long long h = 14695981039346656037ull;
    *temporary = 0;
    if (hash_file(packed, &h) != 0) {
        snprintf(why, why_size, "%s: cannot read it: %s", packed, strerror(errno));
        return -1;
    }
    int status = -2;
    if (cache_base(dir, sizeof dir) == 0 && strlen(dir) + 20 < sizeof dir) {
        snprintf(dir + strlen(dir), sizeof dir - strlen(dir), "/%016llx", h);
        status = decode_into_cache(packed, name, decode, dir, final, sizeof final, reason, sizeof reason);
    }
    if (status == -2) { /* no usable cache: a private folder, removed once loaded */
        const char *tmp = getenv("TMPDIR");
        remove_stale(tmp && tmp[0] ? tmp : "/tmp", "ftc-runtime-", name);
        snprintf(dir, sizeof dir, "%s/ftc-runtime-XXXXXX", tmp && tmp[0] ? tmp : "/tmp");
        if (!mkdtemp(dir)) {
            snprintf(why, why_size, "%s: no usable cache, and no folder can be made in %s: %s", packed,
                     tmp && tmp[0] ? tmp : "/tmp", strerror(errno));
            return -1;
        }
        snprintf(final, sizeof final, "%s/%s", dir, name);
        int fd = open(final, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
        status = fd < 0 ? -2 : decode_into(packed, fd, decode, reason, sizeof reason);
        if (fd < 0) snprintf(reason, sizeof reason, "cannot write the decoded file: %s", strerror(errno));
        if (status != 0) ftc_remove_temporary(final);
        else *temporary = 1;
    }
    if (status != 0) {
        rmdir(dir); /* the cache's folder of a bad file, if empty */
        snprintf(why, why_size, "%s: %s", packed, reason);
        return -1;
    }
    return (size_t)snprintf(out, size, "%s", final) < size ? 0 : -1;
}

int ftc_process_lock(void) {
    int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd < 0) return -1;
    struct sockaddr_un name = {.sun_family = AF_UNIX}; /* abstract: sun_path[0] is '\0' */
    int n = snprintf(name.sun_path + 1, sizeof name.sun_path - 1, "fixed-time-cosim-runtime-%ld", (long)getpid());
    socklen_t length = (socklen_t)(offsetof(struct sockaddr_un, sun_path) + 1 + (size_t)n);
    struct timespec millisecond = {0, 1000000};
    for (int k = 0; k < 120000; k++) { /* two minutes at most: then without the lock */
        if (bind(fd, (struct sockaddr *)&name, length) == 0) return fd;
        if (errno != EADDRINUSE) break;
        nanosleep(&millisecond, NULL);
    }
    close(fd);
    return -1;
}

void ftc_process_unlock(int lock) {
    if (lock >= 0) close(lock); /* frees the name */
}

void ftc_remove_temporary(const char *path) {
    char dir[FTC_PLATFORM_TEXT];
    snprintf(dir, sizeof dir, "%s", path);
    char *slash = strrchr(dir, '/');
    unlink(path);
    if (slash) {
        *slash = '\0';
        rmdir(dir);
    }
}

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

/* The name a file of the source gets in the copy: `name` without ".xz" when decoded, else itself. */
static const wchar_t *copied_name(const wchar_t *name, ftc_decoder decode, wchar_t *out) {
    size_t n = wcslen(name);
    if (!decode || n <= 3 || _wcsicmp(name + n - 3, L".xz") != 0 || n >= FTC_PLATFORM_TEXT) return name;
    wmemcpy(out, name, n - 3);
    out[n - 3] = L'\0';
    return out;
}

/* A folder of ours that did not become the cache's: its files and folders removed (best effort). */
static void remove_copy(const wchar_t *folder, wchar_t **names, size_t n, ftc_decoder decode) {
    wchar_t path[FTC_PLATFORM_TEXT], plain[FTC_PLATFORM_TEXT];
    for (size_t k = 0; k < n; k++)
        if (_snwprintf(path, FTC_PLATFORM_TEXT, L"%ls/%ls", folder, copied_name(names[k], decode, plain)) > 0)
            DeleteFileW(path);
    if (_snwprintf(path, FTC_PLATFORM_TEXT, L"%ls/.complete", folder) > 0) DeleteFileW(path);
    for (size_t k = n; k-- > 0;) /* the subfolders, deepest first (names are sorted) */
        for (wchar_t *slash = wcsrchr(names[k], L'/'); slash; slash = wcsrchr(names[k], L'/')) {
            *slash = L'\0';
            if (_snwprintf(path, FTC_PLATFORM_TEXT, L"%ls/%ls", folder, names[k]) > 0) RemoveDirectoryW(path);
        }
    RemoveDirectoryW(folder);
}

/* `from` decoded by `decode` into the new file `to`; 0, or -1 (bad input, `why` says so) or -2. */
static int decode_file(const wchar_t *from, const wchar_t *to, ftc_decoder decode, char *why, size_t size) {
    FILE *in = _wfopen(from, L"rb"), *out = in ? _wfopen(to, L"wb") : NULL;
    char reason[FTC_PLATFORM_TEXT] = "cannot read it", source[FTC_PLATFORM_TEXT];
    int status = !in ? -1 : !out ? -2 : decode(in, out, reason, sizeof reason);
    if (out && fclose(out) != 0 && status == 0) status = -2;
    if (in) fclose(in);
    if (status == -1 && narrow(from, source, sizeof source) == 0) snprintf(why, size, "%s: %s", source, reason);
    return status;
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

/* The files `names` of `source` copied (decoded, with `decode`) into `work`; 0, or -1 (a bad
   compressed file: `why` names it) or -2. */
static int copy_files(const wchar_t *source, const wchar_t *work, wchar_t **names, size_t n, ftc_decoder decode,
                      char *why, size_t why_size) {
    wchar_t from[FTC_PLATFORM_TEXT], to[FTC_PLATFORM_TEXT], plain[FTC_PLATFORM_TEXT];
    int status = 0;
    for (size_t k = 0; k < n && status == 0; k++) {
        const wchar_t *name = copied_name(names[k], decode, plain);
        if (_snwprintf(from, FTC_PLATFORM_TEXT, L"%ls/%ls", source, names[k]) < 0 ||
            _snwprintf(to, FTC_PLATFORM_TEXT, L"%ls/%ls", work, name) < 0 || make_folders(to, 1) != 0)
            status = -2;
        else if (name == plain) status = decode_file(from, to, decode, why, why_size);
        else status = CopyFileW(from, to, TRUE) ? 0 : -2;
    }
    return status;
}

/* The files `names` of `source` copied into a folder of this thread, marked complete and renamed
   to `final`; 0 when `final` then holds them (ours, or another process's that was first), -1 (a
   bad compressed file) or -2. */
static int copy_into_place(const wchar_t *source, const wchar_t *final, const wchar_t *marker_path,
                           wchar_t **names, size_t n, ftc_decoder decode, char *why, size_t why_size) {
    wchar_t work[FTC_PLATFORM_TEXT], to[FTC_PLATFORM_TEXT];
    if (_snwprintf(work, FTC_PLATFORM_TEXT, L"%ls.part-%lu-%lu", final, GetCurrentProcessId(),
                   GetCurrentThreadId()) < 0 || make_folders(work, 0) != 0)
        return -2;
    int copied = copy_files(source, work, names, n, decode, why, why_size);
    HANDLE marker = INVALID_HANDLE_VALUE;
    if (copied == 0 && _snwprintf(to, FTC_PLATFORM_TEXT, L"%ls/.complete", work) > 0)
        marker = CreateFileW(to, GENERIC_WRITE, 0, NULL, CREATE_NEW, FILE_ATTRIBUTE_NORMAL, NULL);
    if (marker != INVALID_HANDLE_VALUE) CloseHandle(marker);
    /* into place complete, or another process was first: its copy serves */
    if (marker != INVALID_HANDLE_VALUE && MoveFileExW(work, final, 0)) return 0;
    remove_copy(work, names, n, decode);
    if (copied == -1) return -1;
    return GetFileAttributesW(marker_path) != INVALID_FILE_ATTRIBUTES ? 0 : -2;
}

static int cached_copy(const char *folder, const char *only, ftc_decoder decode, char *out, size_t size, char *why,
                       size_t why_size) {
    wchar_t source[FTC_PLATFORM_TEXT], path[FTC_PLATFORM_TEXT], base[FTC_PLATFORM_TEXT], final[FTC_PLATFORM_TEXT];
    if (!wide(folder, source, FTC_PLATFORM_TEXT) || (only && !wide(only, path, FTC_PLATFORM_TEXT))) return -1;
    DWORD n_base = GetEnvironmentVariableW(L"LOCALAPPDATA", base, FTC_PLATFORM_TEXT);
    if (n_base == 0 || n_base >= FTC_PLATFORM_TEXT - 64) return -1;
    wchar_t **names = calloc(CACHE_FILES, sizeof *names);
    size_t n = 0;
    unsigned long long h = 14695981039346656037ull;
    if (decode) h = fnv(h, "decoded", 8); /* never the key of a plain copy of the same files */
    int status = -1;
    if (names && listed_and_hashed(source, only ? path : NULL, names, &n, &h) == 0 && n > 0 &&
        _snwprintf(final, FTC_PLATFORM_TEXT, L"%ls/fixed-time-cosim/runtime/%016llx", base, h) > 0 &&
        _snwprintf(path, FTC_PLATFORM_TEXT, L"%ls/.complete", final) > 0) {
        if (GetFileAttributesW(path) != INVALID_FILE_ATTRIBUTES) status = 0; /* made before */
        else status = copy_into_place(source, final, path, names, n, decode, why, why_size) == 0 ? 0 : -1;
    }
    for (size_t k = 0; names && k < n; k++) free(names[k]);
    free(names);
    if (status == 0 && narrow(final, out, size) != 0) status = -1;
    return status;
}

int ftc_cached_copy(const char *folder, const char *only, char *out, size_t size) {
    char why[FTC_PLATFORM_TEXT];
    return cached_copy(folder, only, NULL, out, size, why, sizeof why);
}

int ftc_cached_copy_decoded(const char *folder, ftc_decoder decode, char *out, size_t size, char *why,
                            size_t why_size) {
    why[0] = '\0';
    return cached_copy(folder, NULL, decode, out, size, why, why_size);
}

/* The copies of %TEMP% (`temp`, ending in a separator) that ftc_temporary_copy made for processes
   that have ended: each process leaves its own (a loaded DLL cannot be deleted), so each new copy
   first removes those unchanged for ten minutes. python311.dll goes first: Windows refuses while a
   process has it loaded, and then nothing of that copy is touched (its zip is read as it runs). */
static void remove_ended_copies(const wchar_t *temp) {
    const unsigned long long stale = 600ull * 10000000ull; /* ten minutes in FILETIME's 100 ns */
    wchar_t pattern[FTC_PLATFORM_TEXT], folder[FTC_PLATFORM_TEXT], dll[FTC_PLATFORM_TEXT];
    if (_snwprintf(pattern, FTC_PLATFORM_TEXT, L"%lsfixed-time-cosim-*", temp) < 0) return;
    FILETIME now_time;
    GetSystemTimeAsFileTime(&now_time);
    unsigned long long now = (unsigned long long)now_time.dwHighDateTime << 32 | now_time.dwLowDateTime;
    WIN32_FIND_DATAW found;
    HANDLE search = FindFirstFileW(pattern, &found);
    if (search == INVALID_HANDLE_VALUE) return;
    wchar_t **names = calloc(CACHE_FILES, sizeof *names);
    do {
        unsigned long long written =
            (unsigned long long)found.ftLastWriteTime.dwHighDateTime << 32 | found.ftLastWriteTime.dwLowDateTime;
        size_t n = 0;
        if (!names || !(found.dwFileAttributes & FILE_ATTRIBUTE_DIRECTORY) || written > now ||
            now - written < stale || _snwprintf(folder, FTC_PLATFORM_TEXT, L"%ls%ls", temp, found.cFileName) < 0 ||
            _snwprintf(dll, FTC_PLATFORM_TEXT, L"%ls/python311.dll", folder) < 0 ||
            (GetFileAttributesW(dll) != INVALID_FILE_ATTRIBUTES && !DeleteFileW(dll)))
            continue;
        if (collect(folder, L"", names, &n) == 0) {
            qsort(names, n, sizeof *names, by_name);
            remove_copy(folder, names, n, NULL);
        }
        for (size_t k = 0; k < n; k++) free(names[k]);
    } while (FindNextFileW(search, &found));
    free(names);
    FindClose(search);
}

int ftc_temporary_copy(const char *folder, ftc_decoder decode, char *out, size_t size, char *why,
                       size_t why_size) {
    wchar_t source[FTC_PLATFORM_TEXT], temp[FTC_PLATFORM_TEXT], work[FTC_PLATFORM_TEXT];
    why[0] = '\0';
    DWORD n_temp = GetTempPathW(FTC_PLATFORM_TEXT, temp);
    if (n_temp > 0 && n_temp < FTC_PLATFORM_TEXT - 96) remove_ended_copies(temp);
    if (!wide(folder, source, FTC_PLATFORM_TEXT) || n_temp == 0 || n_temp >= FTC_PLATFORM_TEXT - 96 ||
        _snwprintf(work, FTC_PLATFORM_TEXT, L"%lsfixed-time-cosim-%lu-%lu-%llu", temp, GetCurrentProcessId(),
                   GetCurrentThreadId(), (unsigned long long)GetTickCount64()) < 0 ||
        make_folders(work, 0) != 0)
        return -1;
    wchar_t **names = calloc(CACHE_FILES, sizeof *names);
    size_t n = 0;
    int status = names && collect(source, L"", names, &n) == 0 ? copy_files(source, work, names, n, decode, why,
                                                                          why_size)
                                                              : -2;
    if (status != 0) remove_copy(work, names, n, decode);
    for (size_t k = 0; names && k < n; k++) free(names[k]);
    free(names);
    if (status == 0 && narrow(work, out, size) != 0) status = -1;
    return status == 0 ? 0 : -1;
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
