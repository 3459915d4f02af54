/* SPDX-License-Identifier: MIT */
/* fmath.h: exp, sin, cos and pow that give the same bits on every platform and CPU.

   Owns: the elementary functions of the law (controller/_law.c) and of the plants
   (fmu_src/models/_dopri.c). controller/fmath.py is the same algorithms in Python, operation for
   operation, and gives the same bits (tests/test_fmath.py compares them, and both with glibc and
   mpmath). May not: call the C library's math (whose last bit differs between glibc and the
   Universal C Runtime, and between glibc's FMA and plain variants on one machine), or be built
   with fused multiply-add (-ffp-contract=off) or -ffast-math.

   Why: with the platform's libm, a chattering law run on Windows, or on a Linux CPU without FMA,
   drifted from the same run on this machine by up to 0.28 of the output's magnitude (issue 31);
   every operation here is an IEEE 754 +, -, *, / or a conversion, which round alike everywhere.

   The algorithms are musl's (MIT; src/math: exp.c as of 9b0fcb44, pow.c as of 688d3da0, sin.c,
   cos.c, __sin.c, __cos.c, __rem_pio2.c, __rem_pio2_large.c, scalbn.c), which are FreeBSD's msun,
   which are Sun's fdlibm. Accuracy: below 1 ulp (measured in tests/test_fmath.py). The floating-
   point exceptions musl raises on purpose (FORCE_EVAL) are left out: nothing here reads them.

   Sun's notice, which the fdlibm-derived parts carry:
   ====================================================
   Copyright (C) 1993, 2004 by Sun Microsystems, Inc. All rights reserved.
   Developed at SunSoft, a Sun Microsystems, Inc. business.
   Permission to use, copy, modify, and distribute this
   software is freely granted, provided that this notice
   is preserved.
   ====================================================
   musl's licence: documentation/licenses/musl.txt in every FMU (fmu_src/toolchain/licences.py). */

#ifndef FTC_FMATH_H
#define FTC_FMATH_H

#include <math.h> /* floor: exact everywhere */
#include <stdint.h>
#include <string.h>

#if defined(__FAST_MATH__)
#error "fmath.h must not be built with -ffast-math: it relies on IEEE 754 rounding of every operation"
#endif

/* The correctly rounded square root, as IEEE 754 requires: on x86-64 the SSE2 instruction itself,
   since a C library's sqrt need not be it (mingw-w64's rounds sqrt(DBL_MAX) up to 2^512). */
#if defined(__SSE2__)
#include <emmintrin.h>
static inline double ftc_sqrt(double x) { return _mm_cvtsd_f64(_mm_sqrt_sd(_mm_setzero_pd(), _mm_set_sd(x))); }
#else
static inline double ftc_sqrt(double x) { return sqrt(x); }
#endif

static inline uint64_t ftc_bits(double x) {
    uint64_t i;
    memcpy(&i, &x, sizeof i);
    return i;
}

static inline double ftc_double(uint64_t i) {
    double x;
    memcpy(&x, &i, sizeof x);
    return x;
}

/* x * 2^n rounded once (musl scalbn.c: in steps that avoid double rounding below 2^-1022). */
static double ftc_scalbn(double x, int n) {
    if (n > 1023) {
        x *= 0x1p1023;
        n -= 1023;
        if (n > 1023) {
            x *= 0x1p1023;
            n -= 1023;
            if (n > 1023) n = 1023;
        }
    } else if (n < -1022) {
        x *= 0x1p-1022 * 0x1p53;
        n += 1022 - 53;
        if (n < -1022) {
            x *= 0x1p-1022 * 0x1p53;
            n += 1022 - 53;
            if (n < -1022) n = -1022;
        }
    }
    return x * ftc_double((uint64_t)(0x3ff + n) << 52);
}

