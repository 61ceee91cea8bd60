/*
 * FusionAHRS13 (x-io Fusion 1.3, imufusion 1.3.3). See fusion13.h. The
 * pure-Python twin is python/imufuse/reference/fusion13.py: the same lines in the same order.
 *
 * Longer than 500 lines because: it is Fusion 1.3's AHRS and bias algorithm in one file, in
 * the published code's order, read line by line against it and against its one-file twin.
 */
#include "fusion13.h"

/* Initial gain of start-up and the start-up period in seconds. */
#define IMF_FUSION13_INITIAL_GAIN IMF_R(10.0)
#define IMF_FUSION13_STARTUP_PERIOD IMF_R(3.0)

void imf_fusion13_ahrs_default_settings(imf_fusion13_ahrs_settings_t *const settings)
{
    settings->sample_rate = IMF_R(100.0);
    settings->convention = IMF_FUSION_NWU;
    settings->gain = IMF_R(0.5);
    settings->gyroscope_range = IMF_R(0.0);
    settings->acceleration_rejection = IMF_R(0.0);
    settings->magnetic_rejection = IMF_R(0.0);
    settings->rejection_timeout = IMF_R(0.0);
}

/* threshold (degrees) -> (sin(threshold) / 2)^2 (Fusion's powf(v, 2) is v * v); 0 disables */
static imf_real rejection_threshold(const imf_real degrees)
{
    imf_real v;
    if (degrees == IMF_R(0.0)) {
        return IMF_FUSION_REAL_MAX;
    }
    v = IMF_R(0.5) * imf_fusion_sin(imf_fusion_deg2rad(degrees));
    return v * v;
}

void imf_fusion13_ahrs_set_settings(imf_fusion13_ahrs_t *const self,
                                    const imf_fusion13_ahrs_settings_t *const settings)
{
    imf_fusion13_ahrs_config_t *const set = &self->set;
    self->x.sample_period = IMF_R(1.0) / settings->sample_rate;
    set->convention = settings->convention == IMF_FUSION_ENU   ? IMF_FUSION_ENU
                      : settings->convention == IMF_FUSION_NED ? IMF_FUSION_NED
                                                               : IMF_FUSION_NWU;
    set->gain = settings->gain;
    /* the ramp per update, at the settings' period */
    set->startup_gain_rate = ((IMF_FUSION13_INITIAL_GAIN - set->gain) / IMF_FUSION13_STARTUP_PERIOD)
                             * self->x.sample_period;
    set->overrange_enabled = settings->gyroscope_range > IMF_R(0.0);
    set->overrange_threshold = IMF_R(0.98) * settings->gyroscope_range;
    set->acceleration_rejection = rejection_threshold(settings->acceleration_rejection);
    set->magnetic_rejection = rejection_threshold(settings->magnetic_rejection);
    set->rejection_timeout = (int32_t)(settings->sample_rate * settings->rejection_timeout);
    self->x.acceleration_recovery_threshold = set->rejection_timeout;
    self->x.magnetic_recovery_threshold = set->rejection_timeout;
    /* without feedback or without a timeout, rejection is disabled */
    if (settings->gain == IMF_R(0.0) || settings->rejection_timeout == IMF_R(0.0)) {
        set->acceleration_rejection = IMF_FUSION_REAL_MAX;
        set->magnetic_rejection = IMF_FUSION_REAL_MAX;
    }
}

void imf_fusion13_ahrs_restart(imf_fusion13_ahrs_t *const self)
{
    imf_fusion13_ahrs_state_t *const x = &self->x;
    x->q0 = IMF_R(1.0);
    x->q1 = IMF_R(0.0);
    x->q2 = IMF_R(0.0);
    x->q3 = IMF_R(0.0);
    x->acc_x = IMF_R(0.0);
    x->acc_y = IMF_R(0.0);
    x->acc_z = IMF_R(0.0);
    x->startup = 1;
    x->startup_gain = IMF_FUSION13_INITIAL_GAIN;
    x->overrange_recovery = 0;
    x->half_acc_res_x = IMF_R(0.0);
    x->half_acc_res_y = IMF_R(0.0);
    x->half_acc_res_z = IMF_R(0.0);
    x->acceleration_recovery_trigger = 0;
    x->acceleration_recovery_threshold = self->set.rejection_timeout;
    x->accelerometer_ignored = 0;
    x->half_mag_res_x = IMF_R(0.0);
    x->half_mag_res_y = IMF_R(0.0);
    x->half_mag_res_z = IMF_R(0.0);
    x->magnetic_recovery_trigger = 0;
    x->magnetic_recovery_threshold = self->set.rejection_timeout;
    x->magnetometer_ignored = 0;
}

