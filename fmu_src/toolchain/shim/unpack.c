/* SPDX-License-Identifier: BSD-2-Clause */
/* The decoder of the runtime's xz-compressed members (unpack.h), on XZ Embedded (xz/README.md).

   The build stores the two interpreter libraries, libpython3.11.so.1.0 and python311.dll, as .xz
   (8 MB less per FMU). The shim decodes one only when it loads the bundled interpreter, that is
   when its host has no Python: into the user's cache once (platform.h: ftc_decoded_file on
   Linux, ftc_cached_copy on Windows), where every later process finds it decoded. */

#include "unpack.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "xz/xz.h"

int ftc_xz_decode(FILE *in, FILE *out, char *why, size_t size) {
    enum { BLOCK = 1 << 16 };
    xz_crc32_init();
    xz_crc64_init();
    struct xz_dec *decoder = xz_dec_init(XZ_DYNALLOC, FTC_XZ_DICT_MAX);
    unsigned char *input = malloc(BLOCK), *output = malloc(BLOCK);
    if (!decoder || !input || !output) {
        snprintf(why, size, "out of memory");
        xz_dec_end(decoder);
        free(input), free(output);
        return -1;
    }
    struct xz_buf b = {.in = input, .in_pos = 0, .in_size = 0, .out = output, .out_pos = 0, .out_size = BLOCK};
    unsigned long long written = 0;
    enum xz_ret ret = XZ_OK;
    int output_failed = 0;
    why[0] = '\0';
    while (ret == XZ_OK) {
        if (b.in_pos == b.in_size) {
            b.in_size = fread(input, 1, BLOCK, in);
            b.in_pos = 0;
            if (b.in_size == 0 && ferror(in)) {
                snprintf(why, size, "cannot read it: %s", strerror(errno));
                break;
            }
        }
        size_t before_in = b.in_pos;
        ret = xz_dec_run(decoder, &b);
        size_t produced = b.out_pos;
        written += produced;
        if (written > FTC_XZ_LIMIT) {
            snprintf(why, size, "it decodes to more than %llu bytes", FTC_XZ_LIMIT);
            break;
        }
        if (b.out_pos && fwrite(output, 1, b.out_pos, out) != b.out_pos) {
            snprintf(why, size, "cannot write the decoded file: %s", strerror(errno));
            output_failed = 1;
            break;
        }
        b.out_pos = 0;
        if (ret == XZ_OK && b.in_size == 0 && before_in == b.in_pos && !produced) ret = XZ_BUF_ERROR; /* truncated */
    }
    if (!why[0] && ret == XZ_STREAM_END) { /* nothing may follow the stream */
        if (b.in_pos != b.in_size || fgetc(in) != EOF) snprintf(why, size, "data after the xz stream");
    } else if (!why[0]) {
        const char *what = ret == XZ_MEM_ERROR        ? "out of memory"
                           : ret == XZ_MEMLIMIT_ERROR ? "its dictionary is larger than 8 MiB"
                           : ret == XZ_FORMAT_ERROR   ? "not an xz file"
                           : ret == XZ_OPTIONS_ERROR  ? "unsupported xz options"
                           : ret == XZ_BUF_ERROR      ? "truncated xz data"
                                                      : "corrupt xz data (check or size mismatch)";
        snprintf(why, size, "%s", what);
    }
    if (!why[0] && (fflush(out) != 0 || ferror(out))) {
        snprintf(why, size, "cannot write the decoded file: %s", strerror(errno));
        output_failed = 1;
    }
    xz_dec_end(decoder);
    free(input), free(output);
    return !why[0] ? 0 : output_failed ? -2 : -1;
}
