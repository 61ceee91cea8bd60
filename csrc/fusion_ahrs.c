/*
 * FusionAHRS (Longbin's Fusion walkthrough, imufusion 1.2.3). See fusion_ahrs.h. The pure-Python
 * twin is python/imufuse/reference/fusion.py: the same lines in the same
 * order. Step comments name the parts of the algorithm in Longbin's walkthrough.
 *
 * Longer than 500 lines because: it is Fusion 1.2.3's FusionAhrs.c in one file, in the
 * published code's order, read line by line against it and against its twin.
 */
#include "fusion_ahrs.h"

/* Initial gain of the startup ramp and the ramp's duration in seconds. */
#define IMF_FUSION_INITIAL_GAIN IMF_R(10.0)
#define IMF_FUSION_INITIALISATION_PERIOD IMF_R(3.0)

void imf_fusion_ahrs_default_settings(imf_fusion_ahrs_settings_t *const settings)
{
    settings->convention = IMF_FUSION_NWU;
    settings->gain = IMF_R(0.5);
    settings->gyroscope_range = IMF_R(0.0);
    settings->acceleration_rejection = IMF_R(90.0);
    settings->magnetic_rejection = IMF_R(90.0);
    settings->recovery_trigger_period = 0;
}

/* threshold (degrees) -> (sin(threshold) / 2)^2, compared with |feedback/2|^2;
   0 disables. Squared by a product (Fusion's powf(v, 2) compiles to v * v). */
static imf_real rejection_threshold(const imf_real degrees)
{
    imf_real v;
    if (degrees == IMF_R(0.0)) {
        return IMF_FUSION_REAL_MAX;
    }
    v = IMF_R(0.5) * imf_fusion_sin(imf_fusion_deg2rad(degrees));
    return v * v;
}

void imf_fusion_ahrs_set_settings(imf_fusion_ahrs_t *const self,
                                  const imf_fusion_ahrs_settings_t *const settings)
{
    imf_fusion_ahrs_config_t *const set = &self->set;
    set->convention = settings->convention == IMF_FUSION_ENU   ? IMF_FUSION_ENU
                      : settings->convention == IMF_FUSION_NED ? IMF_FUSION_NED
                                                               : IMF_FUSION_NWU;
    set->gain = settings->gain;
    /* overrange is declared at 98 % of the range */
    set->gyroscope_range = settings->gyroscope_range == IMF_R(0.0)
                               ? IMF_FUSION_REAL_MAX
                               : IMF_R(0.98) * settings->gyroscope_range;
    set->acceleration_rejection = rejection_threshold(settings->acceleration_rejection);
    set->magnetic_rejection = rejection_threshold(settings->magnetic_rejection);
    set->recovery_trigger_period = settings->recovery_trigger_period;
    self->x.acceleration_recovery_timeout = set->recovery_trigger_period;
    self->x.magnetic_recovery_timeout = set->recovery_trigger_period;
    /* without feedback or without recovery, rejection is disabled */
    if (settings->gain == IMF_R(0.0) || settings->recovery_trigger_period == 0) {
        set->acceleration_rejection = IMF_FUSION_REAL_MAX;
        set->magnetic_rejection = IMF_FUSION_REAL_MAX;
    }
    if (self->x.initialising == 0) {
        self->x.ramped_gain = set->gain;
    }
    set->ramped_gain_step =
        (IMF_FUSION_INITIAL_GAIN - set->gain) / IMF_FUSION_INITIALISATION_PERIOD;
}

void imf_fusion_ahrs_reset(imf_fusion_ahrs_t *const self)
{
    imf_fusion_ahrs_state_t *const x = &self->x;
    x->q0 = IMF_R(1.0);
    x->q1 = IMF_R(0.0);
    x->q2 = IMF_R(0.0);
    x->q3 = IMF_R(0.0);
    x->acc_x = IMF_R(0.0);
    x->acc_y = IMF_R(0.0);
    x->acc_z = IMF_R(0.0);
    x->initialising = 1;
    x->ramped_gain = IMF_FUSION_INITIAL_GAIN;
    x->angular_rate_recovery = 0;
    x->half_acc_fb_x = IMF_R(0.0);
    x->half_acc_fb_y = IMF_R(0.0);
    x->half_acc_fb_z = IMF_R(0.0);
    x->half_mag_fb_x = IMF_R(0.0);
    x->half_mag_fb_y = IMF_R(0.0);
    x->half_mag_fb_z = IMF_R(0.0);
    x->accelerometer_ignored = 0;
    x->acceleration_recovery_trigger = 0;
    x->acceleration_recovery_timeout = self->set.recovery_trigger_period;
    x->magnetometer_ignored = 0;
    x->magnetic_recovery_trigger = 0;
    x->magnetic_recovery_timeout = self->set.recovery_trigger_period;
}