void imf_fusion13_ahrs_init(imf_fusion13_ahrs_t *const self,
                            const imf_fusion13_ahrs_settings_t *const settings, const int invsqrt)
{
    imf_fusion13_ahrs_settings_t defaults;
    imf_fusion13_ahrs_default_settings(&defaults);
    self->set.invsqrt =
        invsqrt == IMF_FUSION_INVSQRT_FAST ? IMF_FUSION_INVSQRT_FAST : IMF_FUSION_INVSQRT_EXACT;
    self->skipped = 0;
    imf_fusion13_ahrs_set_settings(self, settings != NULL ? settings : &defaults);
    imf_fusion13_ahrs_restart(self);
}

void imf_fusion13_ahrs_set_sample_period(imf_fusion13_ahrs_t *const self,
                                         const imf_real sample_period)
{
    if (!isfinite(sample_period) || sample_period < IMF_R(0.0)) {
        self->skipped++;
        return;
    }
    self->x.sample_period = sample_period;
}

void imf_fusion13_ahrs_skip_startup(imf_fusion13_ahrs_t *const self)
{
    self->x.startup = 0;
    self->x.overrange_recovery = 0;
}

static imf_fusion_quat_t get_q(const imf_fusion13_ahrs_state_t *const x)
{
    const imf_fusion_quat_t q = { x->q0, x->q1, x->q2, x->q3 };
    return q;
}

static void put_q(imf_fusion13_ahrs_state_t *const x, const imf_fusion_quat_t q)
{
    x->q0 = q.w;
    x->q1 = q.x;
    x->q2 = q.y;
    x->q3 = q.z;
}

/* Gyroscope overrange: restart, keeping q and the accelerometer sample. */
static void overrange(imf_fusion13_ahrs_t *const self, const imf_fusion_vec_t gyr)
{
    imf_fusion13_ahrs_state_t *const x = &self->x;
    const imf_real threshold = self->set.overrange_threshold;
    imf_fusion_quat_t q;
    imf_real ax, ay, az;
    if (self->set.overrange_enabled == 0) {
        return;
    }
    if (imf_fusion_fabs(gyr.x) <= threshold && imf_fusion_fabs(gyr.y) <= threshold
        && imf_fusion_fabs(gyr.z) <= threshold) {
        return;
    }
    q = get_q(x);
    ax = x->acc_x;
    ay = x->acc_y;
    az = x->acc_z;
    imf_fusion13_ahrs_restart(self);
    put_q(x, q);
    x->acc_x = ax;
    x->acc_y = ay;
    x->acc_z = az;
    x->overrange_recovery = 1;
}

/* Start-up: the gain ramps down by one step per update until it reaches gain. */
static imf_real startup(imf_fusion13_ahrs_t *const self)
{
    imf_fusion13_ahrs_state_t *const x = &self->x;
    if (x->startup == 0) {
        return self->set.gain;
    }
    x->startup_gain -= self->set.startup_gain_rate;
    if (x->startup_gain > self->set.gain) {
        return x->startup_gain;
    }
    x->startup = 0;
    x->overrange_recovery = 0;
    return self->set.gain;
}

/* Direction of gravity predicted by q, halved: the third column of R^T / 2
   (NWU, ENU: up), its negative for NED (down). */
