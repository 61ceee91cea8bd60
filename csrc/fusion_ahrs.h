/*
 * FusionAHRS: the AHRS of Longbin's Fusion walkthrough, x-io Fusion as shipped in imufusion 1.2.3,
 * written from the algorithm; a float32 build reproduces imufusion 1.2.3
 * (built with FUSION_USE_NORMAL_SQRT) bit for bit.
 *
 * UNITS ARE FUSION'S: gyroscope in degrees per second, accelerometer in g,
 * magnetometer in any unit, dt in seconds per update, angles in degrees.
 *
 * A complementary filter on the quaternion q (w, x, y, z; sensor -> earth):
 *   q <- normalise(q + q (x) (0, dt (w/2 + g_r (e_a + e_m))))
 * with w the gyroscope in rad/s, e_a = a_hat x (R^T up)/2 the accelerometer
 * feedback and e_m the magnetometer feedback (the measured horizontal field
 * direction against the predicted one), each halved, and g_r the gain.
 * Behaviour:
 *   - startup: g_r ramps down from 10 to `gain` at (10 - gain)/3 per second
 *     ("initialising"); rejection is off meanwhile;
 *   - gyroscope overrange (|w_i| > 0.98 gyroscope_range): reset, keeping q,
 *     and flag angular-rate recovery until the ramp ends;
 *   - rejection: a feedback whose |e|^2 exceeds (sin(threshold)/2)^2 is
 *     ignored; the recovery trigger counts -9 per accepted and +1 per
 *     rejected sample, clamped to [0, recovery_trigger_period]; when it
 *     exceeds the timeout the feedback is forced on (recovery) and the
 *     timeout drops to 0 until the trigger falls back;
 *   - an all-zero accelerometer or magnetometer skips that feedback.
 * Conventions NWU, ENU, NED choose the earth axes (gravity up or down, the
 * magnetic reference along north or east).
 *
 * imufuse additions (never active on inputs Fusion handles): float64; the
 * zero-vector guard in the exact normalisation (fusion_math.h); and the
 * non-finite policy: a sample with a non-finite input or dt, a negative dt,
 * or whose update leaves a non-finite state is rejected (state restored,
 * `skipped` incremented).
 */
#ifndef IMF_FUSION_AHRS_H
#define IMF_FUSION_AHRS_H

#include <stdint.h>
#include "fusion_math.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Settings as given by the user (FusionAhrsSettings). */
typedef struct {
    int convention;                  /* IMF_FUSION_NWU, _ENU or _NED */
    imf_real gain;                   /* dimensionless, >= 0 (0: gyroscope only) */
    imf_real gyroscope_range;        /* degrees per second; 0 disables */
    imf_real acceleration_rejection; /* degrees; 0 disables */
    imf_real magnetic_rejection;     /* degrees; 0 disables */
    int32_t recovery_trigger_period; /* samples; 0 disables rejection */
} imf_fusion_ahrs_settings_t;

/* The settings converted once into what the update needs. */
typedef struct {
    int convention;                  /* IMF_FUSION_CONVENTION_* */
    imf_real gain;                   /* as set */
    imf_real gyroscope_range;        /* 0.98 * range, or the largest real */
    imf_real acceleration_rejection; /* (sin(threshold)/2)^2, or the largest real */
    imf_real magnetic_rejection;     /* (sin(threshold)/2)^2, or the largest real */
    int32_t recovery_trigger_period; /* samples; 0 disables rejection */
    imf_real ramped_gain_step;       /* (10 - gain) / 3 s, per second */
    int invsqrt;                     /* IMF_FUSION_INVSQRT_EXACT or _FAST */
} imf_fusion_ahrs_config_t;

/* Everything that determines the future. */
typedef struct {
    imf_real q0, q1, q2, q3;      /* quaternion w, x, y, z */
    imf_real acc_x, acc_y, acc_z; /* last accelerometer sample, g */
    imf_real ramped_gain;         /* the gain during initialisation, ramped down to gain */
    imf_real half_acc_fb_x, half_acc_fb_y, half_acc_fb_z; /* last accelerometer feedback / 2 */
    imf_real half_mag_fb_x, half_mag_fb_y, half_mag_fb_z; /* last magnetometer feedback / 2 */
    int32_t initialising;                                 /* 0 or 1 */
    int32_t angular_rate_recovery;                        /* 0 or 1 */
    int32_t accelerometer_ignored;                        /* 0 or 1 */
    int32_t acceleration_recovery_trigger;                /* samples, counts up while rejected */
    int32_t acceleration_recovery_timeout;                /* samples */
    int32_t magnetometer_ignored;                         /* 0 or 1 */
    int32_t magnetic_recovery_trigger;                    /* samples, counts up while rejected */
    int32_t magnetic_recovery_timeout;                    /* samples */
} imf_fusion_ahrs_state_t;

#define IMF_FUSION_AHRS_N_STATE 22

typedef struct {
    imf_fusion_ahrs_config_t set; /* internal: the settings as init converted them */
    uint32_t skipped;             /* samples rejected by the non-finite policy */
    imf_fusion_ahrs_state_t x; /* the state (above): the estimate; write it only through the API */
} imf_fusion_ahrs_t;