/* exp(x), musl's exp.c before its table-driven rewrite (fdlibm e_exp.c). */
static double ftc_exp(double x) {
    static const double half[2] = {0.5, -0.5};
    static const double ln2hi = 6.93147180369123816490e-01, ln2lo = 1.90821492927058770002e-10,
                        invln2 = 1.44269504088896338700e+00, P1 = 1.66666666666666019037e-01,
                        P2 = -2.77777777770155933842e-03, P3 = 6.61375632143793436117e-05,
                        P4 = -1.65339022054652515390e-06, P5 = 4.13813679705723846039e-08;
    double hi, lo, c, xx, y;
    int k;
    uint32_t hx = (uint32_t)(ftc_bits(x) >> 32);
    int sign = (int)(hx >> 31);
    hx &= 0x7fffffff;
    if (hx >= 0x4086232b) { /* |x| >= 708.39... */
        if (x != x) return x;
        if (x > 709.782712893383973096) return x * 0x1p1023; /* overflow: inf */
        if (x < -745.13321910194110842) return 0.0;         /* underflow */
    }
    if (hx > 0x3fd62e42) { /* |x| > 0.5 ln2: reduce */
        if (hx >= 0x3ff0a2b2) /* |x| >= 1.5 ln2 */
            k = (int)(invln2 * x + half[sign]);
        else
            k = 1 - sign - sign;
        hi = x - k * ln2hi; /* k*ln2hi is exact here */
        lo = k * ln2lo;
        x = hi - lo;
    } else if (hx > 0x3e300000) { /* |x| > 2^-28 */
        k = 0;
        hi = x;
        lo = 0.0;
    } else {
        return 1.0 + x;
    }
    xx = x * x;
    c = x - xx * (P1 + xx * (P2 + xx * (P3 + xx * (P4 + xx * P5))));
    y = 1.0 + (x * c / (2.0 - c) - lo + hi);
    return k == 0 ? y : ftc_scalbn(y, k);
}

/* The kernels of sin and cos on [-pi/4, pi/4]: x + y is the reduced argument (musl __sin.c, __cos.c). */
static double ftc_ksin(double x, double y, int iy) {
    static const double S1 = -1.66666666666666324348e-01, S2 = 8.33333333332248946124e-03,
                        S3 = -1.98412698298579493134e-04, S4 = 2.75573137070700676789e-06,
                        S5 = -2.50507602534068634195e-08, S6 = 1.58969099521155010221e-10;
    double z = x * x, w = z * z;
    double r = S2 + z * (S3 + z * S4) + z * w * (S5 + z * S6);
    double v = z * x;
    if (iy == 0) return x + v * (S1 + z * r);
    return x - ((z * (0.5 * y - v * r) - y) - v * S1);
}

static double ftc_kcos(double x, double y) {
    static const double C1 = 4.16666666666666019037e-02, C2 = -1.38888888888741095749e-03,
                        C3 = 2.48015872894767294178e-05, C4 = -2.75573143513906633035e-07,
                        C5 = 2.08757232129817482790e-09, C6 = -1.13596475577881948265e-11;
    double z = x * x, w = z * z;
    double r = z * (C1 + z * (C2 + z * C3)) + w * w * (C4 + z * (C5 + z * C6));
    double hz = 0.5 * z;
    w = 1.0 - hz;
    return w + (((1.0 - w) - hz) + (z * r - x * y));
}

/* x - N pi/2 in *y0 + *y1 and n = N mod 8 with the sign of x, for finite |x| >= 2^20 pi/2 (high
   word >= 0x413921fb): Payne-Hanek reduction, musl's __rem_pio2_large.c (fdlibm k_rem_pio2.c)
   specialised to double precision (prec = 1: jk = jp = 4), with the caller's part of __rem_pio2.c. */
/*
 * Table of constants for 2/pi: ipio2[i] holds bits 24*i .. 24*i+23 of 2/pi
 * after the binary point (value ipio2[i] * 2^(-24(i+1))).
 * Only the first 66 entries (the part musl uses when long double == double)
 * are kept: for double x, e0 <= 1000 so jv <= 41 and the first pass reads up
 * to ipio2[jv+4] = ipio2[45]. Recomputation can read a few more: since
 * |x*2/pi - N| >= 2^-61.54 for every double (minimum at 6381956970095103*2^797),
 * at most ~62 extra bits (3 chunks) are ever needed; the largest index reached
 * in tests covering the near-worst cases of every exponent is 47 < 66.
 */
static const int32_t ftc_ipio2[66] = {
0xA2F983, 0x6E4E44, 0x1529FC, 0x2757D1, 0xF534DD, 0xC0DB62,
0x95993C, 0x439041, 0xFE5163, 0xABDEBB, 0xC561B7, 0x246E3A,
0x424DD2, 0xE00649, 0x2EEA09, 0xD1921C, 0xFE1DEB, 0x1CB129,
0xA73EE8, 0x8235F5, 0x2EBB44, 0x84E99C, 0x7026B4, 0x5F7E41,
0x3991D6, 0x398353, 0x39F49C, 0x845F8B, 0xBDF928, 0x3B1FF8,
0x97FFDE, 0x05980F, 0xEF2F11, 0x8B5A0A, 0x6D1F6D, 0x367ECF,
0x27CB09, 0xB74F46, 0x3F669E, 0x5FEA2D, 0x7527BA, 0xC7EBE5,
0xF17B3D, 0x0739F7, 0x8A5292, 0xEA6BFB, 0x5FB11F, 0x8D5D08,
0x560330, 0x46FC7B, 0x6BABF0, 0xCFBC20, 0x9AF436, 0x1DA9E3,
0x91615E, 0xE61B08, 0x659985, 0x5F14A0, 0x68408D, 0xFFD880,
0x4D7327, 0x310606, 0x1556CA, 0x73A8C9, 0x60E27B, 0xC08C6B,
};