void imf_fusion_ahrs_init(imf_fusion_ahrs_t *const self,
                          const imf_fusion_ahrs_settings_t *const settings, const int invsqrt)
{
    imf_fusion_ahrs_settings_t defaults;
    imf_fusion_ahrs_default_settings(&defaults);
    self->set.invsqrt =
        invsqrt == IMF_FUSION_INVSQRT_FAST ? IMF_FUSION_INVSQRT_FAST : IMF_FUSION_INVSQRT_EXACT;
    self->skipped = 0;
    self->x.initialising = 1;
    imf_fusion_ahrs_set_settings(self, settings != NULL ? settings : &defaults);
    imf_fusion_ahrs_reset(self);
}

static imf_fusion_quat_t get_q(const imf_fusion_ahrs_state_t *const x)
{
    const imf_fusion_quat_t q = { x->q0, x->q1, x->q2, x->q3 };
    return q;
}

static void put_q(imf_fusion_ahrs_state_t *const x, const imf_fusion_quat_t q)
{
    x->q0 = q.w;
    x->q1 = q.x;
    x->q2 = q.y;
    x->q3 = q.z;
}

/* Direction of gravity predicted by q, halved: the third column of R^T / 2
   (NWU, ENU: up), its negative for NED (down). */
static imf_fusion_vec_t half_gravity(const imf_fusion_ahrs_t *const self)
{
    const imf_fusion_ahrs_state_t *const x = &self->x;
    if (self->set.convention == IMF_FUSION_NED) {
        const imf_fusion_vec_t g = { x->q0 * x->q2 - x->q1 * x->q3,
                                     IMF_R(-1.0) * (x->q2 * x->q3 + x->q0 * x->q1),
                                     IMF_R(0.5) - x->q0 * x->q0 - x->q3 * x->q3 };
        return g;
    } else {
        const imf_fusion_vec_t g = { x->q1 * x->q3 - x->q0 * x->q2, x->q2 * x->q3 + x->q0 * x->q1,
                                     x->q0 * x->q0 - IMF_R(0.5) + x->q3 * x->q3 };
        return g;
    }
}

/* Direction of the magnetic reference predicted by q, halved: the earth
   axis the horizontal field is compared with, in the sensor frame. NWU:
   second column of R^T / 2 (west); ENU: first column / -2 (west); NED:
   second column / -2 (west). */
static imf_fusion_vec_t half_magnetic(const imf_fusion_ahrs_t *const self)
{
    const imf_fusion_ahrs_state_t *const x = &self->x;
    if (self->set.convention == IMF_FUSION_ENU) {
        const imf_fusion_vec_t m = { IMF_R(0.5) - x->q0 * x->q0 - x->q1 * x->q1,
                                     x->q0 * x->q3 - x->q1 * x->q2,
                                     IMF_R(-1.0) * (x->q1 * x->q3 + x->q0 * x->q2) };
        return m;
    } else if (self->set.convention == IMF_FUSION_NED) {
        const imf_fusion_vec_t m = { IMF_R(-1.0) * (x->q1 * x->q2 + x->q0 * x->q3),
                                     IMF_R(0.5) - x->q0 * x->q0 - x->q2 * x->q2,
                                     x->q0 * x->q1 - x->q2 * x->q3 };
        return m;
    } else {
        const imf_fusion_vec_t m = { x->q1 * x->q2 + x->q0 * x->q3,
                                     x->q0 * x->q0 - IMF_R(0.5) + x->q2 * x->q2,
                                     x->q2 * x->q3 - x->q0 * x->q1 };
        return m;
    }
}