/* Outputs (FusionAhrsGet*), computed from the state; the order of
   imf_fusion_ahrs_outputs(). */
enum {
    IMF_FUSION_OUT_GRAVITY = 0,      /* 3: gravity as the accelerometer reads it, g */
    IMF_FUSION_OUT_LINEAR = 3,       /* 3: accelerometer minus gravity, sensor frame, g */
    IMF_FUSION_OUT_EARTH = 6,        /* 3: accelerometer minus gravity, earth frame, g */
    IMF_FUSION_OUT_EULER = 9,        /* 3: roll, pitch, yaw in degrees */
    IMF_FUSION_OUT_ACC_ERROR = 12,   /* degrees */
    IMF_FUSION_OUT_ACC_TRIGGER = 13, /* trigger / period, 0..1 */
    IMF_FUSION_OUT_MAG_ERROR = 14,   /* degrees */
    IMF_FUSION_OUT_MAG_TRIGGER = 15, /* trigger / period, 0..1 */
    IMF_FUSION_N_OUT = 16
};
/* Flag bits of imf_fusion_ahrs_flags(). */
enum {
    IMF_FUSION_FLAG_INITIALISING = 1,
    IMF_FUSION_FLAG_ANGULAR_RATE_RECOVERY = 2,
    IMF_FUSION_FLAG_ACCELERATION_RECOVERY = 4,
    IMF_FUSION_FLAG_MAGNETIC_RECOVERY = 8,
    IMF_FUSION_FLAG_ACCELEROMETER_IGNORED = 16,
    IMF_FUSION_FLAG_MAGNETOMETER_IGNORED = 32
};

/* Default settings (FusionAhrsInitialise): NWU, gain 0.5, no range,
   rejection 90 degrees, recovery trigger period 0. */
void imf_fusion_ahrs_default_settings(imf_fusion_ahrs_settings_t *settings);
/* settings: NULL for the defaults; invsqrt: IMF_FUSION_INVSQRT_*. */
void imf_fusion_ahrs_init(imf_fusion_ahrs_t *self, const imf_fusion_ahrs_settings_t *settings,
                          int invsqrt);
/* Back to the initial state, keeping the settings. */
void imf_fusion_ahrs_reset(imf_fusion_ahrs_t *self);
/* New settings at any time (the state is kept, see FusionAhrsSetSettings). */
void imf_fusion_ahrs_set_settings(imf_fusion_ahrs_t *self,
                                  const imf_fusion_ahrs_settings_t *settings);

/* gx, gy, gz: degrees per second; ax, ay, az: g; mx, my, mz: any unit;
   dt: seconds. */
void imf_fusion_ahrs_update(imf_fusion_ahrs_t *self, imf_real gx, imf_real gy, imf_real gz,
                            imf_real ax, imf_real ay, imf_real az, imf_real mx, imf_real my,
                            imf_real mz, imf_real dt);
/* Without magnetometer: heading held at 0 while initialising. */
void imf_fusion_ahrs_update_no_magnetometer(imf_fusion_ahrs_t *self, imf_real gx, imf_real gy,
                                            imf_real gz, imf_real ax, imf_real ay, imf_real az,
                                            imf_real dt);
/* heading: degrees, from an external source, in place of a magnetometer. */
void imf_fusion_ahrs_update_external_heading(imf_fusion_ahrs_t *self, imf_real gx, imf_real gy,
                                             imf_real gz, imf_real ax, imf_real ay, imf_real az,
                                             imf_real heading, imf_real dt);
/* Rotate q about the earth vertical so that its yaw is heading (degrees).
   A non-finite heading is rejected (skipped). */
void imf_fusion_ahrs_set_heading(imf_fusion_ahrs_t *self, imf_real heading);

/* The state as IMF_FUSION_AHRS_N_STATE reals, in struct order (integers
   converted exactly), and back (integers truncated toward zero). */
void imf_fusion_ahrs_get_state(const imf_fusion_ahrs_t *self, imf_real *out);
void imf_fusion_ahrs_set_state(imf_fusion_ahrs_t *self, const imf_real *in);

/* All outputs, IMF_FUSION_N_OUT reals (see the enum); flags as bits. */
void imf_fusion_ahrs_outputs(const imf_fusion_ahrs_t *self, imf_real *out);
unsigned imf_fusion_ahrs_flags(const imf_fusion_ahrs_t *self);

/* Tilt-compensated compass heading (degrees) from an accelerometer and a
   magnetometer sample in the sensor frame, per convention
   (FusionCompassCalculateHeading). NaN where the heading is undefined: gravity x field
   is exactly zero (a zero accelerometer or magnetometer, or a field along gravity),
   where Fusion returns 0 (north). */
imf_real imf_fusion_compass_heading(int convention, imf_fusion_vec_t acc, imf_fusion_vec_t mag,
                                    int invsqrt);

#ifdef __cplusplus
}
#endif

#endif /* IMF_FUSION_AHRS_H */
