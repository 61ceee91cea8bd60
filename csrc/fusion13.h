/*
 * FusionAHRS13: x-io Fusion's current release (1.3, as in imufusion 1.3.3),
 * written from the algorithm beside the 1.2.3 port (fusion_ahrs.h); a float32 build
 * reproduces imufusion 1.3.3 (built with FUSION_USE_NORMAL_SQRT) bit for bit.
 *
 * UNITS ARE FUSION'S: gyroscope in degrees per second, accelerometer in g,
 * magnetometer in any unit, sample rate in Hz, sample period and timeouts in
 * seconds, angles in degrees.
 *
 * The AHRS is the 1.2.3 complementary filter on q (fusion_ahrs.h) with what 1.3
 * changed:
 *   - the sample period is a setting (1 / sample_rate), replaced before an update
 *     by imf_fusion13_ahrs_set_sample_period (the measured period);
 *   - start-up: the gain starts at 10 and drops by (10 - gain)/3 s * period (the
 *     settings' period) every update until it reaches gain; it can be skipped;
 *   - overrange: |w_i| > 0.98 range restarts the filter keeping q and the last
 *     accelerometer sample, and flags overrange recovery until start-up ends;
 *   - rejection: the timeout is given in seconds (samples = rate * timeout);
 *   - the residual of exactly opposite vectors is zero (1.2.3 gives NaN);
 *   - gravity and linear acceleration are outputs of the current q.
 * FusionBias, 1.3's gyroscope bias algorithm, is fusion13_bias.h.
 *
 * imufuse additions (never active on inputs Fusion handles): float64; the
 * zero-vector guard of fusion_math.h's exact normalisation; and the non-finite
 * policy of fusion_ahrs.h (a sample with a non-finite input, or whose update
 * leaves a non-finite state, is rejected: state restored, `skipped` counted).
 */
#ifndef IMF_FUSION13_H
#define IMF_FUSION13_H

#include <stdint.h>
#include "fusion_math.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Settings as given by the user (FusionAhrsSettings of Fusion 1.3). */
typedef struct {
    imf_real sample_rate;            /* Hz, > 0 */
    int convention;                  /* IMF_FUSION_NWU, _ENU or _NED */
    imf_real gain;                   /* dimensionless, >= 0 (0: gyroscope only) */
    imf_real gyroscope_range;        /* degrees per second; 0 disables */
    imf_real acceleration_rejection; /* degrees; 0 disables */
    imf_real magnetic_rejection;     /* degrees; 0 disables */
    imf_real rejection_timeout;      /* seconds; 0 disables rejection */
} imf_fusion13_ahrs_settings_t;

/* The settings converted once into what the update needs. */
typedef struct {
    int convention;                  /* IMF_FUSION_* */
    imf_real gain;                   /* as set */
    imf_real startup_gain_rate;      /* (10 - gain) / 3 s * settings' period, per update */
    int overrange_enabled;           /* gyroscope_range > 0 */
    imf_real overrange_threshold;    /* 0.98 * range */
    imf_real acceleration_rejection; /* (sin(threshold)/2)^2, or the largest real */
    imf_real magnetic_rejection;     /* (sin(threshold)/2)^2, or the largest real */
    int32_t rejection_timeout;       /* samples: (int32) (rate * timeout) */
    int invsqrt;                     /* IMF_FUSION_INVSQRT_EXACT or _FAST */
} imf_fusion13_ahrs_config_t;

/* Everything that determines the future. */
typedef struct {
    imf_real q0, q1, q2, q3;      /* quaternion w, x, y, z */
    imf_real acc_x, acc_y, acc_z; /* last accelerometer sample, g */
    imf_real startup_gain;        /* the gain during start-up, ramped down to gain */
    imf_real half_acc_res_x, half_acc_res_y, half_acc_res_z; /* accelerometer residual / 2 */
    imf_real half_mag_res_x, half_mag_res_y, half_mag_res_z; /* magnetometer residual / 2 */
    imf_real sample_period;                  /* seconds, integrates the next update */
    int32_t startup;                         /* 0 or 1 */
    int32_t overrange_recovery;              /* 0 or 1 */
    int32_t accelerometer_ignored;           /* 0 or 1 */
    int32_t acceleration_recovery_trigger;   /* samples, counts up while rejected */
    int32_t acceleration_recovery_threshold; /* samples */
    int32_t magnetometer_ignored;            /* 0 or 1 */
    int32_t magnetic_recovery_trigger;       /* samples, counts up while rejected */
    int32_t magnetic_recovery_threshold;     /* samples */
} imf_fusion13_ahrs_state_t;