/* Feedback = sensor x reference (sin of the error angle, halved by the
   halved reference); beyond 90 degrees of error it is normalised so that
   it does not shrink again. */
static imf_fusion_vec_t feedback(const imf_fusion_vec_t sensor, const imf_fusion_vec_t reference,
                                 const int invsqrt)
{
    if (imf_fusion_vec_dot(sensor, reference) < IMF_R(0.0)) {
        return imf_fusion_vec_normalise(imf_fusion_vec_cross(sensor, reference), invsqrt);
    }
    return imf_fusion_vec_cross(sensor, reference);
}

static int32_t clamp_i32(const int32_t value, const int32_t min, const int32_t max)
{
    if (value < min) {
        return min;
    }
    if (value > max) {
        return max;
    }
    return value;
}

/* One FusionAhrsUpdate, without the non-finite policy. */
static void ahrs_update(imf_fusion_ahrs_t *const self, const imf_fusion_vec_t gyr,
                        const imf_fusion_vec_t acc, const imf_fusion_vec_t mag, const imf_real dt)
{
    const imf_fusion_ahrs_config_t *const set = &self->set;
    imf_fusion_ahrs_state_t *const x = &self->x;
    const int invsqrt = set->invsqrt;
    imf_fusion_vec_t half_grav, half_acc_fb, half_mag_fb, half_gyr, adjusted;
    imf_fusion_quat_t q;

    /* keep the accelerometer for the acceleration outputs */
    x->acc_x = acc.x;
    x->acc_y = acc.y;
    x->acc_z = acc.z;

    /* gyroscope overrange: start again from the current attitude */
    if (imf_fusion_fabs(gyr.x) > set->gyroscope_range
        || imf_fusion_fabs(gyr.y) > set->gyroscope_range
        || imf_fusion_fabs(gyr.z) > set->gyroscope_range) {
        q = get_q(x);
        imf_fusion_ahrs_reset(self);
        put_q(x, q);
        x->angular_rate_recovery = 1;
    }

    /* startup: ramp the gain down from 10 to gain */
    if (x->initialising != 0) {
        x->ramped_gain = x->ramped_gain - set->ramped_gain_step * dt;
        if (x->ramped_gain < set->gain || set->gain == IMF_R(0.0)) {
            x->ramped_gain = set->gain;
            x->initialising = 0;
            x->angular_rate_recovery = 0;
        }
    }

    half_grav = half_gravity(self);

    /* accelerometer feedback, with rejection and recovery */
    half_acc_fb.x = IMF_R(0.0);
    half_acc_fb.y = IMF_R(0.0);
    half_acc_fb.z = IMF_R(0.0);
    x->accelerometer_ignored = 1;
    if (!imf_fusion_vec_is_zero(acc)) {
        const imf_fusion_vec_t fb =
            feedback(imf_fusion_vec_normalise(acc, invsqrt), half_grav, invsqrt);
        x->half_acc_fb_x = fb.x;
        x->half_acc_fb_y = fb.y;
        x->half_acc_fb_z = fb.z;
        if (x->initialising != 0 || imf_fusion_vec_norm2(fb) <= set->acceleration_rejection) {
            x->accelerometer_ignored = 0;
            x->acceleration_recovery_trigger -= 9;
        } else {
            x->acceleration_recovery_trigger += 1;
        }
        if (x->acceleration_recovery_trigger > x->acceleration_recovery_timeout) {
            x->acceleration_recovery_timeout = 0;
            x->accelerometer_ignored = 0;
        } else {
            x->acceleration_recovery_timeout = set->recovery_trigger_period;
        }
        x->acceleration_recovery_trigger =
            clamp_i32(x->acceleration_recovery_trigger, 0, set->recovery_trigger_period);
        if (x->accelerometer_ignored == 0) {
            half_acc_fb = fb;
        }
    }

    /* magnetometer feedback: the horizontal field direction, gravity x m */
    half_mag_fb.x = IMF_R(0.0);
    half_mag_fb.y = IMF_R(0.0);
    half_mag_fb.z = IMF_R(0.0);
    x->magnetometer_ignored = 1;
    if (!imf_fusion_vec_is_zero(mag)) {
        const imf_fusion_vec_t half_mag = half_magnetic(self);
        const imf_fusion_vec_t fb =
            feedback(imf_fusion_vec_normalise(imf_fusion_vec_cross(half_grav, mag), invsqrt),
                     half_mag, invsqrt);
        x->half_mag_fb_x = fb.x;
        x->half_mag_fb_y = fb.y;
        x->half_mag_fb_z = fb.z;
        if (x->initialising != 0 || imf_fusion_vec_norm2(fb) <= set->magnetic_rejection) {
            x->magnetometer_ignored = 0;
            x->magnetic_recovery_trigger -= 9;
        } else {
            x->magnetic_recovery_trigger += 1;
        }
        if (x->magnetic_recovery_trigger > x->magnetic_recovery_timeout) {
            x->magnetic_recovery_timeout = 0;
            x->magnetometer_ignored = 0;
        } else {
            x->magnetic_recovery_timeout = set->recovery_trigger_period;
        }
        x->magnetic_recovery_trigger =
            clamp_i32(x->magnetic_recovery_trigger, 0, set->recovery_trigger_period);
        if (x->magnetometer_ignored == 0) {
            half_mag_fb = fb;
        }
    }

    /* gyroscope in rad/s, halved, plus the gained feedback */
    half_gyr = imf_fusion_vec_scale(gyr, imf_fusion_deg2rad(IMF_R(0.5)));
    adjusted = imf_fusion_vec_add(
        half_gyr,
        imf_fusion_vec_scale(imf_fusion_vec_add(half_acc_fb, half_mag_fb), x->ramped_gain));

    /* q <- normalise(q + q (x) (0, adjusted dt)) */
    q = get_q(x);
    q = imf_fusion_quat_add(q, imf_fusion_quat_mul_vec(q, imf_fusion_vec_scale(adjusted, dt)));
    put_q(x, imf_fusion_quat_normalise(q, invsqrt));
}

