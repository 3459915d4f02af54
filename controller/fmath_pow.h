/* SPDX-License-Identifier: MIT */
/* pow(x, y) of fmath.h (included from there; musl's licence: fmath-LICENSE.txt):
   musl pow.c before its table-driven rewrite (fdlibm e_pow.c). Unlike musl, a nan result is built
   from bits (the first nan argument, quieted, as SSE2's x + y gives it; the x86 default nan for a
   negative x to a non-integer y), so that it does not depend on the compiler's operand order;
   n << 20 is done in uint32_t (no signed shift).

   musl's one function of 250 lines is cut at its own comments into the steps below, each the
   same statements in the same order (so the same bits: tests/test_fmath.py against fmath.py's
   _pow, cut alike, and against mpmath):
   ftc_pow_yisint      whether y is an odd or even integer (when x < 0);
   ftc_pow_special_y   y = +-inf, +-1, 2, 0.5;
   ftc_pow_special_x   x = +-0, +-inf, +-1;
   ftc_pow_log2_near_1 log2(|x|) as t1 + t2 when |y| > 2^31 and |x| is within 2^-20 of 1;
   ftc_pow_log2        log2(|x|) as t1 + t2 otherwise;
   ftc_pow_exp2        s * 2^(y * (t1 + t2)), with its overflow and underflow checks.

   Sun's notice, which fdlibm's e_pow.c carries: Copyright (C) 2004 by Sun Microsystems, Inc. All
   rights reserved. Permission to use, copy, modify, and distribute this software is freely
   granted, provided that this notice is preserved. */

#ifndef FTC_FMATH_POW_H
#define FTC_FMATH_POW_H

#define FTC_HI(x) ((int32_t)(ftc_bits(x) >> 32))
#define FTC_LO(x) ((uint32_t)ftc_bits(x))
#define FTC_ZERO_LO(x) ftc_double(ftc_bits(x) & 0xFFFFFFFF00000000ULL)
#define FTC_SET_HI(x, hi) ftc_double((ftc_bits(x) & 0xFFFFFFFFULL) | ((uint64_t)(uint32_t)(hi) << 32))

static const double
ftc_pow_bp[]   = {1.0, 1.5,},
ftc_pow_dp_h[] = { 0.0, 5.84962487220764160156e-01,}, /* 0x3FE2B803, 0x40000000 */
ftc_pow_dp_l[] = { 0.0, 1.35003920212974897128e-08,}, /* 0x3E4CFDEB, 0x43CFD006 */
ftc_pow_huge   =  1.0e300,
ftc_pow_tiny   =  1.0e-300,
ftc_pow_ivln2   =  1.44269504088896338700e+00, /* 0x3FF71547, 0x652B82FE =1/ln2 */
ftc_pow_ivln2_h =  1.44269502162933349609e+00, /* 0x3FF71547, 0x60000000 =24b 1/ln2*/
ftc_pow_ivln2_l =  1.92596299112661746887e-08; /* 0x3E54AE0B, 0xF85DDF44 =1/ln2 tail*/

/* yisint = 0: y is not an integer, 1: an odd integer, 2: an even integer (asked when x < 0) */
static int32_t ftc_pow_yisint(int32_t iy, uint32_t ly)
{
    int32_t k;
    if (iy >= 0x43400000)
        return 2; /* even integer y */
    if (iy < 0x3ff00000)
        return 0;
    k = (iy>>20) - 0x3ff;  /* exponent */
    if (k > 20) {
        uint32_t jj = ly>>(52-k);
        if ((jj<<(52-k)) == ly)
            return 2 - (int32_t)(jj&1);
    } else if (ly == 0) {
        uint32_t jj = (uint32_t)iy>>(20-k);
        if ((jj<<(20-k)) == (uint32_t)iy)
            return 2 - (int32_t)(jj&1);
    }
    return 0;
}

/* x**y for y = +-inf, +-1, 2 and (x >= +0) 0.5 into *z (1), else 0; ly == 0 */
static int ftc_pow_special_y(double x, double y, double *z)
{
    int32_t hx = FTC_HI(x), hy = FTC_HI(y);
    int32_t ix = hx & 0x7fffffff, iy = hy & 0x7fffffff;
    uint32_t lx = FTC_LO(x);
    if (iy == 0x7ff00000) {  /* y is +-inf */
        if (((ix-0x3ff00000)|lx) == 0)  /* (-1)**+-inf is 1 */
            *z = 1.0;
        else if (ix >= 0x3ff00000) /* (|x|>1)**+-inf = inf,0 */
            *z = hy >= 0 ? y : 0.0;
        else                       /* (|x|<1)**+-inf = 0,inf */
            *z = hy >= 0 ? 0.0 : -y;
        return 1;
    }
    if (iy == 0x3ff00000) {    /* y is +-1 */
        *z = hy >= 0 ? x : 1/x;
        return 1;
    }
    if (hy == 0x40000000) {   /* y is 2 */
        *z = x*x;
        return 1;
    }
    if (hy == 0x3fe00000 && hx >= 0) {  /* y is 0.5, x >= +0 */
        *z = ftc_sqrt(x);
        return 1;
    }
    return 0;
}