/* pi/2 cut into 24-bit chunks; only PIo2[0..jp] = PIo2[0..4] are used for prec = 1 */
static const double ftc_PIo2[5] = {
  1.57079625129699707031e+00, /* 0x3FF921FB, 0x40000000 */
  7.54978941586159635335e-08, /* 0x3E74442D, 0x00000000 */
  5.39030252995776476554e-15, /* 0x3CF84698, 0x80000000 */
  3.28200341580791294123e-22, /* 0x3B78CC51, 0x60000000 */
  1.27065575308067607349e-29, /* 0x39F01B83, 0x80000000 */
};

static int ftc_rem_pio2_large(double x, double *y0, double *y1)
{
    /* caller part (musl __rem_pio2, large-argument tail) */
    uint64_t ui = ftc_bits(x);
    double tx[3];
    int sign = (int)(ui >> 63);
    uint32_t ix = (uint32_t)(ui >> 32) & 0x7fffffff;
    int nx, e0;
    /* k_rem_pio2 locals; jk = jp = 4 for prec = 1 */
    const int32_t jk = 4, jp = 4;
    int32_t jz, jx, jv, carry, n, iq[20], i, j, k, m, q0, ih;
    double z, fw, f[20], fq[20] = {0}, q[20]; /* fq zeroed: gcc cannot see jz >= 0 */

    /* set z = scalbn(|x|,-ilogb(x)+23) */
    ui &= (uint64_t)-1 >> 12;
    ui |= (uint64_t)(0x3ff + 23) << 52;
    z = ftc_double(ui);
    for (i = 0; i < 2; i++) {
        tx[i] = (double)(int32_t)z;
        z     = (z - tx[i]) * 0x1p24;
    }
    tx[i] = z;
    /* skip zero terms, first term is non-zero */
    while (tx[i] == 0.0)
        i--;
    nx = i + 1;
    e0 = (int)(ix >> 20) - (0x3ff + 23);

    /* __rem_pio2_large(tx, ty, e0, nx, 1) */
    /* determine jx,jv,q0, note that 3>q0 */
    jx = nx - 1;
    jv = (e0 - 3) / 24;  if (jv < 0) jv = 0;
    q0 = e0 - 24 * (jv + 1);

    /* set up f[0] to f[jx+jk] where f[jx+jk] = ipio2[jv+jk] */
    j = jv - jx; m = jx + jk;
    for (i = 0; i <= m; i++, j++) {
        f[i] = j < 0 ? 0.0 : (double)ftc_ipio2[j];
    }

    /* compute q[0],q[1],...q[jk] */
    for (i = 0; i <= jk; i++) {
        for (j = 0, fw = 0.0; j <= jx; j++)
            fw += tx[j] * f[jx + i - j];
        q[i] = fw;
    }

    jz = jk;
recompute:
    /* distill q[] into iq[] reversingly */
    for (i = 0, j = jz, z = q[jz]; j > 0; i++, j--) {
        fw    = (double)(int32_t)(0x1p-24 * z);
        iq[i] = (int32_t)(z - 0x1p24 * fw);
        z     = q[j - 1] + fw;
    }

    /* compute n */
    z  = ftc_scalbn(z, q0);        /* actual value of z */
    z -= 8.0 * floor(z * 0.125);   /* trim off integer >= 8 */
    n  = (int32_t)z;
    z -= (double)n;
    ih = 0;
    if (q0 > 0) {  /* need iq[jz-1] to determine n */
        i  = iq[jz - 1] >> (24 - q0); n += i;
        iq[jz - 1] -= i << (24 - q0);
        ih = iq[jz - 1] >> (23 - q0);
    }
    else if (q0 == 0) ih = iq[jz - 1] >> 23;
    else if (z >= 0.5) ih = 2;

    if (ih > 0) {  /* q > 0.5 */
        n += 1; carry = 0;
        for (i = 0; i < jz; i++) {  /* compute 1-q */
            j = iq[i];
            if (carry == 0) {
                if (j != 0) {
                    carry = 1;
                    iq[i] = 0x1000000 - j;
                }
            } else
                iq[i] = 0xffffff - j;
        }
        if (q0 > 0) {  /* rare case: chance is 1 in 12 */
            switch (q0) {
            case 1:
                iq[jz - 1] &= 0x7fffff; break;
            case 2:
                iq[jz - 1] &= 0x3fffff; break;
            }
        }
        if (ih == 2) {
            z = 1.0 - z;
            if (carry != 0)
                z -= ftc_scalbn(1.0, q0);
        }
    }

    /* check if recomputation is needed */
    if (z == 0.0) {
        j = 0;
        for (i = jz - 1; i >= jk; i--) j |= iq[i];
        if (j == 0) {  /* need recomputation */
            for (k = 1; iq[jk - k] == 0; k++);  /* k = no. of terms needed */

            for (i = jz + 1; i <= jz + k; i++) {  /* add q[jz+1] to q[jz+k] */
                f[jx + i] = (double)ftc_ipio2[jv + i];
                for (j = 0, fw = 0.0; j <= jx; j++)
                    fw += tx[j] * f[jx + i - j];
                q[i] = fw;
            }
            jz += k;
            goto recompute;
        }
    }

    /* chop off zero terms */
    if (z == 0.0) {
        jz -= 1;
        q0 -= 24;
        while (iq[jz] == 0) {
            jz--;
            q0 -= 24;
        }
    } else { /* break z into 24-bit if necessary */
        z = ftc_scalbn(z, -q0);
        if (z >= 0x1p24) {
            fw = (double)(int32_t)(0x1p-24 * z);
            iq[jz] = (int32_t)(z - 0x1p24 * fw);
            jz += 1;
            q0 += 24;
            iq[jz] = (int32_t)fw;
        } else
            iq[jz] = (int32_t)z;
    }

    /* convert integer "bit" chunk to floating-point value */
    fw = ftc_scalbn(1.0, q0);
    for (i = jz; i >= 0; i--) {
        q[i] = fw * (double)iq[i];
        fw *= 0x1p-24;
    }

    /* compute PIo2[0,...,jp]*q[jz,...,0] */
    for (i = jz; i >= 0; i--) {
        for (fw = 0.0, k = 0; k <= jp && k <= jz - i; k++)
            fw += ftc_PIo2[k] * q[i + k];
        fq[jz - i] = fw;
    }

    /* compress fq[] into y[] (prec = 1) */
    fw = 0.0;
    for (i = jz; i >= 0; i--)
        fw += fq[i];
    *y0 = ih == 0 ? fw : -fw;
    fw = fq[0] - fw;
    for (i = 1; i <= jz; i++)
        fw += fq[i];
    *y1 = ih == 0 ? fw : -fw;
    n &= 7;

    /* caller part: apply the sign of x */
    if (sign) {
        *y0 = -*y0;
        *y1 = -*y1;
        return -n;
    }
    return n;
}