/* yaw of q -> heading: q <- (cos(d/2), 0, 0, -sin(d/2)) (x) q, d = yaw - heading */
static void ahrs_set_heading(imf_fusion_ahrs_t *const self, const imf_real heading)
{
    imf_fusion_ahrs_state_t *const x = &self->x;
    const imf_real yaw =
        imf_fusion_atan2(x->q0 * x->q3 + x->q1 * x->q2, IMF_R(0.5) - x->q2 * x->q2 - x->q3 * x->q3);
    const imf_real half_yaw_minus_heading = IMF_R(0.5) * (yaw - imf_fusion_deg2rad(heading));
    const imf_fusion_quat_t rotation = { imf_fusion_cos(half_yaw_minus_heading), IMF_R(0.0),
                                         IMF_R(0.0),
                                         IMF_R(-1.0) * imf_fusion_sin(half_yaw_minus_heading) };
    put_q(x, imf_fusion_quat_mul(rotation, get_q(x)));
}

static int state_finite(const imf_fusion_ahrs_state_t *const x)
{
    return imf_finite4(x->q0, x->q1, x->q2, x->q3)
           && imf_finite4(x->ramped_gain, x->half_acc_fb_x, x->half_acc_fb_y, x->half_acc_fb_z)
           && imf_finite3(x->half_mag_fb_x, x->half_mag_fb_y, x->half_mag_fb_z)
           && (x->q0 != IMF_R(0.0) || x->q1 != IMF_R(0.0) || x->q2 != IMF_R(0.0)
               || x->q3 != IMF_R(0.0));
}

/* Non-finite policy around every update form. */
static int inputs_ok(const imf_fusion_vec_t gyr, const imf_fusion_vec_t acc, const imf_real dt)
{
    return imf_finite3(gyr.x, gyr.y, gyr.z) && imf_finite3(acc.x, acc.y, acc.z) && isfinite(dt)
           && dt >= IMF_R(0.0);
}

static void commit_or_restore(imf_fusion_ahrs_t *const self,
                              const imf_fusion_ahrs_state_t *const saved)
{
    if (!state_finite(&self->x)) {
        self->x = *saved;
        self->skipped++;
    }
}

