# SPDX-License-Identifier: MIT
"""exp, sin, cos and x ** y with the same bits on every platform and CPU.

The law and the models call these instead of :mod:`math` and ``**``, whose last bit comes from
the platform's C library: glibc and Windows' Universal C Runtime differ, and so do glibc's FMA and
plain variants on two Linux CPUs. Chattering laws amplify one such bit to a visible difference
(up to 0.28 of the output's magnitude in a 3 s run, issue 31). Here every operation is an IEEE
754 ``+``, ``-``, ``*``, ``/`` or an integer conversion, which round alike everywhere.

``controller/fmath.h`` (pow in ``fmath_pow.h``) is the same algorithms in C for the compiled law
and plants, operation for operation and cut into the same functions, so both give the same bits
(``tests/test_fmath.py``).

Why a Python twin at all: ``controller`` is the pure-Python reference of the law, and it must run
where nothing is compiled (a source tree without ``make``, a docs build, a platform without a C
compiler), with the bits of the compiled FMUs, which the tests compare against it. Where
``controller/_fmath.c`` is compiled (``make`` in a checkout, every FMU) the public functions call
that instead; the transcriptions below then serve only as that reference. The algorithms are musl's (MIT),
from FreeBSD's msun and Sun's fdlibm (exp.c, pow.c, sin.c, cos.c and their kernels); their
accuracy is below 1 ulp (tests/test_fmath.py, against mpmath), but for pow with x within about
3e-7 of 1 and |y| > 2^31 (musl's own algorithm: up to 519 ulp, far from the law's arguments).
Where the FMU build has compiled ``controller/_fmath.c`` (in every FMU) the public functions call
it: 0.08 us per call (math's: 0.03 us); the Python transcriptions cost 0.4-0.8 us for exp, sin or
cos and 5 us for pow. The public functions keep the contract of the
Python operation they replace: :func:`exp` as :func:`math.exp`, :func:`sin` and :func:`cos` as
:func:`math.sin` and :func:`math.cos`, :func:`power` as ``float ** float`` (ValueError where that
gives a complex).

Sun's notice, which the fdlibm-derived parts carry: Copyright (C) 1993, 2004 by Sun Microsystems,
Inc. All rights reserved. Developed at SunSoft, a Sun Microsystems, Inc. business. Permission to
use, copy, modify, and distribute this software is freely granted, provided that this notice is
preserved.
"""

from __future__ import annotations

import struct
import sys
from math import copysign as _copysign
from math import floor as _floor
from math import sqrt as _math_sqrt  # correctly rounded by IEEE 754 everywhere

__all__ = ["COMPILED", "cos", "exp", "power", "sin"]

_DOUBLE = struct.Struct("<d")
_QUAD = struct.Struct("<Q")
_pack_double, _unpack_double = _DOUBLE.pack, _DOUBLE.unpack
_pack_quad, _unpack_quad = _QUAD.pack, _QUAD.unpack
_INF = float("inf")
_TWO1023 = float.fromhex("0x1p1023")


def _bits(x: float) -> int:
    """The IEEE 754 bits of ``x`` as an unsigned 64-bit integer."""
    return _unpack_quad(_pack_double(x))[0]


def _double(i: int) -> float:
    """The double whose bits are the low 64 bits of ``i``."""
    return _unpack_double(_pack_quad(i & 0xFFFFFFFFFFFFFFFF))[0]


_TWO_M969 = float.fromhex("0x1p-1022") * float.fromhex("0x1p53")


def _scalbn(x: float, n: int) -> float:
    """x * 2 ** n rounded once (musl scalbn.c: in steps that avoid double rounding below 2^-1022)."""
    if n > 1023:
        x *= _TWO1023
        n -= 1023
        if n > 1023:
            x *= _TWO1023
            n -= 1023
            n = min(n, 1023)
    elif n < -1022:
        x *= _TWO_M969
        n += 1022 - 53
        if n < -1022:
            x *= _TWO_M969
            n += 1022 - 53
            n = max(n, -1022)
    return x * _double((0x3FF + n) << 52)

# exp (musl exp.c before its table-driven rewrite; fdlibm e_exp.c)
_HALF = (0.5, -0.5)
_LN2HI = 6.93147180369123816490e-01
_LN2LO = 1.90821492927058770002e-10
_INVLN2 = 1.44269504088896338700e00
_P1 = 1.66666666666666019037e-01
_P2 = -2.77777777770155933842e-03
_P3 = 6.61375632143793436117e-05
_P4 = -1.65339022054652515390e-06
_P5 = 4.13813679705723846039e-08


