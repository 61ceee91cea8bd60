/*
 * imufuse_c lanes: many parameter sets of one filter over one log, and the BROAD scores
 * computed while the filter runs. Host only (the Python extension), never part of csrc/.
 *
 * Lanes: P filters of one class, each with its own settings, step side by side in the
 * SIMD lanes of one register (GCC vector extensions; AVX-512, AVX2, SSE2 or one lane, chosen
 * at run time). Each lane performs the operations of the filter's scalar C update in the
 * same order, with the valid-attitude policy decided per lane, so each lane's state is bit
 * for bit the state the scalar update computes. Built with the numerical contract (-O2
 * -ffp-contract=off, no fast-math): vector +, -, *, / and sqrt are the same correctly
 * rounded IEEE operations as the scalar ones.
 *
 * Scores: each sample's estimate (a sensor-to-earth NWU quaternion) is compared with the
 * reference (sensor-to-ENU, unit, prepared by imufuse.evaluation.prepare_reference) where the
 * sample counts, and the squares of the total, heading and inclination errors (degrees) are
 * summed per set: imufuse.evaluation.evaluate's definitions, within 1e-12 relative (its
 * arccos/arctan2 are computed here by one arctangent, Cephes' rational approximation).
 */
#ifndef IMF_LANES_H
#define IMF_LANES_H

#include <stddef.h>
#include <stdint.h>

#include "imf_config.h"

/* A log's reference, prepared once for every set scored on it. */
typedef struct {
    const unsigned char *use; /* (N,): 1 where the sample counts (movement mask, finite ref) */
    const double *r;          /* (N, 4): the reference, sensor-to-ENU, unit, w x y z */
    int store;                /* 1: keep e_w, e_z per counted sample (heading offset removal,
                                 finished in Python); 0: sum the squared errors */
} imf_scorer_t;

/* One set's score so far. */
typedef struct {
    double sq[3];       /* sum of squared errors, deg^2: total, heading, inclination */
    double n_est_nan;   /* counted samples whose estimate is not finite (or has no norm) */
    ptrdiff_t j;        /* counted samples so far (the store index) */
    double *ew, *ez;    /* store: the error quaternion's w and z, per counted sample */
    unsigned char *ok;  /* store: 1 where the estimate is finite */
} imf_score_acc_t;

/* Estimate adapters (imufuse.shared.estimate): a state read as a quaternion w x y z, NWU,
   sensor-to-earth, not necessarily unit. */
enum { IMF_EST_QUATERNION = 0, IMF_EST_MATRIX = 1, IMF_EST_GRAVITY = 2, IMF_EST_EULER = 3 };
void imf_estimate_q(int adapter, const double *s, const int *idx, double q[4]);

/* Score sample k of one set (one lane: the scalar path of every filter). */
void imf_score_q(const imf_scorer_t *sc, imf_score_acc_t *acc, ptrdiff_t k, const double q[4]);

/* A lane kernel: run filters f[0..p) (pointers to their C structs, one class, p <= width)
   over samples k0..k1 of gyr, acc, mag ((N, 3), mag NULL for 6-D filters), dts ((N,)
   periods or NULL: each filter's own dt); out[i] (NULL or (N, state) rows) receives
   filter i's state after each sample; with sc, acc[i] is scored. Returns 0 without running
   when the group cannot share lanes (settings that select code paths differ). */
typedef int (*imf_lanes_fn)(void *const *f, int p, ptrdiff_t k0, ptrdiff_t k1,
                            const imf_real *gyr, const imf_real *acc, const imf_real *mag,
                            const imf_real *dts, const imf_scorer_t *sc, imf_score_acc_t *accs,
                            imf_real *const *out);

/* The kernel running the scalar update c_update ("imf_madgwick_update", "..._update_imu")
   at `width` lanes (1, 2, 4, 8), or NULL (no kernel, or the CPU lacks the width). */
imf_lanes_fn imf_lanes_kernel(const char *c_update, int width);
/* The widest lane count this CPU runs (8 AVX-512F, 4 AVX2, 2 SSE2 / generic, 1). */
int imf_lanes_best(void);
/* "avx512f", "avx2", "sse2", "generic" or "scalar": what `width` runs on. */
const char *imf_lanes_isa(int width);

#endif /* IMF_LANES_H */