/* x - n pi/2 in *y0 + *y1 and n, for |x| > ~pi/4 (musl __rem_pio2.c); ix: the high word of |x|. */
static int ftc_rem_pio2(double x, uint32_t ix, double *y0, double *y1) {
    static const double toint = 0x1.8p52, pio4 = 0x1.921fb54442d18p-1,
                        invpio2 = 6.36619772367581382433e-01, pio2_1 = 1.57079632673412561417e+00,
                        pio2_1t = 6.07710050650619224932e-11, pio2_2 = 6.07710050630396597660e-11,
                        pio2_2t = 2.02226624879595063154e-21, pio2_3 = 2.02226624871116645580e-21,
                        pio2_3t = 8.47842766036889956997e-32;
    double z, w, t, r, fn;
    int sign = (int)(ftc_bits(x) >> 63), n, ex, ey;
    if (ix <= 0x400f6a7a) { /* |x| ~<= 5pi/4 */
        if ((ix & 0xfffff) == 0x921fb) goto medium; /* |x| ~= pi/2 or 2pi/2: cancellation */
        if (ix <= 0x4002d97c) { /* |x| ~<= 3pi/4 */
            if (!sign) {
                z = x - pio2_1;
                *y0 = z - pio2_1t;
                *y1 = (z - *y0) - pio2_1t;
                return 1;
            }
            z = x + pio2_1;
            *y0 = z + pio2_1t;
            *y1 = (z - *y0) + pio2_1t;
            return -1;
        }
        if (!sign) {
            z = x - 2 * pio2_1;
            *y0 = z - 2 * pio2_1t;
            *y1 = (z - *y0) - 2 * pio2_1t;
            return 2;
        }
        z = x + 2 * pio2_1;
        *y0 = z + 2 * pio2_1t;
        *y1 = (z - *y0) + 2 * pio2_1t;
        return -2;
    }
    if (ix <= 0x401c463b) { /* |x| ~<= 9pi/4 */
        if (ix <= 0x4015fdbc) { /* |x| ~<= 7pi/4 */
            if (ix == 0x4012d97c) goto medium; /* |x| ~= 3pi/2 */
            if (!sign) {
                z = x - 3 * pio2_1;
                *y0 = z - 3 * pio2_1t;
                *y1 = (z - *y0) - 3 * pio2_1t;
                return 3;
            }
            z = x + 3 * pio2_1;
            *y0 = z + 3 * pio2_1t;
            *y1 = (z - *y0) + 3 * pio2_1t;
            return -3;
        }
        if (ix == 0x401921fb) goto medium; /* |x| ~= 4pi/2 */
        if (!sign) {
            z = x - 4 * pio2_1;
            *y0 = z - 4 * pio2_1t;
            *y1 = (z - *y0) - 4 * pio2_1t;
            return 4;
        }
        z = x + 4 * pio2_1;
        *y0 = z + 4 * pio2_1t;
        *y1 = (z - *y0) + 4 * pio2_1t;
        return -4;
    }
    if (ix >= 0x413921fb) return ftc_rem_pio2_large(x, y0, y1); /* |x| ~>= 2^20 pi/2 */
medium:
    fn = x * invpio2 + toint - toint; /* rint(x / (pi/2)) */
    n = (int32_t)fn;
    r = x - fn * pio2_1;
    w = fn * pio2_1t; /* 1st round, good to 85 bits */
    if (r - w < -pio4) {
        n--;
        fn--;
        r = x - fn * pio2_1;
        w = fn * pio2_1t;
    } else if (r - w > pio4) {
        n++;
        fn++;
        r = x - fn * pio2_1;
        w = fn * pio2_1t;
    }
    *y0 = r - w;
    ey = (int)(ftc_bits(*y0) >> 52 & 0x7ff);
    ex = (int)(ix >> 20);
    if (ex - ey > 16) { /* 2nd round, good to 118 bits */
        t = r;
        w = fn * pio2_2;
        r = t - w;
        w = fn * pio2_2t - ((t - r) - w);
        *y0 = r - w;
        ey = (int)(ftc_bits(*y0) >> 52 & 0x7ff);
        if (ex - ey > 49) { /* 3rd round, good to 151 bits, covers all cases */
            t = r;
            w = fn * pio2_3;
            r = t - w;
            w = fn * pio2_3t - ((t - r) - w);
            *y0 = r - w;
        }
    }
    *y1 = (r - *y0) - w;
    return n;
}

