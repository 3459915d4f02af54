/* SPDX-License-Identifier: BSD-2-Clause */
/* The project's C portability layer (fmu_src/cbase, below the FMUs' shim and the engine's C code:
   see fmu_src/cbase/README.md): every call to the operating system (loading libraries, finding a
   library's own file, locks, file tests, opening files) goes through these few functions, so that
   the FMI code has no branch per platform. Some (the user's cache, the standard streams, ASCII
   paths) only the shim uses. Two branches here (platform.c): POSIX (Linux,
   glibc) and Windows (64-bit, cross-compiled with mingw-w64). Paths are UTF-8 with '/' on both:
   the Windows branch converts to and from UTF-16 at the system call. */

#ifndef FTC_PLATFORM_H
#define FTC_PLATFORM_H

#include <stddef.h>
#include <stdio.h>

#define FTC_PLATFORM_TEXT 4096

/* What the shim exports (the FMI functions). */
#ifdef _WIN32
#define FTC_EXPORT __declspec(dllexport)
#else
#define FTC_EXPORT __attribute__((visibility("default")))
#endif

/* Shared libraries: load (global: its symbols serve libraries loaded later; Windows has no such
   thing), find a symbol (NULL library: every library of the process), unload.
   ftc_library_error: the last failure, without a leading "<path>: ". ftc_library_loaded: the
   library of that file name if the process has it, else NULL (nothing is loaded). */
void *ftc_library_open(const char *path, int global);
void *ftc_library_symbol(void *library, const char *name);
void ftc_library_close(void *library);
const char *ftc_library_error(const char *path);
void *ftc_library_loaded(const char *name);

/* The file of the shared library that holds `address` (a function of it); 0 on success. */
int ftc_library_file(const void *address, char *out, size_t size);

/* Whether `path` is a regular file, a folder; fopen for a UTF-8 path. */
int ftc_is_file(const char *path);
int ftc_is_dir(const char *path);
FILE *ftc_fopen(const char *path, const char *mode);

/* An exclusive lock on a file shared by every process and library that opens it; -1 if the file
   cannot be opened (then nothing is locked). (A Windows HANDLE fits an int: Windows keeps handle
   values in 32 bits for 32/64-bit interoperability.) */
int ftc_file_lock(const char *path);
void ftc_file_unlock(int lock);

/* A decoder of a compressed file (the shim's ftc_xz_decode): `in` decoded into `out`; 0, or what
   failed in `why` and -1 (the input is bad: nothing else will decode it) or -2 (the output cannot
   be written: another place may serve). */
typedef int (*ftc_decoder)(FILE *in, FILE *out, char *why, size_t size);

#ifndef _WIN32
/* POSIX: the file `packed` decoded by `decode` into the user's cache once,
   $XDG_CACHE_HOME/fixed-time-cosim/runtime/<key>/<name> (else ~/.cache/...), where <key> is a
   64-bit FNV-1a hash of `packed`'s bytes: decoded into a temporary file of that folder and linked
   into place complete, so that processes racing all succeed and none ever sees half a file. Where
   there is no usable cache (no HOME, a read-only or full disk), into a new private folder of
   $TMPDIR (else /tmp) instead, and `*temporary` is 1: the caller removes it with
   ftc_remove_temporary once it has loaded the file (Linux keeps the mapping). Writes the decoded
   file's path to `out`; 0, or -1 and one message naming `packed` in `why`. */
int ftc_decoded_file(const char *packed, const char *name, ftc_decoder decode, char *out, size_t size,
                     int *temporary, char *why, size_t why_size);
void ftc_remove_temporary(const char *path);

/* POSIX: a lock every library of the process shares (the shims of all FMUs: an abstract Unix
   socket named after the process, nothing on the disk), so that of FMUs instantiated at once in
   several threads one decodes and loads libpython and the others then find it; -1 if it cannot
   be had (then nothing is locked). */
int ftc_process_lock(void);
void ftc_process_unlock(int lock);
#endif