static imf_fusion_vec_t half_gravity(const imf_fusion13_ahrs_t *const self)
{
    const imf_fusion13_ahrs_state_t *const x = &self->x;
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

/* Direction of west predicted by q, halved (gravity x field is west). NWU: second
   column of R^T / 2; ENU: first column / -2; NED: second column / -2. */
static imf_fusion_vec_t half_west(const imf_fusion13_ahrs_t *const self)
{
    const imf_fusion13_ahrs_state_t *const x = &self->x;
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

/* Residual = sensor x reference; beyond 90 degrees of error it is normalised so that
   it does not shrink again, and exactly opposite vectors give zero. */
static imf_fusion_vec_t residual(const imf_fusion_vec_t sensor, const imf_fusion_vec_t reference,
                                 const int invsqrt)
{
    const imf_fusion_vec_t cross = imf_fusion_vec_cross(sensor, reference);
    const imf_fusion_vec_t zero = { IMF_R(0.0), IMF_R(0.0), IMF_R(0.0) };
    if (imf_fusion_vec_dot(sensor, reference) > IMF_R(0.0)) {
        return cross;
    }
    /* +0 in every component (a zero cross product may hold -0) */
    if (imf_fusion_vec_is_zero(cross)) {
        return zero;
    }
    return imf_fusion_vec_normalise(cross, invsqrt);
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

/* Rejection and recovery of one feedback: the residual counts as accepted during
   start-up or below the threshold; the trigger counts -9 per accepted and +1 per
   rejected sample; beyond the threshold the feedback is forced on (recovery).
   Returns nonzero when the feedback is ignored. */
static int32_t reject(const int32_t startup_on, const imf_fusion_vec_t half_res,
                      const imf_real rejection, const int32_t timeout, int32_t *const trigger,
                      int32_t *const threshold)
{
    int32_t ignored = 1;
    if (startup_on != 0 || imf_fusion_vec_norm2(half_res) <= rejection) {
        ignored = 0;
        *trigger -= 9;
    } else {
        *trigger += 1;
    }
    if (*trigger > *threshold) {
        *threshold = 0;
        ignored = 0;
    } else {
        *threshold = timeout;
    }
    *trigger = clamp_i32(*trigger, 0, timeout);
    return ignored;
}

/* Inclination feedback, halved (zero when the accelerometer is ignored or zero). */
static imf_fusion_vec_t half_inclination_feedback(imf_fusion13_ahrs_t *const self,
                                                  const imf_fusion_vec_t half_grav,
                                                  const imf_fusion_vec_t acc)
{
    imf_fusion13_ahrs_state_t *const x = &self->x;
    const imf_fusion_vec_t zero = { IMF_R(0.0), IMF_R(0.0), IMF_R(0.0) };
    imf_fusion_vec_t res;
    x->accelerometer_ignored = 1;
    if (imf_fusion_vec_is_zero(acc)) {
        return zero;
    }
    res = residual(imf_fusion_vec_normalise(acc, self->set.invsqrt), half_grav, self->set.invsqrt);
    x->half_acc_res_x = res.x;
    x->half_acc_res_y = res.y;
    x->half_acc_res_z = res.z;
    x->accelerometer_ignored =
        reject(x->startup, res, self->set.acceleration_rejection, self->set.rejection_timeout,
               &x->acceleration_recovery_trigger, &x->acceleration_recovery_threshold);
    return x->accelerometer_ignored == 0 ? res : zero;
}

/* Heading feedback, halved: the measured west (gravity x field) against the predicted. */
static imf_fusion_vec_t half_heading_feedback(imf_fusion13_ahrs_t *const self,
                                              const imf_fusion_vec_t half_grav,
                                              const imf_fusion_vec_t mag)
{
    imf_fusion13_ahrs_state_t *const x = &self->x;
    const imf_fusion_vec_t zero = { IMF_R(0.0), IMF_R(0.0), IMF_R(0.0) };
    imf_fusion_vec_t west, res;
    x->magnetometer_ignored = 1;
    if (imf_fusion_vec_is_zero(mag)) {
        return zero;
    }
    west = half_west(self);
    res =
        residual(imf_fusion_vec_normalise(imf_fusion_vec_cross(half_grav, mag), self->set.invsqrt),
                 west, self->set.invsqrt);
    x->half_mag_res_x = res.x;
    x->half_mag_res_y = res.y;
    x->half_mag_res_z = res.z;
    x->magnetometer_ignored =
        reject(x->startup, res, self->set.magnetic_rejection, self->set.rejection_timeout,
               &x->magnetic_recovery_trigger, &x->magnetic_recovery_threshold);
    return x->magnetometer_ignored == 0 ? res : zero;
}

/* One FusionAhrsUpdate, without the non-finite policy. */
static void ahrs_update(imf_fusion13_ahrs_t *const self, const imf_fusion_vec_t gyr,
                        const imf_fusion_vec_t acc, const imf_fusion_vec_t mag)
{
    imf_fusion13_ahrs_state_t *const x = &self->x;
    imf_real gain;
    imf_fusion_vec_t half_gyr, half_grav, half_fb, half_rate;
    imf_fusion_quat_t q;
    x->acc_x = acc.x;
    x->acc_y = acc.y;
    x->acc_z = acc.z;
    overrange(self, gyr);
    gain = startup(self);
    half_gyr = imf_fusion_vec_scale(gyr, imf_fusion_deg2rad(IMF_R(0.5)));
    half_grav = half_gravity(self);
    half_fb = half_inclination_feedback(self, half_grav, acc);
    half_fb = imf_fusion_vec_add(half_fb, half_heading_feedback(self, half_grav, mag));
    half_rate = imf_fusion_vec_add(half_gyr, imf_fusion_vec_scale(half_fb, gain));
    /* q <- normalise(q + q (x) (0, half_rate T)) */
    q = get_q(x);
    q = imf_fusion_quat_add(
        q, imf_fusion_quat_mul_vec(q, imf_fusion_vec_scale(half_rate, x->sample_period)));
    put_q(x, imf_fusion_quat_normalise(q, self->set.invsqrt));
}

/* yaw of q -> heading: q <- (cos(d/2), 0, 0, -sin(d/2)) (x) q, d = yaw - heading */
static void ahrs_set_heading(imf_fusion13_ahrs_t *const self, const imf_real heading)
{
    imf_fusion13_ahrs_state_t *const x = &self->x;
    const imf_real yaw =
        imf_fusion_atan2(x->q0 * x->q3 + x->q1 * x->q2, IMF_R(0.5) - x->q2 * x->q2 - x->q3 * x->q3);
    const imf_real half_yaw_minus_heading = IMF_R(0.5) * (yaw - imf_fusion_deg2rad(heading));
    const imf_fusion_quat_t rotation = { imf_fusion_cos(half_yaw_minus_heading), IMF_R(0.0),
                                         IMF_R(0.0),
                                         IMF_R(-1.0) * imf_fusion_sin(half_yaw_minus_heading) };
    put_q(x, imf_fusion_quat_mul(rotation, get_q(x)));
}

static int state_finite(const imf_fusion13_ahrs_state_t *const x)
{
    return imf_finite4(x->q0, x->q1, x->q2, x->q3)
           && imf_finite4(x->startup_gain, x->half_acc_res_x, x->half_acc_res_y, x->half_acc_res_z)
           && imf_finite3(x->half_mag_res_x, x->half_mag_res_y, x->half_mag_res_z)
           && (x->q0 != IMF_R(0.0) || x->q1 != IMF_R(0.0) || x->q2 != IMF_R(0.0)
               || x->q3 != IMF_R(0.0));
}

static int inputs_ok(const imf_fusion_vec_t gyr, const imf_fusion_vec_t acc)
{
    return imf_finite3(gyr.x, gyr.y, gyr.z) && imf_finite3(acc.x, acc.y, acc.z);
}

static void commit_or_restore(imf_fusion13_ahrs_t *const self,
                              const imf_fusion13_ahrs_state_t *const saved)
{
    if (!state_finite(&self->x)) {
        self->x = *saved;
        self->skipped++;
    }
}

void imf_fusion13_ahrs_update(imf_fusion13_ahrs_t *const self, const imf_real gx, const imf_real gy,
                              const imf_real gz, const imf_real ax, const imf_real ay,
                              const imf_real az, const imf_real mx, const imf_real my,
                              const imf_real mz)
{
    const imf_fusion_vec_t gyr = { gx, gy, gz }, acc = { ax, ay, az }, mag = { mx, my, mz };
    const imf_fusion13_ahrs_state_t saved = self->x;
    if (!inputs_ok(gyr, acc) || !imf_finite3(mx, my, mz)) {
        self->skipped++;
        return;
    }
    ahrs_update(self, gyr, acc, mag);
    commit_or_restore(self, &saved);
}

void imf_fusion13_ahrs_update_no_magnetometer(imf_fusion13_ahrs_t *const self, const imf_real gx,
                                              const imf_real gy, const imf_real gz,
                                              const imf_real ax, const imf_real ay,
                                              const imf_real az)
{
    const imf_fusion_vec_t gyr = { gx, gy, gz }, acc = { ax, ay, az };
    const imf_fusion_vec_t zero = { IMF_R(0.0), IMF_R(0.0), IMF_R(0.0) };
    const imf_fusion13_ahrs_state_t saved = self->x;
    if (!inputs_ok(gyr, acc)) {
        self->skipped++;
        return;
    }
    ahrs_update(self, gyr, acc, zero);
    /* without a heading reference, hold the heading at 0 during start-up */
    if (self->x.startup != 0) {
        ahrs_set_heading(self, IMF_R(0.0));
    }
    commit_or_restore(self, &saved);
}

void imf_fusion13_ahrs_update_external_heading(imf_fusion13_ahrs_t *const self, const imf_real gx,
                                               const imf_real gy, const imf_real gz,
                                               const imf_real ax, const imf_real ay,
                                               const imf_real az, const imf_real heading)
{
    const imf_fusion_vec_t gyr = { gx, gy, gz }, acc = { ax, ay, az };
    const imf_fusion13_ahrs_state_t saved = self->x;
    const imf_fusion13_ahrs_state_t *const x = &self->x;
    imf_real roll, heading_rad, sin_heading;
    imf_fusion_vec_t mag;
    if (!inputs_ok(gyr, acc) || !isfinite(heading)) {
        self->skipped++;
        return;
    }
    /* a magnetometer reading pointing along the given heading, at the current roll */
    roll =
        imf_fusion_atan2(x->q0 * x->q1 + x->q2 * x->q3, IMF_R(0.5) - x->q2 * x->q2 - x->q1 * x->q1);
    heading_rad = imf_fusion_deg2rad(heading);
    sin_heading = imf_fusion_sin(heading_rad);
    mag.x = imf_fusion_cos(heading_rad);
    mag.y = IMF_R(-1.0) * imf_fusion_cos(roll) * sin_heading;
    mag.z = sin_heading * imf_fusion_sin(roll);
    ahrs_update(self, gyr, acc, mag);
    commit_or_restore(self, &saved);
}

void imf_fusion13_ahrs_set_heading(imf_fusion13_ahrs_t *const self, const imf_real heading)
{
    const imf_fusion13_ahrs_state_t saved = self->x;
    if (!isfinite(heading)) {
        self->skipped++;
        return;
    }
    ahrs_set_heading(self, heading);
    commit_or_restore(self, &saved);
}

void imf_fusion13_ahrs_get_state(const imf_fusion13_ahrs_t *const self, imf_real *const out)
{
    const imf_fusion13_ahrs_state_t *const x = &self->x;
    const imf_real reals[IMF_FUSION13_AHRS_N_REAL] = { x->q0,
                                                       x->q1,
                                                       x->q2,
                                                       x->q3,
                                                       x->acc_x,
                                                       x->acc_y,
                                                       x->acc_z,
                                                       x->startup_gain,
                                                       x->half_acc_res_x,
                                                       x->half_acc_res_y,
                                                       x->half_acc_res_z,
                                                       x->half_mag_res_x,
                                                       x->half_mag_res_y,
                                                       x->half_mag_res_z,
                                                       x->sample_period };
    const int32_t ints[IMF_FUSION13_AHRS_N_STATE - IMF_FUSION13_AHRS_N_REAL] = {
        x->startup,
        x->overrange_recovery,
        x->accelerometer_ignored,
        x->acceleration_recovery_trigger,
        x->acceleration_recovery_threshold,
        x->magnetometer_ignored,
        x->magnetic_recovery_trigger,
        x->magnetic_recovery_threshold
    };
    int i;
    for (i = 0; i < IMF_FUSION13_AHRS_N_REAL; i++) {
        out[i] = reals[i];
    }
    for (i = IMF_FUSION13_AHRS_N_REAL; i < IMF_FUSION13_AHRS_N_STATE; i++) {
        out[i] = (imf_real)ints[i - IMF_FUSION13_AHRS_N_REAL];
    }
}

void imf_fusion13_ahrs_set_state(imf_fusion13_ahrs_t *const self, const imf_real *const in)
{
    imf_fusion13_ahrs_state_t *const x = &self->x;
    x->q0 = in[0];
    x->q1 = in[1];
    x->q2 = in[2];
    x->q3 = in[3];
    x->acc_x = in[4];
    x->acc_y = in[5];
    x->acc_z = in[6];
    x->startup_gain = in[7];
    x->half_acc_res_x = in[8];
    x->half_acc_res_y = in[9];
    x->half_acc_res_z = in[10];
    x->half_mag_res_x = in[11];
    x->half_mag_res_y = in[12];
    x->half_mag_res_z = in[13];
    x->sample_period = in[14];
    x->startup = (int32_t)in[15];
    x->overrange_recovery = (int32_t)in[16];
    x->accelerometer_ignored = (int32_t)in[17];
    x->acceleration_recovery_trigger = (int32_t)in[18];
    x->acceleration_recovery_threshold = (int32_t)in[19];
    x->magnetometer_ignored = (int32_t)in[20];
    x->magnetic_recovery_trigger = (int32_t)in[21];
    x->magnetic_recovery_threshold = (int32_t)in[22];
}

void imf_fusion13_ahrs_outputs(const imf_fusion13_ahrs_t *const self, imf_real *const out)
{
    const imf_fusion13_ahrs_state_t *const x = &self->x;
    const imf_real qw = x->q0, qx = x->q1, qy = x->q2, qz = x->q3;
    const imf_real ax = x->acc_x, ay = x->acc_y, az = x->acc_z;
    const imf_fusion_vec_t g = imf_fusion_vec_scale(half_gravity(self), IMF_R(2.0));
    out[0] = g.x;
    out[1] = g.y;
    out[2] = g.z;
    out[3] = ax - g.x;
    out[4] = ay - g.y;
    out[5] = az - g.z;
    /* R a: the accelerometer in the earth frame, minus gravity */
    out[6] = IMF_R(2.0)
             * ((qw * qw - IMF_R(0.5) + qx * qx) * ax + (qx * qy - qw * qz) * ay
                + (qx * qz + qw * qy) * az);
    out[7] = IMF_R(2.0)
             * ((qx * qy + qw * qz) * ax + (qw * qw - IMF_R(0.5) + qy * qy) * ay
                + (qy * qz - qw * qx) * az);
    out[8] = IMF_R(2.0)
             * ((qx * qz - qw * qy) * ax + (qy * qz + qw * qx) * ay
                + (qw * qw - IMF_R(0.5) + qz * qz) * az);
    if (self->set.convention == IMF_FUSION_NED) {
        out[8] += IMF_R(1.0);
    } else {
        out[8] -= IMF_R(1.0);
    }
    /* Euler angles (ZYX), degrees, in 1.3's form */
    out[9] =
        imf_fusion_rad2deg(imf_fusion_atan2(qy * qz + qw * qx, qw * qw + qz * qz - IMF_R(0.5)));
    out[10] = imf_fusion_rad2deg(imf_fusion_safe_asin(IMF_R(2.0) * (qw * qy - qx * qz)));
    out[11] =
        imf_fusion_rad2deg(imf_fusion_atan2(qx * qy + qw * qz, qw * qw + qx * qx - IMF_R(0.5)));
    out[12] = imf_fusion_error_degrees(x->half_acc_res_x, x->half_acc_res_y, x->half_acc_res_z);
    out[13] =
        imf_fusion_trigger_ratio(x->acceleration_recovery_trigger, self->set.rejection_timeout);
    out[14] = imf_fusion_error_degrees(x->half_mag_res_x, x->half_mag_res_y, x->half_mag_res_z);
    out[15] = imf_fusion_trigger_ratio(x->magnetic_recovery_trigger, self->set.rejection_timeout);
}

unsigned imf_fusion13_ahrs_flags(const imf_fusion13_ahrs_t *const self)
{
    const imf_fusion13_ahrs_state_t *const x = &self->x;
    unsigned flags = 0u;
    flags |= x->startup != 0 ? 1u : 0u;
    flags |= x->overrange_recovery != 0 ? 2u : 0u;
    flags |= x->acceleration_recovery_trigger > x->acceleration_recovery_threshold ? 4u : 0u;
    flags |= x->magnetic_recovery_trigger > x->magnetic_recovery_threshold ? 8u : 0u;
    flags |= x->accelerometer_ignored != 0 ? 16u : 0u;
    flags |= x->magnetometer_ignored != 0 ? 32u : 0u;
    return flags;
}