void imf_fusion_ahrs_update(imf_fusion_ahrs_t *const self, const imf_real gx, const imf_real gy,
                            const imf_real gz, const imf_real ax, const imf_real ay,
                            const imf_real az, const imf_real mx, const imf_real my,
                            const imf_real mz, const imf_real dt)
{
    const imf_fusion_vec_t gyr = { gx, gy, gz }, acc = { ax, ay, az }, mag = { mx, my, mz };
    const imf_fusion_ahrs_state_t saved = self->x;
    if (!inputs_ok(gyr, acc, dt) || !imf_finite3(mx, my, mz)) {
        self->skipped++;
        return;
    }
    ahrs_update(self, gyr, acc, mag, dt);
    commit_or_restore(self, &saved);
}

void imf_fusion_ahrs_update_no_magnetometer(imf_fusion_ahrs_t *const self, const imf_real gx,
                                            const imf_real gy, const imf_real gz, const imf_real ax,
                                            const imf_real ay, const imf_real az, const imf_real dt)
{
    const imf_fusion_vec_t gyr = { gx, gy, gz }, acc = { ax, ay, az };
    const imf_fusion_vec_t zero = { IMF_R(0.0), IMF_R(0.0), IMF_R(0.0) };
    const imf_fusion_ahrs_state_t saved = self->x;
    if (!inputs_ok(gyr, acc, dt)) {
        self->skipped++;
        return;
    }
    ahrs_update(self, gyr, acc, zero, dt);
    /* without a heading reference, hold the heading at 0 while initialising */
    if (self->x.initialising != 0) {
        ahrs_set_heading(self, IMF_R(0.0));
    }
    commit_or_restore(self, &saved);
}

void imf_fusion_ahrs_update_external_heading(imf_fusion_ahrs_t *const self, const imf_real gx,
                                             const imf_real gy, const imf_real gz,
                                             const imf_real ax, const imf_real ay,
                                             const imf_real az, const imf_real heading,
                                             const imf_real dt)
{
    const imf_fusion_vec_t gyr = { gx, gy, gz }, acc = { ax, ay, az };
    const imf_fusion_ahrs_state_t saved = self->x;
    const imf_fusion_ahrs_state_t *const x = &self->x;
    imf_real roll, heading_rad, sin_heading;
    imf_fusion_vec_t mag;
    if (!inputs_ok(gyr, acc, dt) || !isfinite(heading)) {
        self->skipped++;
        return;
    }
    /* a magnetometer reading pointing along the given heading, at the
       current roll */
    roll =
        imf_fusion_atan2(x->q0 * x->q1 + x->q2 * x->q3, IMF_R(0.5) - x->q2 * x->q2 - x->q1 * x->q1);
    heading_rad = imf_fusion_deg2rad(heading);
    sin_heading = imf_fusion_sin(heading_rad);
    mag.x = imf_fusion_cos(heading_rad);
    mag.y = IMF_R(-1.0) * imf_fusion_cos(roll) * sin_heading;
    mag.z = sin_heading * imf_fusion_sin(roll);
    ahrs_update(self, gyr, acc, mag, dt);
    commit_or_restore(self, &saved);
}

void imf_fusion_ahrs_set_heading(imf_fusion_ahrs_t *const self, const imf_real heading)
{
    const imf_fusion_ahrs_state_t saved = self->x;
    if (!isfinite(heading)) {
        self->skipped++;
        return;
    }
    ahrs_set_heading(self, heading);
    commit_or_restore(self, &saved);
}

void imf_fusion_ahrs_get_state(const imf_fusion_ahrs_t *const self, imf_real *const out)
{
    const imf_fusion_ahrs_state_t *const x = &self->x;
    out[0] = x->q0;
    out[1] = x->q1;
    out[2] = x->q2;
    out[3] = x->q3;
    out[4] = x->acc_x;
    out[5] = x->acc_y;
    out[6] = x->acc_z;
    out[7] = x->ramped_gain;
    out[8] = x->half_acc_fb_x;
    out[9] = x->half_acc_fb_y;
    out[10] = x->half_acc_fb_z;
    out[11] = x->half_mag_fb_x;
    out[12] = x->half_mag_fb_y;
    out[13] = x->half_mag_fb_z;
    out[14] = (imf_real)x->initialising;
    out[15] = (imf_real)x->angular_rate_recovery;
    out[16] = (imf_real)x->accelerometer_ignored;
    out[17] = (imf_real)x->acceleration_recovery_trigger;
    out[18] = (imf_real)x->acceleration_recovery_timeout;
    out[19] = (imf_real)x->magnetometer_ignored;
    out[20] = (imf_real)x->magnetic_recovery_trigger;
    out[21] = (imf_real)x->magnetic_recovery_timeout;
}

