/* SPDX-License-Identifier: BSD-2-Clause */
/* The runtime's xz-compressed members (unpack.c): decoded only where the bundled interpreter must
   be loaded. */
#ifndef FTC_UNPACK_H
#define FTC_UNPACK_H

#include <stddef.h>
#include <stdio.h>

/* What the build writes (fmu_src/toolchain/build.py, XZ_FILTERS and XZ_LIMIT): an .xz stream with
   a CRC64 check, the x86 BCJ filter and LZMA2 with an 8 MiB dictionary; nothing decodes to more
   than 64 MiB. */
#define FTC_XZ_SUFFIX ".xz"
#define FTC_XZ_DICT_MAX (8u << 20)
#define FTC_XZ_LIMIT (64ull << 20)

/* Decodes the one .xz stream of `in` into `out` (an ftc_decoder, platform.h): the stream's CRC64
   and index checked, nothing after the stream, at most FTC_XZ_LIMIT bytes. 0 on success; else
   what failed in `why`, and -1 (the input: corrupt, truncated, unreadable) or -2 (the output
   cannot be written: a full disk; another place may serve). */
int ftc_xz_decode(FILE *in, FILE *out, char *why, size_t size);

#endif
