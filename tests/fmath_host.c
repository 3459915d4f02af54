/* SPDX-License-Identifier: BSD-2-Clause */
/* fmath_host: controller/fmath.h's functions on arguments read from stdin, for tests/test_fmath.py.

   Reads (from the file named by its argument, else stdin) lines "<f> <x bits> [<y bits>]" (f one of e s c p: exp, sin, cos, pow; bits as 16 hex
   digits) and prints each result's bits, one per line. Built with the flags the FMU build uses
   (-O2 -ffp-contract=off) for Linux and, with mingw-w64, for Windows (run under wine), so the test
   compares the compiled functions with controller/fmath.py and the two platforms with each other. */

#include <stdint.h>
#include <stdio.h>

#include "fmath.h"

int main(int argc, char **argv) {
    FILE *in = argc > 1 ? fopen(argv[1], "r") : stdin;
    char f;
    unsigned long long xb, yb;
    if (!in) return 2;
    while (fscanf(in, " %c %llx", &f, &xb) == 2) {
        double x = ftc_double(xb), r;
        if (f == 'p') {
            if (fscanf(in, "%llx", &yb) != 1) return 2;
            r = ftc_pow(x, ftc_double(yb));
        } else {
            r = f == 'e' ? ftc_exp(x) : f == 's' ? ftc_sin(x) : ftc_cos(x);
        }
        printf("%016llx\n", (unsigned long long)ftc_bits(r));
    }
    return 0;
}