def _exp(x: float) -> float:
    """e ** x as IEEE gives it: inf on overflow, 0 on underflow (fmath.h's ftc_exp)."""
    hx = _unpack_quad(_pack_double(x))[0] >> 32
    sign = hx >> 31
    hx &= 0x7FFFFFFF
    if hx >= 0x4086232B:  # |x| >= 708.39...
        if x != x:
            return x
        if x > 709.782712893383973096:
            return x * _TWO1023  # overflow: inf
        if x < -745.13321910194110842:
            return 0.0  # underflow
    if hx > 0x3FD62E42:  # |x| > 0.5 ln2: reduce
        k = int(_INVLN2 * x + _HALF[sign]) if hx >= 0x3FF0A2B2 else 1 - sign - sign
        hi = x - k * _LN2HI  # k * ln2hi is exact here
        lo = k * _LN2LO
        x = hi - lo
    elif hx > 0x3E300000:  # |x| > 2^-28
        k = 0
        hi = x
        lo = 0.0
    else:
        return 1.0 + x
    xx = x * x
    c = x - xx * (_P1 + xx * (_P2 + xx * (_P3 + xx * (_P4 + xx * _P5))))
    y = 1.0 + (x * c / (2.0 - c) - lo + hi)
    return y if k == 0 else _scalbn(y, k)


# The kernels of sin and cos on [-pi/4, pi/4] (musl __sin.c, __cos.c)
_S1 = -1.66666666666666324348e-01
_S2 = 8.33333333332248946124e-03
_S3 = -1.98412698298579493134e-04
_S4 = 2.75573137070700676789e-06
_S5 = -2.50507602534068634195e-08
_S6 = 1.58969099521155010221e-10
_C1 = 4.16666666666666019037e-02
_C2 = -1.38888888888741095749e-03
_C3 = 2.48015872894767294178e-05
_C4 = -2.75573143513906633035e-07
_C5 = 2.08757232129817482790e-09
_C6 = -1.13596475577881948265e-11


def _ksin(x: float, y: float, iy: int) -> float:
    """sin(x + y) for |x + y| <= pi/4; ``iy`` 0: y is 0."""
    z = x * x
    w = z * z
    r = _S2 + z * (_S3 + z * _S4) + z * w * (_S5 + z * _S6)
    v = z * x
    if iy == 0:
        return x + v * (_S1 + z * r)
    return x - ((z * (0.5 * y - v * r) - y) - v * _S1)


def _kcos(x: float, y: float) -> float:
    """cos(x + y) for |x + y| <= pi/4."""
    z = x * x
    w = z * z
    r = z * (_C1 + z * (_C2 + z * _C3)) + w * w * (_C4 + z * (_C5 + z * _C6))
    hz = 0.5 * z
    w = 1.0 - hz
    return w + (((1.0 - w) - hz) + (z * r - x * y))


# Bits 24*i .. 24*i+23 of 2/pi after the binary point; the first 66 entries suffice for double x
# (e0 <= 1000, so jv <= 41; recomputation adds at most ~3 chunks since |x*2/pi - N| >= 2^-61.54;
# the largest index reached in the tests is 47).
_IPIO2: tuple[int, ...] = (
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
)  # fmt: skip
_F_IPIO2: tuple[float, ...] = tuple(float(v) for v in _IPIO2)

# pi/2 cut into 24-bit chunks (PIo2[0..jp], jp = 4).
_PIO2: tuple[float, ...] = (
    1.57079625129699707031e00,  # 0x3FF921FB, 0x40000000
    7.54978941586159635335e-08,  # 0x3E74442D, 0x00000000
    5.39030252995776476554e-15,  # 0x3CF84698, 0x80000000
    3.28200341580791294123e-22,  # 0x3B78CC51, 0x60000000
    1.27065575308067607349e-29,  # 0x39F01B83, 0x80000000
)

_JK = 4  # init_jk[prec = 1]
_JP = 4
_TWO24 = 16777216.0  # 0x1p24
_TWOM24 = 5.9604644775390625e-08  # 0x1p-24

def _rem_pio2_digits(x: float) -> tuple[list[float], int]:
    """x's 24-bit digits (from the first non-zero one) and their exponent e0 (ftc_rem_pio2_digits)."""
    ui = _unpack_quad(_pack_double(x))[0]
    ix = (ui >> 32) & 0x7FFFFFFF
    # set z = scalbn(|x|,-ilogb(x)+23)
    z = _double((ui & 0x000FFFFFFFFFFFFF) | ((0x3FF + 23) << 52))
    tx = [0.0, 0.0, 0.0]
    for i in range(2):
        tx[i] = float(int(z))  # (double)(int32_t)z, z in [0, 2^24)
        z = (z - tx[i]) * _TWO24
    tx[2] = z
    # skip zero terms, first term is non-zero
    i = 2
    while tx[i] == 0.0:
        i -= 1
    return tx[: i + 1], (ix >> 20) - (0x3FF + 23)


def _rem_pio2_q(tx: list[float], f: list[float], q: list[float], first: int, last: int) -> None:
    """q[first..last], q[i] = sum over j of tx[j] * f[jx + i - j] (ftc_rem_pio2_q)."""
    jx = len(tx) - 1
    for i in range(first, last + 1):
        fw = 0.0
        for j in range(jx + 1):
            fw += tx[j] * f[jx + i - j]
        q[i] = fw