/* sin(x) (musl sin.c). */
static double ftc_sin(double x) {
    double y0, y1;
    uint32_t ix = (uint32_t)(ftc_bits(x) >> 32) & 0x7fffffff;
    if (ix <= 0x3fe921fb) {                /* |x| ~< pi/4 */
        if (ix < 0x3e500000) return x;     /* |x| < 2^-26 */
        return ftc_ksin(x, 0.0, 0);
    }
    if (ix >= 0x7ff00000) return x - x; /* inf or nan: nan */
    switch ((unsigned)ftc_rem_pio2(x, ix, &y0, &y1) & 3) {
    case 0: return ftc_ksin(y0, y1, 1);
    case 1: return ftc_kcos(y0, y1);
    case 2: return -ftc_ksin(y0, y1, 1);
    default: return -ftc_kcos(y0, y1);
    }
}

/* cos(x) (musl cos.c). */
static double ftc_cos(double x) {
    double y0, y1;
    uint32_t ix = (uint32_t)(ftc_bits(x) >> 32) & 0x7fffffff;
    if (ix <= 0x3fe921fb) {                /* |x| ~< pi/4 */
        if (ix < 0x3e46a09e) return 1.0;   /* |x| < 2^-27 sqrt(2) */
        return ftc_kcos(x, 0.0);
    }
    if (ix >= 0x7ff00000) return x - x; /* inf or nan: nan */
    switch ((unsigned)ftc_rem_pio2(x, ix, &y0, &y1) & 3) {
    case 0: return ftc_kcos(y0, y1);
    case 1: return -ftc_ksin(y0, y1, 1);
    case 2: return -ftc_kcos(y0, y1);
    default: return ftc_ksin(y0, y1, 1);
    }
}

/* pow(x, y) (musl pow.c before its table-driven rewrite; fdlibm e_pow.c). Unlike musl, a nan
   result is built from bits (the first nan argument, quieted, as SSE2's x + y gives it; the x86
   default nan for a negative x to a non-integer y), so that it does not depend on the compiler's
   operand order; n << 20 is done in uint32_t (no signed shift). */