void imf_fusion_ahrs_set_state(imf_fusion_ahrs_t *const self, const imf_real *const in)
{
    imf_fusion_ahrs_state_t *const x = &self->x;
    x->q0 = in[0];
    x->q1 = in[1];
    x->q2 = in[2];
    x->q3 = in[3];
    x->acc_x = in[4];
    x->acc_y = in[5];
    x->acc_z = in[6];
    x->ramped_gain = in[7];
    x->half_acc_fb_x = in[8];
    x->half_acc_fb_y = in[9];
    x->half_acc_fb_z = in[10];
    x->half_mag_fb_x = in[11];
    x->half_mag_fb_y = in[12];
    x->half_mag_fb_z = in[13];
    x->initialising = (int32_t)in[14];
    x->angular_rate_recovery = (int32_t)in[15];
    x->accelerometer_ignored = (int32_t)in[16];
    x->acceleration_recovery_trigger = (int32_t)in[17];
    x->acceleration_recovery_timeout = (int32_t)in[18];
    x->magnetometer_ignored = (int32_t)in[19];
    x->magnetic_recovery_trigger = (int32_t)in[20];
    x->magnetic_recovery_timeout = (int32_t)in[21];
}

void imf_fusion_ahrs_outputs(const imf_fusion_ahrs_t *const self, imf_real *const out)
{
    const imf_fusion_ahrs_state_t *const x = &self->x;
    const imf_real qw = x->q0, qx = x->q1, qy = x->q2, qz = x->q3;
    const imf_real ax = x->acc_x, ay = x->acc_y, az = x->acc_z;
    /* gravity in the sensor frame: third column of R^T (up) */
    const imf_real gx = IMF_R(2.0) * (qx * qz - qw * qy);
    const imf_real gy = IMF_R(2.0) * (qy * qz + qw * qx);
    const imf_real gz = IMF_R(2.0) * (qw * qw - IMF_R(0.5) + qz * qz);
    /* R a: the accelerometer in the earth frame, common products first */
    const imf_real qwqw = qw * qw, qwqx = qw * qx, qwqy = qw * qy, qwqz = qw * qz;
    const imf_real qxqy = qx * qy, qxqz = qx * qz, qyqz = qy * qz;
    const imf_real half_minus_qyqy = IMF_R(0.5) - qy * qy;
    out[IMF_FUSION_OUT_EARTH + 0] =
        IMF_R(2.0) * ((qwqw - IMF_R(0.5) + qx * qx) * ax + (qxqy - qwqz) * ay + (qxqz + qwqy) * az);
    out[IMF_FUSION_OUT_EARTH + 1] =
        IMF_R(2.0) * ((qxqy + qwqz) * ax + (qwqw - IMF_R(0.5) + qy * qy) * ay + (qyqz - qwqx) * az);
    out[IMF_FUSION_OUT_EARTH + 2] =
        IMF_R(2.0) * ((qxqz - qwqy) * ax + (qyqz + qwqx) * ay + (qwqw - IMF_R(0.5) + qz * qz) * az);
    if (self->set.convention == IMF_FUSION_NED) {
        /* earth z down: the accelerometer reads -up at rest */
        out[IMF_FUSION_OUT_GRAVITY + 0] = -gx;
        out[IMF_FUSION_OUT_GRAVITY + 1] = -gy;
        out[IMF_FUSION_OUT_GRAVITY + 2] = -gz;
        out[IMF_FUSION_OUT_LINEAR + 0] = ax + gx;
        out[IMF_FUSION_OUT_LINEAR + 1] = ay + gy;
        out[IMF_FUSION_OUT_LINEAR + 2] = az + gz;
        out[IMF_FUSION_OUT_EARTH + 2] += IMF_R(1.0);
    } else {
        out[IMF_FUSION_OUT_GRAVITY + 0] = gx;
        out[IMF_FUSION_OUT_GRAVITY + 1] = gy;
        out[IMF_FUSION_OUT_GRAVITY + 2] = gz;
        out[IMF_FUSION_OUT_LINEAR + 0] = ax - gx;
        out[IMF_FUSION_OUT_LINEAR + 1] = ay - gy;
        out[IMF_FUSION_OUT_LINEAR + 2] = az - gz;
        out[IMF_FUSION_OUT_EARTH + 2] -= IMF_R(1.0);
    }
    /* Euler angles (ZYX), degrees */
    out[IMF_FUSION_OUT_EULER + 0] =
        imf_fusion_rad2deg(imf_fusion_atan2(qw * qx + qy * qz, half_minus_qyqy - qx * qx));
    out[IMF_FUSION_OUT_EULER + 1] =
        imf_fusion_rad2deg(imf_fusion_safe_asin(IMF_R(2.0) * (qw * qy - qz * qx)));
    out[IMF_FUSION_OUT_EULER + 2] =
        imf_fusion_rad2deg(imf_fusion_atan2(qw * qz + qx * qy, half_minus_qyqy - qz * qz));
    out[IMF_FUSION_OUT_ACC_ERROR] =
        imf_fusion_error_degrees(x->half_acc_fb_x, x->half_acc_fb_y, x->half_acc_fb_z);
    out[IMF_FUSION_OUT_ACC_TRIGGER] = imf_fusion_trigger_ratio(x->acceleration_recovery_trigger,
                                                               self->set.recovery_trigger_period);
    out[IMF_FUSION_OUT_MAG_ERROR] =
        imf_fusion_error_degrees(x->half_mag_fb_x, x->half_mag_fb_y, x->half_mag_fb_z);
    out[IMF_FUSION_OUT_MAG_TRIGGER] =
        imf_fusion_trigger_ratio(x->magnetic_recovery_trigger, self->set.recovery_trigger_period);
}

