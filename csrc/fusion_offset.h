/*
 * FusionOffset: the gyroscope offset estimator of Longbin's walkthrough (x-io Fusion,
 * imufusion 1.2.3). While every axis of the corrected gyroscope stays within
 * 3 degrees per second for 5 seconds, the offset follows the corrected
 * gyroscope through a first-order low-pass filter with a 0.02 Hz cutoff:
 *   b <- b + 2 pi fc / fs * (w - b)
 * UNITS ARE FUSION'S: degrees per second; the sample rate in Hz is fixed at
 * init (one update per sample). Non-finite policy: a sample with a
 * non-finite gyroscope value leaves the state unchanged (`skipped`).
 */
#ifndef IMF_FUSION_OFFSET_H
#define IMF_FUSION_OFFSET_H

#include <stdint.h>
#include "fusion_math.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    imf_real filter_coefficient; /* 2 pi fc / fs */
    uint32_t timeout;            /* samples at rest before the offset adapts */
} imf_fusion_offset_config_t;

typedef struct {
    imf_real offset_x, offset_y, offset_z; /* degrees per second */
    uint32_t timer;                        /* samples at rest so far, <= timeout */
} imf_fusion_offset_state_t;

#define IMF_FUSION_OFFSET_N_STATE 4

typedef struct {
    imf_fusion_offset_config_t set; /* internal: the settings as init converted them */
    uint32_t skipped;               /* samples rejected by the non-finite policy (state kept) */
    imf_fusion_offset_state_t
        x; /* the state (above): the estimate; write it only through the API */
} imf_fusion_offset_t;

/* sample_rate: Hz (> 0) */
void imf_fusion_offset_init(imf_fusion_offset_t *self, uint32_t sample_rate);
/* g: gyroscope (3), degrees per second; out: corrected gyroscope (3) */
void imf_fusion_offset_update(imf_fusion_offset_t *self, const imf_real *g, imf_real *out);
/* The state as IMF_FUSION_OFFSET_N_STATE reals (the offset, deg/s, and the
 * stationary timer), and back. */
void imf_fusion_offset_get_state(const imf_fusion_offset_t *self, imf_real *out);
void imf_fusion_offset_set_state(imf_fusion_offset_t *self, const imf_real *in);

#ifdef __cplusplus
}
#endif

#endif /* IMF_FUSION_OFFSET_H */
