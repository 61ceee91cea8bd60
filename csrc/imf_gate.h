/*
 * Accelerometer-magnitude gate of Hari Nair (2016): an attitude filter
 * uses the accelerometer for its correction only while the measured
 * magnitude is near 1 g (Nair: 0.6 g to 1.4 g); in low-g or high-g
 * phases (turns, pulls) it integrates the gyro alone. Squared magnitudes
 * are compared, so no square root is needed. Header-only, static inline.
 */
#ifndef IMF_GATE_H
#define IMF_GATE_H

#include "imf_config.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Convert the gate settings once: lo, hi in units of 1 g, one_g in the
   accelerometer's unit. lo < 0 turns the gate off (the state after init). */
static inline void imf_acc_gate_set(int *const on, imf_real *const lo2, imf_real *const hi2,
                                    const imf_real lo, const imf_real hi, const imf_real one_g)
{
    const imf_real l = lo * one_g;
    const imf_real h = hi * one_g;
    *on = lo >= IMF_R(0.0);
    *lo2 = l * l;
    *hi2 = h * h;
}

/* |a|^2, the magnitude the gate compares (one order of operations for every user). */
static inline imf_real imf_acc_gate_norm2(const imf_real ax, const imf_real ay, const imf_real az)
{
    return ax * ax + ay * ay + az * az;
}

/* The gate's interval test on n2 = |a|^2, one expression for a scalar (AND: &&) and for
   the lanes of a GCC vector (AND: &, 0 or -1 per lane: the host's lane kernels,
   imufuse_c/host/lanes_body.h). */
#define IMF_ACC_GATE_IN(n2, lo2, hi2, AND) (((n2) >= (lo2)) AND((n2) <= (hi2)))

/* 1 when the correction may use a = (ax, ay, az): the gate is off, or
   lo2 <= |a|^2 <= hi2. */
static inline int imf_acc_gate_pass(const int on, const imf_real lo2, const imf_real hi2,
                                    const imf_real ax, const imf_real ay, const imf_real az)
{
    imf_real n2;
    if (!on) {
        return 1;
    }
    n2 = imf_acc_gate_norm2(ax, ay, az);
    return IMF_ACC_GATE_IN(n2, lo2, hi2, &&);
}

#ifdef __cplusplus
}
#endif

#endif /* IMF_GATE_H */
