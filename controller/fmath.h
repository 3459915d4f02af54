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

/* Payne-Hanek reduction for large |x| (musl __rem_pio2_large.c, fdlibm k_rem_pio2.c, prec = 1, with
   the caller's part of __rem_pio2.c), cut at musl's own comments into the steps below, each the
   same statements in the same order (fmath.py's _rem_pio2_large is cut alike). */

/* x's 24-bit digits tx[0..nx-1] (nx returned; the first non-zero) and their exponent *e0 */
static int32_t ftc_rem_pio2_digits(double x, double tx[3], int32_t *e0)
{
    uint64_t ui = ftc_bits(x);
    uint32_t ix = (uint32_t)(ui >> 32) & 0x7fffffff;
    double z;
    int32_t i;
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
    *e0 = (int32_t)(ix >> 20) - (0x3ff + 23);
    return i + 1;
}

/* q[from..to], q[i] = sum over j of tx[j] * f[jx + i - j] */
static void ftc_rem_pio2_q(const double tx[3], const double f[20], double q[20], int32_t jx, int32_t from,
                           int32_t to)
{
    int32_t i, j;
    double fw;
    for (i = from; i <= to; i++) {
        for (j = 0, fw = 0.0; j <= jx; j++)
            fw += tx[j] * f[jx + i - j];
        q[i] = fw;
    }
}

/* 1 - q in iq[0..jz-1] (q > 0.5), and z for ih == 2 */
static double ftc_rem_pio2_complement(int32_t iq[20], int32_t jz, int32_t q0, int32_t ih, double z)
{
    int32_t i, j, carry = 0;
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
    if (q0 == 1)  /* rare case: chance is 1 in 12 */
        iq[jz - 1] &= 0x7fffff;
    else if (q0 == 2)
        iq[jz - 1] &= 0x3fffff;
    if (ih == 2) {
        z = 1.0 - z;
        if (carry != 0)
            z -= ftc_scalbn(1.0, q0);
    }
    return z;
}

/* q[0..jz] distilled into iq[] reversingly, n (mod 8 and more) into *np, the fraction into *zp;
   returns ih (0: q < 0.5, else q > 0.5 and 1 - q is taken) */
static int32_t ftc_rem_pio2_distill(const double q[20], int32_t iq[20], int32_t jz, int32_t q0, double *zp,
                                    int32_t *np)
{
    double z, fw;
    int32_t i, j, n, ih = 0;
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
    if (q0 > 0) {  /* need iq[jz-1] to determine n */
        i  = iq[jz - 1] >> (24 - q0); n += i;
        iq[jz - 1] -= i << (24 - q0);
        ih = iq[jz - 1] >> (23 - q0);
    }
    else if (q0 == 0) ih = iq[jz - 1] >> 23;
    else if (z >= 0.5) ih = 2;

    if (ih > 0) {  /* q > 0.5 */
        n += 1;
        z = ftc_rem_pio2_complement(iq, jz, q0, ih, z);
    }
    *zp = z;
    *np = n;
    return ih;
}

/* how many more terms of q a recomputation needs (0: none) */
static int32_t ftc_rem_pio2_more(const int32_t iq[20], int32_t jz, int32_t jk, double z)
{
    int32_t i, j = 0, k;
    if (z != 0.0)
        return 0;
    for (i = jz - 1; i >= jk; i--) j |= iq[i];
    if (j != 0)
        return 0;
    for (k = 1; iq[jk - k] == 0; k++);  /* k = no. of terms needed */
    return k;
}

/* zero terms chopped off, or z broken into 24-bit chunks; returns the new jz */
static int32_t ftc_rem_pio2_chop(int32_t iq[20], int32_t jz, int32_t *q0, double z)
{
    double fw;
    if (z == 0.0) {
        jz -= 1;
        *q0 -= 24;
        while (iq[jz] == 0) {
            jz--;
            *q0 -= 24;
        }
        return jz;
    }
    z = ftc_scalbn(z, -*q0);
    if (z >= 0x1p24) {
        fw = (double)(int32_t)(0x1p-24 * z);
        iq[jz] = (int32_t)(z - 0x1p24 * fw);
        jz += 1;
        *q0 += 24;
        iq[jz] = (int32_t)fw;
    } else
        iq[jz] = (int32_t)z;
    return jz;
}

/* the chunks iq[0..jz] times pi/2, compressed into *y0 + *y1 (prec = 1) */
static void ftc_rem_pio2_sum(const int32_t iq[20], int32_t jz, int32_t q0, int32_t ih, double *y0, double *y1)
{
    const int32_t jp = 4;
    double fw, q[20] = {0}, fq[20] = {0}; /* zeroed: gcc cannot see jz >= 0 */
    int32_t i, k;
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
}

static int ftc_rem_pio2_large(double x, double *y0, double *y1)
{
    const int32_t jk = 4; /* jk = jp = 4 for prec = 1 */
    double tx[3], f[20], q[20] = {0}, z;
    int32_t iq[20], jx, jv, jz, q0, n, ih, k, i, j, e0;

    jx = ftc_rem_pio2_digits(x, tx, &e0) - 1;
    /* determine jx,jv,q0, note that 3>q0 */
    jv = (e0 - 3) / 24;  if (jv < 0) jv = 0;
    q0 = e0 - 24 * (jv + 1);

    /* set up f[0] to f[jx+jk] where f[jx+jk] = ipio2[jv+jk] */
    for (i = 0, j = jv - jx; i <= jx + jk; i++, j++)
        f[i] = j < 0 ? 0.0 : (double)ftc_ipio2[j];
    ftc_rem_pio2_q(tx, f, q, jx, 0, jk);  /* compute q[0],q[1],...q[jk] */

    for (jz = jk;; jz += k) {
        ih = ftc_rem_pio2_distill(q, iq, jz, q0, &z, &n);
        k = ftc_rem_pio2_more(iq, jz, jk, z);
        if (k == 0)
            break;
        for (i = jz + 1; i <= jz + k; i++)  /* add q[jz+1] to q[jz+k] */
            f[jx + i] = (double)ftc_ipio2[jv + i];
        ftc_rem_pio2_q(tx, f, q, jx, jz + 1, jz + k);
    }
    jz = ftc_rem_pio2_chop(iq, jz, &q0, z);
    ftc_rem_pio2_sum(iq, jz, q0, ih, y0, y1);
    n &= 7;

    /* caller part: apply the sign of x */
    if (ftc_bits(x) >> 63) {
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

#include "fmath_pow.h" /* pow(x, y) */

#endif