def _rem_pio2_complement(iq: list[int], jz: int, q0: int, ih: int, z: float) -> float:
    """1 - q in iq[0..jz-1] (q > 0.5), and z for ih == 2 (ftc_rem_pio2_complement)."""
    carry = 0
    for i in range(jz):  # compute 1-q
        j = iq[i]
        if carry == 0:
            if j != 0:
                carry = 1
                iq[i] = 0x1000000 - j
        else:
            iq[i] = 0xFFFFFF - j
    if q0 == 1:  # rare case: chance is 1 in 12
        iq[jz - 1] &= 0x7FFFFF
    elif q0 == 2:
        iq[jz - 1] &= 0x3FFFFF
    if ih == 2:
        z = 1.0 - z
        if carry != 0:
            z -= _scalbn(1.0, q0)
    return z


def _rem_pio2_distill(q: list[float], iq: list[int], jz: int, q0: int) -> tuple[int, int, float]:
    """(ih, n, z): q[0..jz] distilled into iq[] reversingly, n and the fraction z; ih = 0: q < 0.5,
    else q > 0.5 and 1 - q is taken (ftc_rem_pio2_distill)."""
    z = q[jz]
    for i, j in enumerate(range(jz, 0, -1)):
        fw = float(int(_TWOM24 * z))
        iq[i] = int(z - _TWO24 * fw)
        z = q[j - 1] + fw

    # compute n
    z = _scalbn(z, q0)  # actual value of z
    z -= 8.0 * _floor(z * 0.125)  # trim off integer >= 8 (floor of a double is exact)
    n = int(z)
    z -= float(n)
    ih = 0
    if q0 > 0:  # need iq[jz-1] to determine n (iq[] >= 0 here, so >> matches C)
        i = iq[jz - 1] >> (24 - q0)
        n += i
        iq[jz - 1] -= i << (24 - q0)
        ih = iq[jz - 1] >> (23 - q0)
    elif q0 == 0:
        ih = iq[jz - 1] >> 23
    elif z >= 0.5:
        ih = 2
    if ih > 0:  # q > 0.5
        n += 1
        z = _rem_pio2_complement(iq, jz, q0, ih, z)
    return ih, n, z


def _rem_pio2_more(iq: list[int], jz: int, z: float) -> int:
    """How many more terms of q a recomputation needs, 0 for none (ftc_rem_pio2_more)."""
    if z != 0.0:
        return 0
    j = 0
    for i in range(jz - 1, _JK - 1, -1):
        j |= iq[i]
    if j != 0:
        return 0
    k = 1
    while iq[_JK - k] == 0:  # k = no. of terms needed
        k += 1
    return k


def _rem_pio2_chop(iq: list[int], jz: int, q0: int, z: float) -> tuple[int, int]:
    """(jz, q0) after the zero terms are chopped off, or z broken into 24-bit chunks
    (ftc_rem_pio2_chop)."""
    if z == 0.0:
        jz -= 1
        q0 -= 24
        while iq[jz] == 0:
            jz -= 1
            q0 -= 24
        return jz, q0
    z = _scalbn(z, -q0)
    if z >= _TWO24:
        fw = float(int(_TWOM24 * z))
        iq[jz] = int(z - _TWO24 * fw)
        jz += 1
        q0 += 24
        iq[jz] = int(fw)
    else:
        iq[jz] = int(z)
    return jz, q0


def _rem_pio2_sum(iq: list[int], jz: int, q0: int, ih: int) -> tuple[float, float]:
    """The chunks iq[0..jz] times pi/2, compressed into y0 + y1 (prec = 1; ftc_rem_pio2_sum)."""
    # convert integer "bit" chunk to floating-point value
    q = [0.0] * 20
    fw = _scalbn(1.0, q0)
    for i in range(jz, -1, -1):
        q[i] = fw * float(iq[i])
        fw *= _TWOM24

    # compute PIo2[0,...,jp]*q[jz,...,0]
    fq = [0.0] * 20
    for i in range(jz, -1, -1):
        fw = 0.0
        for k in range(min(_JP, jz - i) + 1):
            fw += _PIO2[k] * q[i + k]
        fq[jz - i] = fw

    # compress fq[] into y[] (prec = 1)
    fw = 0.0
    for i in range(jz, -1, -1):
        fw += fq[i]
    y0 = fw if ih == 0 else -fw
    fw = fq[0] - fw
    for i in range(1, jz + 1):
        fw += fq[i]
    return y0, (fw if ih == 0 else -fw)