unsigned imf_fusion_ahrs_flags(const imf_fusion_ahrs_t *const self)
{
    const imf_fusion_ahrs_state_t *const x = &self->x;
    unsigned flags = 0u;
    if (x->initialising != 0) {
        flags |= IMF_FUSION_FLAG_INITIALISING;
    }
    if (x->angular_rate_recovery != 0) {
        flags |= IMF_FUSION_FLAG_ANGULAR_RATE_RECOVERY;
    }
    if (x->acceleration_recovery_trigger > x->acceleration_recovery_timeout) {
        flags |= IMF_FUSION_FLAG_ACCELERATION_RECOVERY;
    }
    if (x->magnetic_recovery_trigger > x->magnetic_recovery_timeout) {
        flags |= IMF_FUSION_FLAG_MAGNETIC_RECOVERY;
    }
    if (x->accelerometer_ignored != 0) {
        flags |= IMF_FUSION_FLAG_ACCELEROMETER_IGNORED;
    }
    if (x->magnetometer_ignored != 0) {
        flags |= IMF_FUSION_FLAG_MAGNETOMETER_IGNORED;
    }
    return flags;
}

imf_real imf_fusion_compass_heading(const int convention, const imf_fusion_vec_t acc,
                                    const imf_fusion_vec_t mag, const int invsqrt)
{
    /* NED: gravity "up" is -acc; NWU and ENU: acc */
    const imf_fusion_vec_t up =
        convention == IMF_FUSION_NED ? imf_fusion_vec_scale(acc, IMF_R(-1.0)) : acc;
    const imf_fusion_vec_t w = imf_fusion_vec_cross(up, mag);
    imf_fusion_vec_t west, north;
    /* up x m = 0 (no accelerometer, no field, or a field along gravity): no heading */
    if (imf_fusion_vec_norm2(w) == IMF_R(0.0)) {
        return (imf_real)NAN;
    }
    west = imf_fusion_vec_normalise(w, invsqrt);
    north = imf_fusion_vec_normalise(imf_fusion_vec_cross(west, up), invsqrt);
    if (convention == IMF_FUSION_ENU) {
        const imf_fusion_vec_t east = imf_fusion_vec_scale(west, IMF_R(-1.0));
        return imf_fusion_rad2deg(imf_fusion_atan2(north.x, east.x));
    }
    return imf_fusion_rad2deg(imf_fusion_atan2(west.x, north.x));
}
