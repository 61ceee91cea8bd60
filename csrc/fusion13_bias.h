/*
 * FusionBias: the gyroscope bias algorithm of x-io Fusion's current release (1.3, as in
 * imufusion 1.3.3), beside 1.2.3's FusionOffset (fusion_offset.h); a float32 build reproduces
 * imufusion 1.3.3's Bias bit for bit.
 *
 * UNITS ARE FUSION'S: gyroscope in degrees per second, sample rate in Hz, stationary period in
 * seconds. While every axis of the corrected gyroscope stays within the stationary threshold
 * for the stationary period, the offset follows it through a first-order filter of 0.02 Hz
 * cutoff:
 *   b <- b + 2 pi fc / fs * (w - b)
 * The offset can be read and written (the state), to keep it in non-volatile memory across
 * restarts. Non-finite policy: a sample with a non-finite gyroscope value leaves the state
 * unchanged (`skipped`) and is returned as given.
 */
#ifndef IMF_FUSION13_BIAS_H
#define IMF_FUSION13_BIAS_H

#include <stdint.h>
#include "fusion_math.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Bias settings (FusionBiasSettings). */
typedef struct {
    imf_real sample_rate;          /* Hz, > 0 */
    imf_real stationary_threshold; /* degrees per second */
    imf_real stationary_period;    /* seconds */
} imf_fusion13_bias_settings_t;

typedef struct {
    imf_real stationary_threshold; /* degrees per second */
    imf_real filter_coefficient;   /* 2 pi 0.02 Hz / rate */
    uint32_t timeout;              /* samples: (uint32) (period * rate) */
} imf_fusion13_bias_config_t;

typedef struct {
    imf_real offset_x, offset_y, offset_z; /* degrees per second */
    uint32_t timer;                        /* samples at rest so far, <= timeout */
} imf_fusion13_bias_state_t;

#define IMF_FUSION13_BIAS_N_STATE 4

typedef struct {
    imf_fusion13_bias_config_t set; /* internal */
    uint32_t skipped;               /* samples rejected by the non-finite policy */
    imf_fusion13_bias_state_t x;    /* the state */
} imf_fusion13_bias_t;

/* Defaults: 100 Hz, 3 degrees per second, 3 seconds. */
void imf_fusion13_bias_default_settings(imf_fusion13_bias_settings_t *settings);
/* settings: NULL for the defaults; timer and offset start at zero. */
void imf_fusion13_bias_init(imf_fusion13_bias_t *self,
                            const imf_fusion13_bias_settings_t *settings);
void imf_fusion13_bias_set_settings(imf_fusion13_bias_t *self,
                                    const imf_fusion13_bias_settings_t *settings);
/* g: gyroscope (3), degrees per second; out: offset-corrected gyroscope (3). */
void imf_fusion13_bias_update(imf_fusion13_bias_t *self, const imf_real *g, imf_real *out);
/* The state (offset, deg/s, and timer) as IMF_FUSION13_BIAS_N_STATE reals, and back. */
void imf_fusion13_bias_get_state(const imf_fusion13_bias_t *self, imf_real *out);
void imf_fusion13_bias_set_state(imf_fusion13_bias_t *self, const imf_real *in);

#ifdef __cplusplus
}
#endif

#endif /* IMF_FUSION13_BIAS_H */
