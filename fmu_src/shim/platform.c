/* The shim's portability layer (platform.h): POSIX. */

#define _GNU_SOURCE
#include "platform.h"

#include <dlfcn.h>
#include <fcntl.h>
#include <stdio.h>
#include <string.h>
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

int ftc_file_lock(const char *path) {
    int lock = open(path, O_RDONLY | O_CLOEXEC);
    if (lock >= 0) flock(lock, LOCK_EX);
    return lock;
}

void ftc_file_unlock(int lock) {
    if (lock >= 0) close(lock); /* releases the lock */
}
