/* The shim's portability layer: every call to the operating system (loading libraries, finding
   the shim's own file, locks, file tests) goes through these few functions, so that a port adds
   one branch here (platform.c) and nothing in the FMI code. Today: POSIX (Linux, glibc). */

#ifndef FTC_PLATFORM_H
#define FTC_PLATFORM_H

#include <stddef.h>

#define FTC_PLATFORM_TEXT 4096

/* Shared libraries: load (global: its symbols serve libraries loaded later), find a symbol (NULL
   library: every library of the process), unload. ftc_library_error: the last failure, without a
   leading "<path>: ". */
void *ftc_library_open(const char *path, int global);
void *ftc_library_symbol(void *library, const char *name);
void ftc_library_close(void *library);
const char *ftc_library_error(const char *path);

/* The file of the shared library that holds `address` (a function of it); 0 on success. */
int ftc_library_file(const void *address, char *out, size_t size);

/* Whether `path` is a regular file, a folder. */
int ftc_is_file(const char *path);
int ftc_is_dir(const char *path);

/* An exclusive lock on a file shared by every process and library that opens it; -1 if the file
   cannot be opened (then nothing is locked). */
int ftc_file_lock(const char *path);
void ftc_file_unlock(int lock);

/* A mutex usable from any thread, statically initialized. */
#include <pthread.h>
typedef pthread_mutex_t ftc_mutex;
#define FTC_MUTEX_INIT PTHREAD_MUTEX_INITIALIZER
#define ftc_lock(m) pthread_mutex_lock(m)
#define ftc_unlock(m) pthread_mutex_unlock(m)

#endif