#define FTC_HI(x) ((int32_t)(ftc_bits(x) >> 32))
#define FTC_LO(x) ((uint32_t)ftc_bits(x))
#define FTC_ZERO_LO(x) ftc_double(ftc_bits(x) & 0xFFFFFFFF00000000ULL)
#define FTC_SET_HI(x, hi) ftc_double((ftc_bits(x) & 0xFFFFFFFFULL) | ((uint64_t)(uint32_t)(hi) << 32))

static const double
ftc_pow_bp[]   = {1.0, 1.5,},
ftc_pow_dp_h[] = { 0.0, 5.84962487220764160156e-01,}, /* 0x3FE2B803, 0x40000000 */
ftc_pow_dp_l[] = { 0.0, 1.35003920212974897128e-08,}; /* 0x3E4CFDEB, 0x43CFD006 */

static double ftc_pow(double x, double y)
{
    static const double
    two53  =  9007199254740992.0, /* 0x43400000, 0x00000000 */
    huge   =  1.0e300,
    tiny   =  1.0e-300,
    /* poly coefs for (3/2)*(log(x)-2s-2/3*s**3 */
    L1 =  5.99999999999994648725e-01, /* 0x3FE33333, 0x33333303 */
    L2 =  4.28571428578550184252e-01, /* 0x3FDB6DB6, 0xDB6FABFF */
    L3 =  3.33333329818377432918e-01, /* 0x3FD55555, 0x518F264D */
    L4 =  2.72728123808534006489e-01, /* 0x3FD17460, 0xA91D4101 */
    L5 =  2.30660745775561754067e-01, /* 0x3FCD864A, 0x93C9DB65 */
    L6 =  2.06975017800338417784e-01, /* 0x3FCA7E28, 0x4A454EEF */
    P1 =  1.66666666666666019037e-01, /* 0x3FC55555, 0x5555553E */
    P2 = -2.77777777770155933842e-03, /* 0xBF66C16C, 0x16BEBD93 */
    P3 =  6.61375632143793436117e-05, /* 0x3F11566A, 0xAF25DE2C */
    P4 = -1.65339022054652515390e-06, /* 0xBEBBBD41, 0xC5D26BF1 */
    P5 =  4.13813679705723846039e-08, /* 0x3E663769, 0x72BEA4D0 */
    lg2     =  6.93147180559945286227e-01, /* 0x3FE62E42, 0xFEFA39EF */
    lg2_h   =  6.93147182464599609375e-01, /* 0x3FE62E43, 0x00000000 */
    lg2_l   = -1.90465429995776804525e-09, /* 0xBE205C61, 0x0CA86C39 */
    ovt     =  8.0085662595372944372e-017, /* -(1024-log2(ovfl+.5ulp)) */
    cp      =  9.61796693925975554329e-01, /* 0x3FEEC709, 0xDC3A03FD =2/(3ln2) */
    cp_h    =  9.61796700954437255859e-01, /* 0x3FEEC709, 0xE0000000 =(float)cp */
    cp_l    = -7.02846165095275826516e-09, /* 0xBE3E2FE0, 0x145B01F5 =tail of cp_h*/
    ivln2   =  1.44269504088896338700e+00, /* 0x3FF71547, 0x652B82FE =1/ln2 */
    ivln2_h =  1.44269502162933349609e+00, /* 0x3FF71547, 0x60000000 =24b 1/ln2*/
    ivln2_l =  1.92596299112661746887e-08; /* 0x3E54AE0B, 0xF85DDF44 =1/ln2 tail*/

    double z,ax,z_h,z_l,p_h,p_l;
    double y1,t1,t2,r,s,t,u,v,w;
    int32_t i,j,k,yisint,n;
    int32_t hx,hy,ix,iy;
    uint32_t lx,ly;

    hx = FTC_HI(x); lx = FTC_LO(x);
    hy = FTC_HI(y); ly = FTC_LO(y);
    ix = hx & 0x7fffffff;
    iy = hy & 0x7fffffff;

    /* x**0 = 1, even if x is NaN */
    if ((iy|ly) == 0)
        return 1.0;
    /* 1**y = 1, even if y is NaN */
    if (hx == 0x3ff00000 && lx == 0)
        return 1.0;
    /* NaN if either arg is NaN */
    if (ix > 0x7ff00000 || (ix == 0x7ff00000 && lx != 0) ||
        iy > 0x7ff00000 || (iy == 0x7ff00000 && ly != 0)) {
        /* musl: return x + y; SSE2 result: first NaN operand, quieted */
        if (ix > 0x7ff00000 || (ix == 0x7ff00000 && lx != 0))
            return ftc_double(ftc_bits(x) | 0x0008000000000000ULL);
        return ftc_double(ftc_bits(y) | 0x0008000000000000ULL);
    }

    /* determine if y is an odd int when x < 0
     * yisint = 0       ... y is not an integer
     * yisint = 1       ... y is an odd int
     * yisint = 2       ... y is an even int
     */
    yisint = 0;
    if (hx < 0) {
        if (iy >= 0x43400000)
            yisint = 2; /* even integer y */
        else if (iy >= 0x3ff00000) {
            k = (iy>>20) - 0x3ff;  /* exponent */
            if (k > 20) {
                uint32_t jj = ly>>(52-k);
                if ((jj<<(52-k)) == ly)
                    yisint = 2 - (int32_t)(jj&1);
            } else if (ly == 0) {
                uint32_t jj = (uint32_t)iy>>(20-k);
                if ((jj<<(20-k)) == (uint32_t)iy)
                    yisint = 2 - (int32_t)(jj&1);
            }
        }
    }

    /* special value of y */
    if (ly == 0) {
        if (iy == 0x7ff00000) {  /* y is +-inf */
            if (((ix-0x3ff00000)|lx) == 0)  /* (-1)**+-inf is 1 */
                return 1.0;
            else if (ix >= 0x3ff00000) /* (|x|>1)**+-inf = inf,0 */
                return hy >= 0 ? y : 0.0;
            else                       /* (|x|<1)**+-inf = 0,inf */
                return hy >= 0 ? 0.0 : -y;
        }
        if (iy == 0x3ff00000) {    /* y is +-1 */
            if (hy >= 0)
                return x;
            return 1/x;
        }
        if (hy == 0x40000000)    /* y is 2 */
            return x*x;
        if (hy == 0x3fe00000) {  /* y is 0.5 */
            if (hx >= 0)     /* x >= +0 */
                return ftc_sqrt(x);
        }
    }

    ax = ftc_double(ftc_bits(x) & 0x7FFFFFFFFFFFFFFFULL); /* fabs(x) */
    /* special value of x */
    if (lx == 0) {
        if (ix == 0x7ff00000 || ix == 0 || ix == 0x3ff00000) { /* x is +-0,+-inf,+-1 */
            z = ax;
            if (hy < 0)   /* z = (1/|x|) */
                z = 1.0/z;
            if (hx < 0) {
                if (((ix-0x3ff00000)|yisint) == 0) {
                    /* musl: z = (z-z)/(z-z); (-1)**non-int is NaN */
                    z = ftc_double(0xFFF8000000000000ULL);
                } else if (yisint == 1)
                    z = -z;          /* (x<0)**odd = -(|x|**odd) */
            }
            return z;
        }
    }

    s = 1.0; /* sign of result */
    if (hx < 0) {
        if (yisint == 0) /* (x<0)**(non-int) is NaN; musl: (x-x)/(x-x) */
            return ftc_double(0xFFF8000000000000ULL);
        if (yisint == 1) /* (x<0)**(odd int) */
            s = -1.0;
    }

    /* |y| is huge */
    if (iy > 0x41e00000) { /* if |y| > 2**31 */
        if (iy > 0x43f00000) {  /* if |y| > 2**64, must o/uflow */
            if (ix <= 0x3fefffff)
                return hy < 0 ? huge*huge : tiny*tiny;
            if (ix >= 0x3ff00000)
                return hy > 0 ? huge*huge : tiny*tiny;
        }
        /* over/underflow if x is not close to one */
        if (ix < 0x3fefffff)
            return hy < 0 ? s*huge*huge : s*tiny*tiny;
        if (ix > 0x3ff00000)
            return hy > 0 ? s*huge*huge : s*tiny*tiny;
        /* now |1-x| is tiny <= 2**-20, suffice to compute
           log(x) by x-x^2/2+x^3/3-x^4/4 */
        t = ax - 1.0;       /* t has 20 trailing zeros */
        w = (t*t)*(0.5 - t*(0.3333333333333333333333-t*0.25));
        u = ivln2_h*t;      /* ivln2_h has 21 sig. bits */
        v = t*ivln2_l - w*ivln2;
        t1 = u + v;
        t1 = FTC_ZERO_LO(t1);
        t2 = v - (t1-u);
    } else {
        double ss,s2,s_h,s_l,t_h,t_l;
        n = 0;
        /* take care subnormal number */
        if (ix < 0x00100000) {
            ax *= two53;
            n -= 53;
            ix = FTC_HI(ax);
        }
        n += ((ix)>>20) - 0x3ff;
        j = ix & 0x000fffff;
        /* determine interval */
        ix = j | 0x3ff00000;   /* normalize ix */
        if (j <= 0x3988E)      /* |x|<sqrt(3/2) */
            k = 0;
        else if (j < 0xBB67A)  /* |x|<sqrt(3)   */
            k = 1;
        else {
            k = 0;
            n += 1;
            ix -= 0x00100000;
        }
        ax = FTC_SET_HI(ax, ix);

        /* compute ss = s_h+s_l = (x-1)/(x+1) or (x-1.5)/(x+1.5) */
        u = ax - ftc_pow_bp[k];        /* bp[0]=1.0, bp[1]=1.5 */
        v = 1.0/(ax+ftc_pow_bp[k]);
        ss = u*v;
        s_h = FTC_ZERO_LO(ss);
        /* t_h=ax+bp[k] High */
        t_h = ftc_double((uint64_t)(uint32_t)(((ix>>1)|0x20000000) + 0x00080000 + (k<<18)) << 32);
        t_l = ax - (t_h-ftc_pow_bp[k]);
        s_l = v*((u-s_h*t_h)-s_h*t_l);
        /* compute log(ax) */
        s2 = ss*ss;
        r = s2*s2*(L1+s2*(L2+s2*(L3+s2*(L4+s2*(L5+s2*L6)))));
        r += s_l*(s_h+ss);
        s2 = s_h*s_h;
        t_h = 3.0 + s2 + r;
        t_h = FTC_ZERO_LO(t_h);
        t_l = r - ((t_h-3.0)-s2);
        /* u+v = ss*(1+...) */
        u = s_h*t_h;
        v = s_l*t_h + t_l*ss;
        /* 2/(3log2)*(ss+...) */
        p_h = u + v;
        p_h = FTC_ZERO_LO(p_h);
        p_l = v - (p_h-u);
        z_h = cp_h*p_h;        /* cp_h+cp_l = 2/(3*log2) */
        z_l = cp_l*p_h+p_l*cp + ftc_pow_dp_l[k];
        /* log2(ax) = (ss+..)*2/(3*log2) = n + dp_h + z_h + z_l */
        t = (double)n;
        t1 = ((z_h + z_l) + ftc_pow_dp_h[k]) + t;
        t1 = FTC_ZERO_LO(t1);
        t2 = z_l - (((t1 - t) - ftc_pow_dp_h[k]) - z_h);
    }

    /* split up y into y1+y2 and compute (y1+y2)*(t1+t2) */
    y1 = FTC_ZERO_LO(y);
    p_l = (y-y1)*t1 + y*t2;
    p_h = y1*t1;
    z = p_l + p_h;
    j = FTC_HI(z); i = (int32_t)FTC_LO(z);
    if (j >= 0x40900000) {                      /* z >= 1024 */
        if (((j-0x40900000)|i) != 0)        /* if z > 1024 */
            return s*huge*huge;         /* overflow */
        if (p_l + ovt > z - p_h)
            return s*huge*huge;         /* overflow */
    } else if ((j&0x7fffffff) >= 0x4090cc00) {  /* z <= -1075 */
        if ((((uint32_t)j-0xc090cc00u)|(uint32_t)i) != 0)  /* z < -1075 */
            return s*tiny*tiny;         /* underflow */
        if (p_l <= z - p_h)
            return s*tiny*tiny;         /* underflow */
    }
    /*
     * compute 2**(p_h+p_l)
     */
    i = j & 0x7fffffff;
    k = (i>>20) - 0x3ff;
    n = 0;
    if (i > 0x3fe00000) {  /* if |z| > 0.5, set n = [z+0.5] */
        n = j + (0x00100000>>(k+1));
        k = ((n&0x7fffffff)>>20) - 0x3ff;  /* new k for n */
        t = ftc_double((uint64_t)(uint32_t)(n & ~(0x000fffff>>k)) << 32);
        n = ((n&0x000fffff)|0x00100000)>>(20-k);
        if (j < 0)
            n = -n;
        p_h -= t;
    }
    t = p_l + p_h;
    t = FTC_ZERO_LO(t);
    u = t*lg2_h;
    v = (p_l-(t-p_h))*lg2 + t*lg2_l;
    z = u + v;
    w = v - (z-u);
    t = z*z;
    t1 = z - t*(P1+t*(P2+t*(P3+t*(P4+t*P5))));
    r = (z*t1)/(t1-2.0) - (w + z*w);
    z = 1.0 - (r-z);
    j = FTC_HI(z);
    j += (int32_t)((uint32_t)n << 20);
    if ((j>>20) <= 0)  /* subnormal output */
        z = ftc_scalbn(z,n);
    else
        z = FTC_SET_HI(z, j);
    return s*z;
}

#undef FTC_HI
#undef FTC_LO
#undef FTC_ZERO_LO
#undef FTC_SET_HI

#endif