#ifdef _WIN32
/* The DLLs (*.dll, *.pyd) of folder `dir` are opened for reading without
   FILE_SHARE_DELETE, and the handles kept for the life of the process, so that their files cannot
   be deleted while the process may still hold them loaded. Windows itself refuses to delete a
   loaded image; wine 8 does not, and then gives a new file that reuses the inode of a deleted
   one the stale module instead (a host that unpacks FMU after FMU into temporary folders and
   deletes them got msvcp140.dll of the first FMU for the second's pythonfmu binary). The shim
   never unloads what it loads, so its files are kept, once per folder and process. */
void ftc_keep_files(const char *dir);

/* The files of `folder` (all, its subfolders' too, or only the one named `only`) copied once
   into the user's cache, %LOCALAPPDATA%/fixed-time-cosim/runtime/<key>/, where <key>
   is a 64-bit FNV-1a hash of their names and bytes: the same files share one copy, other files
   never meet it, and nothing in the cache is ever deleted or rewritten (a copy is made in a
   folder of its own and renamed into place, complete). The shim loads its runtime and
   pythonfmu's binary from there, so that the folder the host unpacked holds no module the
   process keeps loaded and can be deleted after fmi2FreeInstance and FreeLibrary, as a C FMU's
   can (and wine's stale modules, see ftc_keep_files, never meet a deleted file). Writes the
   copy's folder to `out`; 0, or -1 (no cache: no LOCALAPPDATA, a full disk, ...; the caller
   then loads from `folder`). */
int ftc_cached_copy(const char *folder, const char *only, char *out, size_t size);

/* ftc_cached_copy of every file of `folder` with its *.xz files decoded by `decode` to their names
   without ".xz" (the key: the source files' hash, marked as decoded). -1 where there is no cache;
   then `why` is empty, or, when a compressed file is bad, names it and says what failed. */
int ftc_cached_copy_decoded(const char *folder, ftc_decoder decode, char *out, size_t size, char *why,
                            size_t why_size);

/* Where there is no cache: the same decoded copy in a new folder of the temporary folder
   (GetTempPathW, fixed-time-cosim-<process>-<thread>-<time>), left there when the process ends
   (Windows cannot delete a DLL its process holds loaded; the system's disk clean-up removes it).
   0, or -1 and `why` as for ftc_cached_copy_decoded. */
int ftc_temporary_copy(const char *folder, ftc_decoder decode, char *out, size_t size, char *why,
                       size_t why_size);

/* The shim's own file (`path`) opened without FILE_SHARE_DELETE until the host unloads the shim
   (DllMain): undeletable while loaded, as Windows keeps any loaded image, so that wine never
   hands a later file the stale module (see ftc_keep_files), and deletable once unloaded. */
void ftc_keep_own_file(const char *path);
#endif

/* Windows only: a path the host's C runtime and pythonfmu's binary read alike (pythonfmu reads
   resources/slavemodule.txt with a narrow std::ifstream, in the ANSI code page, and gives the
   same bytes to Python as UTF-8): `path` itself when it is ASCII, else its short 8.3 form;
   0 on success, -1 when the path has no ASCII form. POSIX: the path unchanged. */
int ftc_ascii_path(const char *path, char *out, size_t size);

/* Windows only: CPython's start stops at a standard descriptor it cannot examine
   ("init_sys_streams: can't initialize sys standard streams", WinError 6): a GUI process has
   none, and under wine a console process's redirected file lacks the right to read its
   attributes. Before the start, such descriptors of the C runtime the interpreter `python` uses
   are pointed at the null device; after it, ftc_standard_streams_done gives the host back those
   that it had (`saved`), so its output and Python's go where they went. POSIX: nothing. */
void ftc_standard_streams(void *python, int saved[3]);
void ftc_standard_streams_done(int saved[3]);

/* A mutex usable from any thread, statically initialized. */
#ifdef _WIN32 /* a slim reader/writer lock (SRWLOCK), without windows.h's macros in the FMI code */
typedef struct {
    void *opaque;
} ftc_mutex;
#define FTC_MUTEX_INIT {0}
void ftc_lock(ftc_mutex *mutex);
void ftc_unlock(ftc_mutex *mutex);
#else
#include <pthread.h>
typedef pthread_mutex_t ftc_mutex;
#define FTC_MUTEX_INIT PTHREAD_MUTEX_INITIALIZER
#define ftc_lock(m) pthread_mutex_lock(m)
#define ftc_unlock(m) pthread_mutex_unlock(m)
#endif

#endif