def _rem_pio2_large(x: float) -> tuple[int, float, float]:
    """(n, y0, y1) with y0 + y1 = x - N pi/2 and n = N mod 8 with the sign of x, for finite
    |x| >= 2^20 pi/2: Payne-Hanek reduction, musl's __rem_pio2_large.c (fdlibm k_rem_pio2.c) for
    double precision (prec = 1) with the caller's part of __rem_pio2.c, cut into the steps of
    fmath.h's ftc_rem_pio2_large."""
    tx, e0 = _rem_pio2_digits(x)
    jx = len(tx) - 1
    # C truncates (e0-3)/24 toward zero; floor differs only for e0 - 3 < 0, where both clamp to 0
    jv = max((e0 - 3) // 24, 0)
    q0 = e0 - 24 * (jv + 1)

    # set up f[0] to f[jx+jk] where f[jx+jk] = ipio2[jv+jk]
    f = [0.0] * 20
    for i, j in enumerate(range(jv - jx, jv + _JK + 1)):
        f[i] = 0.0 if j < 0 else _F_IPIO2[j]
    q = [0.0] * 20
    _rem_pio2_q(tx, f, q, 0, _JK)  # compute q[0],q[1],...q[jk]

    iq = [0] * 20
    jz = _JK
    while True:
        ih, n, z = _rem_pio2_distill(q, iq, jz, q0)
        k = _rem_pio2_more(iq, jz, z)
        if k == 0:
            break
        for i in range(jz + 1, jz + k + 1):  # add q[jz+1] to q[jz+k]
            f[jx + i] = _F_IPIO2[jv + i]
        _rem_pio2_q(tx, f, q, jz + 1, jz + k)
        jz += k
    jz, q0 = _rem_pio2_chop(iq, jz, q0, z)
    y0, y1 = _rem_pio2_sum(iq, jz, q0, ih)
    n &= 7

    # caller part: apply the sign of x
    if _bits(x) >> 63:
        return -n, -y0, -y1
    return n, y0, y1


# Argument reduction (musl __rem_pio2.c)
_TOINT = float.fromhex("0x1.8p52")
_PIO4 = float.fromhex("0x1.921fb54442d18p-1")
_INVPIO2 = 6.36619772367581382433e-01
_PIO2_1 = 1.57079632673412561417e00
_PIO2_1T = 6.07710050650619224932e-11
_PIO2_2 = 6.07710050630396597660e-11
_PIO2_2T = 2.02226624879595063154e-21
_PIO2_3 = 2.02226624871116645580e-21
_PIO2_3T = 8.47842766036889956997e-32


def _rem_pio2(x: float, ix: int) -> tuple[int, float, float]:
    """(n, y0, y1) with y0 + y1 = x - n pi/2, for |x| > ~pi/4; ``ix``: the high word of |x|."""
    if ix <= 0x401C463B and not ((ix & 0xFFFFF) == 0x921FB or ix == 0x4012D97C or ix == 0x401921FB):
        # |x| ~<= 9 pi/4 and not near a multiple of pi/2 (cancellation: the medium case below)
        if ix <= 0x4002D97C:
            k = 1
        elif ix <= 0x400F6A7A:
            k = 2
        elif ix <= 0x4015FDBC:
            k = 3
        else:
            k = 4
        if x > 0.0:
            z = x - k * _PIO2_1
            y0 = z - k * _PIO2_1T
            return k, y0, (z - y0) - k * _PIO2_1T
        z = x + k * _PIO2_1
        y0 = z + k * _PIO2_1T
        return -k, y0, (z - y0) + k * _PIO2_1T
    if ix >= 0x413921FB:  # |x| ~>= 2^20 pi/2
        return _rem_pio2_large(x)
    fn = x * _INVPIO2 + _TOINT - _TOINT  # rint(x / (pi/2))
    n = int(fn)
    r = x - fn * _PIO2_1
    w = fn * _PIO2_1T  # 1st round, good to 85 bits
    if r - w < -_PIO4:
        n -= 1
        fn -= 1.0
        r = x - fn * _PIO2_1
        w = fn * _PIO2_1T
    elif r - w > _PIO4:
        n += 1
        fn += 1.0
        r = x - fn * _PIO2_1
        w = fn * _PIO2_1T
    y0 = r - w
    ex = ix >> 20
    if ex - (_bits(y0) >> 52 & 0x7FF) > 16:  # 2nd round, good to 118 bits
        t = r
        w = fn * _PIO2_2
        r = t - w
        w = fn * _PIO2_2T - ((t - r) - w)
        y0 = r - w
        if ex - (_bits(y0) >> 52 & 0x7FF) > 49:  # 3rd round, good to 151 bits, covers all cases
            t = r
            w = fn * _PIO2_3
            r = t - w
            w = fn * _PIO2_3T - ((t - r) - w)
            y0 = r - w
    return n, y0, (r - y0) - w


def _sin(x: float) -> float:
    """sin(x) as IEEE gives it: nan for inf (fmath.h's ftc_sin)."""
    ix = _unpack_quad(_pack_double(x))[0] >> 32 & 0x7FFFFFFF
    if ix <= 0x3FE921FB:  # |x| ~< pi/4
        return x if ix < 0x3E500000 else _ksin(x, 0.0, 0)
    if ix >= 0x7FF00000:  # inf or nan: nan
        return x - x
    n, y0, y1 = _rem_pio2(x, ix)
    n &= 3
    if n == 0:
        return _ksin(y0, y1, 1)
    if n == 1:
        return _kcos(y0, y1)
    if n == 2:
        return -_ksin(y0, y1, 1)
    return -_kcos(y0, y1)


def _cos(x: float) -> float:
    """cos(x) as IEEE gives it: nan for inf (fmath.h's ftc_cos)."""
    ix = _unpack_quad(_pack_double(x))[0] >> 32 & 0x7FFFFFFF
    if ix <= 0x3FE921FB:  # |x| ~< pi/4
        return 1.0 if ix < 0x3E46A09E else _kcos(x, 0.0)
    if ix >= 0x7FF00000:  # inf or nan: nan
        return x - x
    n, y0, y1 = _rem_pio2(x, ix)
    n &= 3
    if n == 0:
        return _kcos(y0, y1)
    if n == 1:
        return -_ksin(y0, y1, 1)
    if n == 2:
        return -_kcos(y0, y1)
    return _ksin(y0, y1, 1)


# pow (musl pow.c before its table-driven rewrite; fdlibm e_pow.c)
_NAN_INVALID = _double(0xFFF8000000000000)  # x86 default NaN, what (x-x)/(x-x) gives in musl on SSE2

_TWO53 = 9007199254740992.0  # 0x43400000, 0x00000000
_HUGE = 1.0e300
_TINY = 1.0e-300
# poly coefs for (3/2)*(log(x)-2s-2/3*s**3
_L1 = 5.99999999999994648725e-01  # 0x3FE33333, 0x33333303
_L2 = 4.28571428578550184252e-01  # 0x3FDB6DB6, 0xDB6FABFF
_L3 = 3.33333329818377432918e-01  # 0x3FD55555, 0x518F264D
_L4 = 2.72728123808534006489e-01  # 0x3FD17460, 0xA91D4101
_L5 = 2.30660745775561754067e-01  # 0x3FCD864A, 0x93C9DB65
_L6 = 2.06975017800338417784e-01  # 0x3FCA7E28, 0x4A454EEF
_P1 = 1.66666666666666019037e-01  # 0x3FC55555, 0x5555553E
_P2 = -2.77777777770155933842e-03  # 0xBF66C16C, 0x16BEBD93
_P3 = 6.61375632143793436117e-05  # 0x3F11566A, 0xAF25DE2C
_P4 = -1.65339022054652515390e-06  # 0xBEBBBD41, 0xC5D26BF1
_P5 = 4.13813679705723846039e-08  # 0x3E663769, 0x72BEA4D0
_LG2 = 6.93147180559945286227e-01  # 0x3FE62E42, 0xFEFA39EF
_LG2_H = 6.93147182464599609375e-01  # 0x3FE62E43, 0x00000000
_LG2_L = -1.90465429995776804525e-09  # 0xBE205C61, 0x0CA86C39
_OVT = 8.0085662595372944372e-017  # -(1024-log2(ovfl+.5ulp))
_CP = 9.61796693925975554329e-01  # 0x3FEEC709, 0xDC3A03FD =2/(3ln2)
_CP_H = 9.61796700954437255859e-01  # 0x3FEEC709, 0xE0000000 =(float)cp
_CP_L = -7.02846165095275826516e-09  # 0xBE3E2FE0, 0x145B01F5 =tail of cp_h
_IVLN2 = 1.44269504088896338700e00  # 0x3FF71547, 0x652B82FE =1/ln2
_IVLN2_H = 1.44269502162933349609e00  # 0x3FF71547, 0x60000000 =24b 1/ln2
_IVLN2_L = 1.92596299112661746887e-08  # 0x3E54AE0B, 0xF85DDF44 =1/ln2 tail
_DP_H1 = 5.84962487220764160156e-01  # dp_h[1]: 0x3FE2B803, 0x40000000 (dp_h[0] = 0.0)
_DP_L1 = 1.35003920212974897128e-08  # dp_l[1]: 0x3E4CFDEB, 0x43CFD006 (dp_l[0] = 0.0)


_LO, _HI = (0, 1) if sys.byteorder == "little" else (1, 0)  # the words of a double as two int32


def _pow_yisint(iy: int, ly: int) -> int:
    """0: y is not an integer, 1: an odd integer, 2: an even integer (ftc_pow_yisint; ly as uint32)."""
    if iy >= 0x43400000:
        return 2  # even integer y
    if iy < 0x3FF00000:
        return 0
    k = (iy >> 20) - 0x3FF  # exponent
    # (jj << s) only clears the bits shifted out by (>> s), so it cannot exceed 32 bits
    if k > 20:
        jj = ly >> (52 - k)
        if (jj << (52 - k)) == ly:
            return 2 - (jj & 1)
    elif not ly:
        jj = iy >> (20 - k)
        if (jj << (20 - k)) == iy:
            return 2 - (jj & 1)
    return 0


def _pow_special_y(x: float, y: float, hx: int, lx: int, hy: int) -> float | None:
    """x**y for y = +-inf, +-1, 2 and (x >= +0) 0.5, else None; y's low word is 0 (ftc_pow_special_y)."""
    ix, iy = hx & 0x7FFFFFFF, hy & 0x7FFFFFFF
    if iy == 0x7FF00000:  # y is +-inf
        if not ((ix - 0x3FF00000) | lx):  # (-1)**+-inf is 1
            return 1.0
        if ix >= 0x3FF00000:  # (|x|>1)**+-inf = inf,0
            return y if hy >= 0 else 0.0
        return 0.0 if hy >= 0 else -y  # (|x|<1)**+-inf = 0,inf
    if iy == 0x3FF00000:  # y is +-1
        if hy >= 0:
            return x
        if not (ix | lx):  # C: 1/(+-0) = +-inf
            return -_INF if hx < 0 else _INF
        return 1 / x
    if hy == 0x40000000:  # y is 2
        return x * x
    if hy == 0x3FE00000 and hx >= 0:  # y is 0.5, x >= +0
        return _math_sqrt(x)
    return None


def _pow_special_x(ax: float, hx: int, hy: int, yisint: int) -> float:
    """x**y for x = +-0, +-inf, +-1 (ftc_pow_special_x)."""
    ix = hx & 0x7FFFFFFF
    z = ax
    if hy < 0:  # z = (1/|x|)
        z = _INF if ix == 0 else 1.0 / z
    if hx < 0:
        if not ((ix - 0x3FF00000) | yisint):
            z = _NAN_INVALID  # (-1)**non-int is NaN
        elif yisint == 1:
            z = -z  # (x<0)**odd = -(|x|**odd)
    return z


# The steps below share the caller's scratch double ``fd`` and its two int32 words ``wi`` (one
# per call of _pow, so that threads never share one): fdlibm's GET/SET_HIGH/LOW_WORD.


def _pow_log2_near_1(ax: float, fd: memoryview[float], wi: memoryview[int]) -> tuple[float, float]:
    """log2(ax) = t1 + t2 for |1-ax| <= 2**-20 by x-x^2/2+x^3/3-x^4/4 (ftc_pow_log2_near_1)."""
    t = ax - 1.0  # t has 20 trailing zeros
    w = (t * t) * (0.5 - t * (0.3333333333333333333333 - t * 0.25))
    u = _IVLN2_H * t  # ivln2_h has 21 sig. bits
    v = t * _IVLN2_L - w * _IVLN2
    fd[0] = u + v
    wi[_LO] = 0  # SET_LOW_WORD(t1, 0)
    t1 = fd[0]
    return t1, v - (t1 - u)


def _pow_log2(ax: float, ix: int, fd: memoryview[float], wi: memoryview[int]) -> tuple[float, float]:
    """log2(ax) = t1 + t2; ix: ax's high word (ftc_pow_log2)."""
    n = 0
    # take care subnormal number
    if ix < 0x00100000:
        ax *= _TWO53
        n -= 53
        fd[0] = ax
        ix = wi[_HI]
    n += (ix >> 20) - 0x3FF
    j = ix & 0x000FFFFF
    # determine interval
    ix = j | 0x3FF00000  # normalize ix
    k, bp, dp_h, dp_l = 0, 1.0, 0.0, 0.0  # |x|<sqrt(3/2)
    if 0x3988E < j < 0xBB67A:  # |x|<sqrt(3)
        k, bp, dp_h, dp_l = 1, 1.5, _DP_H1, _DP_L1
    elif j >= 0xBB67A:
        n += 1
        ix -= 0x00100000
    fd[0] = ax
    wi[_HI] = ix  # SET_HIGH_WORD(ax, ix)
    ax = fd[0]

    # compute ss = s_h+s_l = (x-1)/(x+1) or (x-1.5)/(x+1.5)
    u = ax - bp
    v = 1.0 / (ax + bp)
    ss = u * v
    fd[0] = ss
    wi[_LO] = 0  # SET_LOW_WORD(s_h, 0)
    s_h = fd[0]
    # t_h=ax+bp[k] High
    wi[_LO] = 0
    wi[_HI] = ((ix >> 1) | 0x20000000) + 0x00080000 + (k << 18)
    t_h = fd[0]
    t_l = ax - (t_h - bp)
    s_l = v * ((u - s_h * t_h) - s_h * t_l)
    # compute log(ax)
    s2 = ss * ss
    r = s2 * s2 * (_L1 + s2 * (_L2 + s2 * (_L3 + s2 * (_L4 + s2 * (_L5 + s2 * _L6)))))
    r += s_l * (s_h + ss)
    s2 = s_h * s_h
    fd[0] = 3.0 + s2 + r
    wi[_LO] = 0  # SET_LOW_WORD(t_h, 0)
    t_h = fd[0]
    t_l = r - ((t_h - 3.0) - s2)
    # u+v = ss*(1+...)
    u = s_h * t_h
    v = s_l * t_h + t_l * ss
    # 2/(3log2)*(ss+...)
    fd[0] = u + v
    wi[_LO] = 0  # SET_LOW_WORD(p_h, 0)
    p_h = fd[0]
    p_l = v - (p_h - u)
    z_h = _CP_H * p_h  # cp_h+cp_l = 2/(3*log2)
    z_l = _CP_L * p_h + p_l * _CP + dp_l
    # log2(ax) = (ss+..)*2/(3*log2) = n + dp_h + z_h + z_l
    t = float(n)
    fd[0] = ((z_h + z_l) + dp_h) + t
    wi[_LO] = 0  # SET_LOW_WORD(t1, 0)
    t1 = fd[0]
    return t1, z_l - (((t1 - t) - dp_h) - z_h)


def _pow_exp2(y: float, t1: float, t2: float, s: float, fd: memoryview[float], wi: memoryview[int]) -> float:
    """s * 2**(y*(t1+t2)) with fdlibm's overflow and underflow checks (ftc_pow_exp2)."""
    # split up y into y1+y2 and compute (y1+y2)*(t1+t2)
    fd[0] = y
    wi[_LO] = 0  # SET_LOW_WORD(y1, 0)
    y1 = fd[0]
    p_l = (y - y1) * t1 + y * t2
    p_h = y1 * t1
    z = p_l + p_h
    fd[0] = z
    i = wi[_LO]  # low word, only tested against 0
    j = wi[_HI]
    if j >= 0x40900000:  # z >= 1024
        if (j - 0x40900000) | i:  # z > 1024
            return s * _HUGE * _HUGE  # overflow
        if p_l + _OVT > z - p_h:
            return s * _HUGE * _HUGE  # overflow
    elif (j & 0x7FFFFFFF) >= 0x4090CC00:  # z <= -1075
        if ((j - 0xC090CC00) & 0xFFFFFFFF) | i:  # z < -1075 (C: unsigned arithmetic)
            return s * _TINY * _TINY  # underflow
        if p_l <= z - p_h:
            return s * _TINY * _TINY  # underflow

    # compute 2**(p_h+p_l)
    i = j & 0x7FFFFFFF
    k = (i >> 20) - 0x3FF
    n = 0
    if i > 0x3FE00000:  # |z| > 0.5, set n = [z+0.5]
        n = j + (0x00100000 >> (k + 1))  # stays within int32 (|z| < 1076)
        k = ((n & 0x7FFFFFFF) >> 20) - 0x3FF  # new k for n (0 <= k <= 10)
        wi[_LO] = 0
        wi[_HI] = n & ~(0x000FFFFF >> k)  # an int32 value (n's sign is kept by &)
        t = fd[0]
        n = ((n & 0x000FFFFF) | 0x00100000) >> (20 - k)
        if j < 0:
            n = -n
        p_h -= t
    fd[0] = p_l + p_h
    wi[_LO] = 0  # SET_LOW_WORD(t, 0)
    t = fd[0]
    u = t * _LG2_H
    v = (p_l - (t - p_h)) * _LG2 + t * _LG2_L
    z = u + v
    w = v - (z - u)
    t = z * z
    t1 = z - t * (_P1 + t * (_P2 + t * (_P3 + t * (_P4 + t * _P5))))
    r = (z * t1) / (t1 - 2.0) - (w + z * w)
    z = 1.0 - (r - z)
    fd[0] = z
    j = wi[_HI]
    j += n << 20  # no int32 overflow: z in [0.7, 1.5), -1075 <= n <= 1024
    if (j >> 20) <= 0:  # subnormal output
        return s * _scalbn(z, n)
    wi[_HI] = j  # SET_HIGH_WORD(z, j): fd still holds z; 0 < j < 0x7FF00000 here
    return s * fd[0]


def _pow_huge_y(ax: float, ix: int, iy: int, hy: int, s: float, fd: memoryview[float],
                wi: memoryview[int]) -> float | tuple[float, float]:
    """|y| > 2**31: the over- or underflowed result, or, for |x| within 2**-20 of 1, log2(|x|) as
    (t1, t2) (ftc_pow_huge_y)."""
    if iy > 0x43F00000:  # |y| > 2**64, must o/uflow
        if ix <= 0x3FEFFFFF:
            return _HUGE * _HUGE if hy < 0 else _TINY * _TINY
        if ix >= 0x3FF00000:
            return _HUGE * _HUGE if hy > 0 else _TINY * _TINY
    # over/underflow if x is not close to one
    if ix < 0x3FEFFFFF:
        return s * _HUGE * _HUGE if hy < 0 else s * _TINY * _TINY
    if ix > 0x3FF00000:
        return s * _HUGE * _HUGE if hy > 0 else s * _TINY * _TINY
    return _pow_log2_near_1(ax, fd, wi)


def _pow(x: float, y: float) -> float:
    """Return x**y exactly as musl's fdlibm pow (the same bits as ftc_pow in fmath_pow.h, cut into
    the same steps); x and y must be floats."""
    mv = memoryview(bytearray(8))
    fd = mv.cast("d")  # the 8 bytes as one double
    wi = mv.cast("i")  # the same bytes as int32 [low word, high word]
    fd[0] = x
    lx = wi[_LO]  # signed here; only ever tested against 0
    hx = wi[_HI]
    fd[0] = y
    ly = wi[_LO] & 0xFFFFFFFF  # C: uint32_t
    hy = wi[_HI]
    ix = hx & 0x7FFFFFFF
    iy = hy & 0x7FFFFFFF

    # x**0 = 1, even if x is NaN
    if not (iy | ly):
        return 1.0
    # 1**y = 1, even if y is NaN
    if hx == 0x3FF00000 and not lx:
        return 1.0
    # NaN if either arg is NaN (musl: x + y; SSE2 gives the first NaN operand, quieted)
    if ix > 0x7FF00000 or (ix == 0x7FF00000 and lx):
        return _double(_bits(x) | 0x0008000000000000)
    if iy > 0x7FF00000 or (iy == 0x7FF00000 and ly):
        return _double(_bits(y) | 0x0008000000000000)

    yisint = _pow_yisint(iy, ly) if hx < 0 else 0
    if not ly:
        z = _pow_special_y(x, y, hx, lx, hy)
        if z is not None:
            return z
    ax = abs(x)
    if not lx and (ix == 0x7FF00000 or ix == 0 or ix == 0x3FF00000):  # x is +-0,+-inf,+-1
        return _pow_special_x(ax, hx, hy, yisint)

    s = 1.0  # sign of result
    if hx < 0:
        if yisint == 0:  # (x<0)**(non-int) is NaN
            return _NAN_INVALID
        if yisint == 1:  # (x<0)**(odd int)
            s = -1.0
    if iy > 0x41E00000:  # |y| > 2**31
        logs = _pow_huge_y(ax, ix, iy, hy, s, fd, wi)
        if isinstance(logs, float):
            return logs
        t1, t2 = logs
    else:
        t1, t2 = _pow_log2(ax, ix, fd, wi)
    return _pow_exp2(y, t1, t2, s, fd, wi)


try:  # the compiled functions (controller/_fmath.c, built into every FMU): the same bits, faster
    from . import _fmath  # type: ignore[attr-defined]
except ImportError:
    if __name__.startswith("_ftc_"):  # bundled in an FMU (fmu_src/toolchain/build.py names the package so)
        raise  # a built FMU carries it: without it the build is broken, not slower
    _fmath = None  # not built here (make build compiles it into a checkout): the Python transcriptions
COMPILED = _fmath is not None
_EXP, _SIN, _COS, _POW = ((_fmath.exp, _fmath.sin, _fmath.cos, _fmath.pow) if _fmath is not None
                          else (_exp, _sin, _cos, _pow))


def exp(x: float) -> float:
    """e ** x with :func:`math.exp`'s contract: OverflowError where the result overflows."""
    x = float(x)
    y = _EXP(x)
    if y == _INF and x != _INF:
        raise OverflowError("math range error")
    return y


def sin(x: float) -> float:
    """sin(x) with :func:`math.sin`'s contract: ValueError for an infinite x, nan for nan."""
    x = float(x)
    if x == _INF or x == -_INF:
        raise ValueError("math domain error")
    return _SIN(x)


def cos(x: float) -> float:
    """cos(x) with :func:`math.cos`'s contract: ValueError for an infinite x, nan for nan."""
    x = float(x)
    if x == _INF or x == -_INF:
        raise ValueError("math domain error")
    return _COS(x)


def power(x: float, y: float) -> float:
    """x ** y with ``float ** float``'s special cases (CPython's float_pow), its ZeroDivisionError
    for 0 to a negative power, :func:`math.pow`'s OverflowError, and a ValueError where ``**``
    would give a complex number (a negative x to a non-integer y)."""
    x = float(x)
    y = float(y)
    if y == 0.0:
        return 1.0
    if x != x:
        return x
    if y != y:
        return 1.0 if x == 1.0 else y
    if y == _INF or y == -_INF:
        x = abs(x)
        if x == 1.0:
            return 1.0
        return abs(y) if (y > 0.0) == (x > 1.0) else 0.0
    odd = abs(y) % 2.0 == 1.0  # y is an odd integer
    if x == _INF or x == -_INF:
        if y > 0.0:
            return x if odd else abs(x)
        return _copysign(0.0, x) if odd else 0.0
    if x == 0.0:
        if y < 0.0:
            raise ZeroDivisionError("0.0 cannot be raised to a negative power")
        return x if odd else 0.0
    negate = False
    if x < 0.0:
        if y != _floor(y):
            raise ValueError(f"a negative number cannot be raised to a fractional power ({x!r} ** {y!r})")
        x = -x
        negate = odd
    if x == 1.0:
        return -1.0 if negate else 1.0
    z = _POW(x, y)
    if z == _INF:
        raise OverflowError("math range error")
    return -z if negate else z