/* x**y for x = +-0, +-inf, +-1 (lx == 0 and ix one of those) */
static double ftc_pow_special_x(double ax, int32_t hx, int32_t hy, int32_t yisint)
{
    int32_t ix = hx & 0x7fffffff;
    double z = ax;
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

/* log2(ax) = t1 + t2 for |1-ax| <= 2**-20 (t has 20 trailing zeros): x-x^2/2+x^3/3-x^4/4 */
static void ftc_pow_log2_near_1(double ax, double *t1, double *t2)
{
    double t, w, u, v;
    t = ax - 1.0;
    w = (t*t)*(0.5 - t*(0.3333333333333333333333-t*0.25));
    u = ftc_pow_ivln2_h*t;      /* ivln2_h has 21 sig. bits */
    v = t*ftc_pow_ivln2_l - w*ftc_pow_ivln2;
    *t1 = u + v;
    *t1 = FTC_ZERO_LO(*t1);
    *t2 = v - (*t1-u);
}

/* log2(ax) = t1 + t2 (ix: ax's high word) */
static void ftc_pow_log2(double ax, int32_t ix, double *t1, double *t2)
{
    static const double
    two53  =  9007199254740992.0, /* 0x43400000, 0x00000000 */
    /* poly coefs for (3/2)*(log(x)-2s-2/3*s**3 */
    L1 =  5.99999999999994648725e-01, /* 0x3FE33333, 0x33333303 */
    L2 =  4.28571428578550184252e-01, /* 0x3FDB6DB6, 0xDB6FABFF */
    L3 =  3.33333329818377432918e-01, /* 0x3FD55555, 0x518F264D */
    L4 =  2.72728123808534006489e-01, /* 0x3FD17460, 0xA91D4101 */
    L5 =  2.30660745775561754067e-01, /* 0x3FCD864A, 0x93C9DB65 */
    L6 =  2.06975017800338417784e-01, /* 0x3FCA7E28, 0x4A454EEF */
    cp      =  9.61796693925975554329e-01, /* 0x3FEEC709, 0xDC3A03FD =2/(3ln2) */
    cp_h    =  9.61796700954437255859e-01, /* 0x3FEEC709, 0xE0000000 =(float)cp */
    cp_l    = -7.02846165095275826516e-09; /* 0xBE3E2FE0, 0x145B01F5 =tail of cp_h*/
    double ss,s2,s_h,s_l,t_h,t_l,u,v,r,p_h,p_l,z_h,z_l,t;
    int32_t j,k,n = 0;
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
    *t1 = ((z_h + z_l) + ftc_pow_dp_h[k]) + t;
    *t1 = FTC_ZERO_LO(*t1);
    *t2 = z_l - (((*t1 - t) - ftc_pow_dp_h[k]) - z_h);
}

/* s * 2**(y*(t1+t2)) */
static double ftc_pow_exp2(double y, double t1, double t2, double s)
{
    static const double
    P1 =  1.66666666666666019037e-01, /* 0x3FC55555, 0x5555553E */
    P2 = -2.77777777770155933842e-03, /* 0xBF66C16C, 0x16BEBD93 */
    P3 =  6.61375632143793436117e-05, /* 0x3F11566A, 0xAF25DE2C */
    P4 = -1.65339022054652515390e-06, /* 0xBEBBBD41, 0xC5D26BF1 */
    P5 =  4.13813679705723846039e-08, /* 0x3E663769, 0x72BEA4D0 */
    lg2     =  6.93147180559945286227e-01, /* 0x3FE62E42, 0xFEFA39EF */
    lg2_h   =  6.93147182464599609375e-01, /* 0x3FE62E43, 0x00000000 */
    lg2_l   = -1.90465429995776804525e-09, /* 0xBE205C61, 0x0CA86C39 */
    ovt     =  8.0085662595372944372e-017; /* -(1024-log2(ovfl+.5ulp)) */
    double y1,p_h,p_l,z,t,u,v,w,r;
    int32_t i,j,k,n;

    /* split up y into y1+y2 and compute (y1+y2)*(t1+t2) */
    y1 = FTC_ZERO_LO(y);
    p_l = (y-y1)*t1 + y*t2;
    p_h = y1*t1;
    z = p_l + p_h;
    j = FTC_HI(z); i = (int32_t)FTC_LO(z);
    if (j >= 0x40900000) {                      /* z >= 1024 */
        if (((j-0x40900000)|i) != 0)        /* if z > 1024 */
            return s*ftc_pow_huge*ftc_pow_huge;         /* overflow */
        if (p_l + ovt > z - p_h)
            return s*ftc_pow_huge*ftc_pow_huge;         /* overflow */
    } else if ((j&0x7fffffff) >= 0x4090cc00) {  /* z <= -1075 */
        if ((((uint32_t)j-0xc090cc00u)|(uint32_t)i) != 0)  /* z < -1075 */
            return s*ftc_pow_tiny*ftc_pow_tiny;         /* underflow */
        if (p_l <= z - p_h)
            return s*ftc_pow_tiny*ftc_pow_tiny;         /* underflow */
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

/* |y| > 2**31: over- or underflow unless |x| is within 2**-20 of 1 (then 0 and log2 into t1, t2) */
static int ftc_pow_huge_y(double ax, int32_t ix, int32_t iy, int32_t hy, double s, double *z,
                          double *t1, double *t2)
{
    const double huge = ftc_pow_huge, tiny = ftc_pow_tiny;
    if (iy > 0x43f00000) {  /* if |y| > 2**64, must o/uflow */
        if (ix <= 0x3fefffff) {
            *z = hy < 0 ? huge*huge : tiny*tiny;
            return 1;
        }
        if (ix >= 0x3ff00000) {
            *z = hy > 0 ? huge*huge : tiny*tiny;
            return 1;
        }
    }
    /* over/underflow if x is not close to one */
    if (ix < 0x3fefffff) {
        *z = hy < 0 ? s*huge*huge : s*tiny*tiny;
        return 1;
    }
    if (ix > 0x3ff00000) {
        *z = hy > 0 ? s*huge*huge : s*tiny*tiny;
        return 1;
    }
    ftc_pow_log2_near_1(ax, t1, t2);
    return 0;
}

static double ftc_pow(double x, double y)
{
    double z,ax,s,t1,t2;
    int32_t yisint;
    int32_t hx = FTC_HI(x), hy = FTC_HI(y);
    int32_t ix = hx & 0x7fffffff, iy = hy & 0x7fffffff;
    uint32_t lx = FTC_LO(x), ly = FTC_LO(y);

    /* x**0 = 1, even if x is NaN */
    if ((iy|ly) == 0)
        return 1.0;
    /* 1**y = 1, even if y is NaN */
    if (hx == 0x3ff00000 && lx == 0)
        return 1.0;
    /* NaN if either arg is NaN (musl: return x + y; SSE2 result: first NaN operand, quieted) */
    if (ix > 0x7ff00000 || (ix == 0x7ff00000 && lx != 0))
        return ftc_double(ftc_bits(x) | 0x0008000000000000ULL);
    if (iy > 0x7ff00000 || (iy == 0x7ff00000 && ly != 0))
        return ftc_double(ftc_bits(y) | 0x0008000000000000ULL);

    yisint = hx < 0 ? ftc_pow_yisint(iy, ly) : 0;
    if (ly == 0 && ftc_pow_special_y(x, y, &z))
        return z;
    ax = ftc_double(ftc_bits(x) & 0x7FFFFFFFFFFFFFFFULL); /* fabs(x) */
    if (lx == 0 && (ix == 0x7ff00000 || ix == 0 || ix == 0x3ff00000)) /* x is +-0,+-inf,+-1 */
        return ftc_pow_special_x(ax, hx, hy, yisint);

    s = 1.0; /* sign of result */
    if (hx < 0) {
        if (yisint == 0) /* (x<0)**(non-int) is NaN; musl: (x-x)/(x-x) */
            return ftc_double(0xFFF8000000000000ULL);
        if (yisint == 1) /* (x<0)**(odd int) */
            s = -1.0;
    }
    if (iy > 0x41e00000) { /* |y| > 2**31 */
        if (ftc_pow_huge_y(ax, ix, iy, hy, s, &z, &t1, &t2))
            return z;
    } else
        ftc_pow_log2(ax, ix, &t1, &t2);
    return ftc_pow_exp2(y, t1, t2, s);
}

#undef FTC_HI
#undef FTC_LO
#undef FTC_ZERO_LO
#undef FTC_SET_HI

#endif