#define IMF_FUSION13_AHRS_N_STATE 23
#define IMF_FUSION13_AHRS_N_REAL 15

typedef struct {
    imf_fusion13_ahrs_config_t set; /* internal: the settings as converted */
    uint32_t skipped;               /* samples rejected by the non-finite policy */
    imf_fusion13_ahrs_state_t x;    /* the state (above); write it only through the API */
} imf_fusion13_ahrs_t;

/* Outputs: the order of imf_fusion13_ahrs_outputs(), as fusion_ahrs.h's
   IMF_FUSION_OUT_* (gravity 0, linear 3, earth 6, euler 9, acceleration error 12,
   its trigger 13, magnetic error 14, its trigger 15); flags as IMF_FUSION_FLAG_*
   (start-up 1, overrange recovery 2, acceleration recovery 4, magnetic recovery 8,
   accelerometer ignored 16, magnetometer ignored 32). */

/* Default settings (fusionAhrsDefaultSettings): 100 Hz, NWU, gain 0.5, no range,
   no rejection, timeout 0. */
void imf_fusion13_ahrs_default_settings(imf_fusion13_ahrs_settings_t *settings);
/* settings: NULL for the defaults; invsqrt: IMF_FUSION_INVSQRT_*. Restarts. */
void imf_fusion13_ahrs_init(imf_fusion13_ahrs_t *self, const imf_fusion13_ahrs_settings_t *settings,
                            int invsqrt);
/* New settings (FusionAhrsSetSettings): the period becomes 1 / sample_rate; the
   state is kept. */
void imf_fusion13_ahrs_set_settings(imf_fusion13_ahrs_t *self,
                                    const imf_fusion13_ahrs_settings_t *settings);
/* sample_period: seconds, the measured period of the next updates (start-up
   keeps the settings' rate). A non-finite or negative period is rejected (skipped). */
void imf_fusion13_ahrs_set_sample_period(imf_fusion13_ahrs_t *self, imf_real sample_period);
/* Back to the initial state (identity, start-up), keeping the settings. */
void imf_fusion13_ahrs_restart(imf_fusion13_ahrs_t *self);
/* End start-up now (the initial orientation is known). */
void imf_fusion13_ahrs_skip_startup(imf_fusion13_ahrs_t *self);

/* gx, gy, gz: degrees per second; ax, ay, az: g; mx, my, mz: any unit. */
void imf_fusion13_ahrs_update(imf_fusion13_ahrs_t *self, imf_real gx, imf_real gy, imf_real gz,
                              imf_real ax, imf_real ay, imf_real az, imf_real mx, imf_real my,
                              imf_real mz);
/* Without magnetometer: heading held at 0 during start-up. */
void imf_fusion13_ahrs_update_no_magnetometer(imf_fusion13_ahrs_t *self, imf_real gx, imf_real gy,
                                              imf_real gz, imf_real ax, imf_real ay, imf_real az);
/* heading: degrees, from an external source, in place of a magnetometer. */
void imf_fusion13_ahrs_update_external_heading(imf_fusion13_ahrs_t *self, imf_real gx, imf_real gy,
                                               imf_real gz, imf_real ax, imf_real ay, imf_real az,
                                               imf_real heading);
/* Rotate q about the earth vertical so that its yaw is heading (degrees). */
void imf_fusion13_ahrs_set_heading(imf_fusion13_ahrs_t *self, imf_real heading);

/* The state as IMF_FUSION13_AHRS_N_STATE reals, in struct order, and back. */
void imf_fusion13_ahrs_get_state(const imf_fusion13_ahrs_t *self, imf_real *out);
void imf_fusion13_ahrs_set_state(imf_fusion13_ahrs_t *self, const imf_real *in);
/* All outputs, IMF_FUSION_N_OUT reals; flags as bits. */
void imf_fusion13_ahrs_outputs(const imf_fusion13_ahrs_t *self, imf_real *out);
unsigned imf_fusion13_ahrs_flags(const imf_fusion13_ahrs_t *self);

/* The compass of 1.3 (FusionCompass) has the operations of 1.2.3's: it is
   imf_fusion_compass_heading (fusion_ahrs.h). The sensor models (FusionModelInertial,
   FusionModelMagnetic) and the remap (FusionRemap) are those of fusion_calibration.h. */

#ifdef __cplusplus
}
#endif

#endif /* IMF_FUSION13_H */
