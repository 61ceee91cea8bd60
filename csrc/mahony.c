/*
 * Mahony's filter in quaternion form as implemented by Madgwick. See
 * mahony.h. The pure-Python twin is python/imufuse/reference/mahony.py: the
 * same lines in the same order. Step numbers are those of the article's
 * Appendix "IMU Implementations".
 *
 * Half vectors: d/2 and e/2 are computed instead of d and e (one multiply
 * less per component); 2 Kp (e/2) = Kp e exactly, since scaling by 2 is
 * exact. The order of every operation is the published one.
 */
#include "mahony.h"

/* The settings that depend on the sample period dt (s). */
static void mahony_set_dt(imf_mahony_consts_t *const set, const imf_real dt)
{
    set->dt = dt;
    set->half_dt = IMF_R(0.5) * dt;
}

void imf_mahony_default_settings(imf_mahony_settings_t *const settings)
{
    settings->dt = IMF_R(0.01);
    settings->kp = IMF_R(0.5);
    settings->ki = IMF_R(0.0);
    settings->invsqrt = IMF_INVSQRT_EXACT;
    settings->acc_gate_lo = IMF_R(-1.0);
    settings->acc_gate_hi = IMF_R(0.0);
    settings->acc_1g = IMF_R(1.0);
}

/* Settings as the twin's record gives them (q = 1, I = 0, skipped = 0). */
void imf_mahony_init(imf_mahony_t *const self, const imf_mahony_settings_t *const s)
{
    mahony_set_dt(&self->set, s->dt);
    imf_acc_gate_set(&self->set.acc_gate, &self->set.acc_lo2, &self->set.acc_hi2, s->acc_gate_lo,
                     s->acc_gate_hi, s->acc_1g);
    self->set.two_kp = IMF_R(2.0) * s->kp;
    self->set.two_ki = IMF_R(2.0) * s->ki;
    self->set.invsqrt = s->invsqrt == IMF_INVSQRT_FAST ? IMF_INVSQRT_FAST : IMF_INVSQRT_EXACT;
    self->skipped = 0;
    self->x.q0 = IMF_R(1.0);
    self->x.q1 = IMF_R(0.0);
    self->x.q2 = IMF_R(0.0);
    self->x.q3 = IMF_R(0.0);
    self->x.ix = IMF_R(0.0);
    self->x.iy = IMF_R(0.0);
    self->x.iz = IMF_R(0.0);
}

void imf_mahony_set_acc_gate(imf_mahony_t *const self, const imf_real acc_gate_lo,
                             const imf_real acc_gate_hi, const imf_real acc_1g)
{
    imf_acc_gate_set(&self->set.acc_gate, &self->set.acc_lo2, &self->set.acc_hi2, acc_gate_lo,
                     acc_gate_hi, acc_1g);
}

void imf_mahony_set_dt(imf_mahony_t *const self, const imf_real dt)
{
    mahony_set_dt(&self->set, dt);
}

static void mahony_set_attitude(imf_mahony_state_t *const x, const imf_attitude_t *const att)
{
    x->q0 = att->q[0];
    x->q1 = att->q[1];
    x->q2 = att->q[2];
    x->q3 = att->q[3];
}

void imf_mahony_set_attitude(imf_mahony_t *const self, const imf_attitude_t *const att)
{
    mahony_set_attitude(&self->x, att);
}

/* Steps 5 and 6: the PI controller on the half error (ex, ey, ez) = e/2,
   added to the rate (*gx, *gy, *gz) in the published order w + I + Kp e. */
static void mahony_feedback(const imf_mahony_consts_t *const set, imf_mahony_state_t *const x,
                            imf_real *const gx, imf_real *const gy, imf_real *const gz,
                            const imf_real ex, const imf_real ey, const imf_real ez)
{
    if (set->two_ki > IMF_R(0.0)) {
        /* Step 5: I_n = I_{n-1} + Ki dt e = I_{n-1} + (2 Ki)(e/2) dt */
        x->ix += set->two_ki * ex * set->dt;
        x->iy += set->two_ki * ey * set->dt;
        x->iz += set->two_ki * ez * set->dt;
        *gx += x->ix;
        *gy += x->iy;
        *gz += x->iz;
    } else {
        /* Ki = 0: no integral action, and none wound up for later */
        x->ix = IMF_R(0.0);
        x->iy = IMF_R(0.0);
        x->iz = IMF_R(0.0);
    }
    /* Step 6: omega' = omega + I_n + Kp e */
    *gx += set->two_kp * ex;
    *gy += set->two_kp * ey;
    *gz += set->two_kp * ez;
}

/* Steps 7 and 8: q_n = q_{n-1} + 1/2 q_{n-1} (x) omega' dt, then normalise.
   Returns 0 when q cannot be normalised (the sample is rejected). */
static int mahony_integrate(const imf_mahony_consts_t *const set, imf_mahony_state_t *const x,
                            imf_real gx, imf_real gy, imf_real gz)
{
    const imf_real q0 = x->q0, q1 = x->q1, q2 = x->q2, q3 = x->q3;
    gx *= set->half_dt;
    gy *= set->half_dt;
    gz *= set->half_dt;
    x->q0 = q0 + (-q1 * gx - q2 * gy - q3 * gz);
    x->q1 = q1 + (q0 * gx + q2 * gz - q3 * gy);
    x->q2 = q2 + (q0 * gy - q1 * gz + q3 * gx);
    x->q3 = q3 + (q0 * gz + q1 * gy - q2 * gx);
    return imf_normalise4(&x->q0, &x->q1, &x->q2, &x->q3, set->invsqrt) == IMF_NORM_OK;
}

/* One update; returns 0 if a normalisation failed (the sample is rejected). */
static int mahony_imu_step(const imf_mahony_consts_t *const set, imf_mahony_state_t *const x,
                           imf_real gx, imf_real gy, imf_real gz, imf_real ax, imf_real ay,
                           imf_real az)
{
    if (!imf_is_zero3(ax, ay, az)
        && imf_acc_gate_pass(set->acc_gate, set->acc_lo2, set->acc_hi2, ax, ay, az)) {
        imf_real vx, vy, vz, ex, ey, ez;
        /* Step 2: normalise a */
        if (imf_normalise3(&ax, &ay, &az, set->invsqrt) != IMF_NORM_OK) {
            return 0;
        }
        /* Step 3: d/2, half the earth's up axis seen in the sensor frame */
        vx = x->q1 * x->q3 - x->q0 * x->q2;
        vy = x->q0 * x->q1 + x->q2 * x->q3;
        vz = x->q0 * x->q0 - IMF_R(0.5) + x->q3 * x->q3;
        /* Step 4: e/2 = a x (d/2) */
        ex = ay * vz - az * vy;
        ey = az * vx - ax * vz;
        ez = ax * vy - ay * vx;
        mahony_feedback(set, x, &gx, &gy, &gz, ex, ey, ez);
    }
    return mahony_integrate(set, x, gx, gy, gz);
}

static int mahony_ahrs_step(const imf_mahony_consts_t *const set, imf_mahony_state_t *const x,
                            imf_real gx, imf_real gy, imf_real gz, imf_real ax, imf_real ay,
                            imf_real az, imf_real mx, imf_real my, imf_real mz)
{
    if (imf_is_zero3(mx, my, mz)) {
        /* no magnetometer reading: the IMU update */
        return mahony_imu_step(set, x, gx, gy, gz, ax, ay, az);
    }
    if (!imf_is_zero3(ax, ay, az)
        && imf_acc_gate_pass(set->acc_gate, set->acc_lo2, set->acc_hi2, ax, ay, az)) {
        imf_real q0q0, q0q1, q0q2, q0q3, q1q1, q1q2, q1q3, q2q2, q2q3, q3q3;
        imf_real hx, hy, bx, bz, vx, vy, vz, wx, wy, wz, ex, ey, ez;
        /* Step 2: normalise a and m */
        if (imf_normalise3(&ax, &ay, &az, set->invsqrt) != IMF_NORM_OK
            || imf_normalise3(&mx, &my, &mz, set->invsqrt) != IMF_NORM_OK) {
            return 0;
        }
        q0q0 = x->q0 * x->q0;
        q0q1 = x->q0 * x->q1;
        q0q2 = x->q0 * x->q2;
        q0q3 = x->q0 * x->q3;
        q1q1 = x->q1 * x->q1;
        q1q2 = x->q1 * x->q2;
        q1q3 = x->q1 * x->q3;
        q2q2 = x->q2 * x->q2;
        q2q3 = x->q2 * x->q3;
        q3q3 = x->q3 * x->q3;
        /* the field in the earth frame, h = R m; the reference field keeps its
           vertical part bz and puts the horizontal part bx along earth x */
        hx = IMF_R(2.0)
             * (mx * (IMF_R(0.5) - q2q2 - q3q3) + my * (q1q2 - q0q3) + mz * (q1q3 + q0q2));
        hy = IMF_R(2.0)
             * (mx * (q1q2 + q0q3) + my * (IMF_R(0.5) - q1q1 - q3q3) + mz * (q2q3 - q0q1));
        bx = imf_sqrt(hx * hx + hy * hy);
        bz = IMF_R(2.0)
             * (mx * (q1q3 - q0q2) + my * (q2q3 + q0q1) + mz * (IMF_R(0.5) - q1q1 - q2q2));
        /* Step 3: d/2 and w/2, the estimated up axis and field direction seen
           in the sensor frame (halved) */
        vx = q1q3 - q0q2;
        vy = q0q1 + q2q3;
        vz = q0q0 - IMF_R(0.5) + q3q3;
        wx = bx * (IMF_R(0.5) - q2q2 - q3q3) + bz * (q1q3 - q0q2);
        wy = bx * (q1q2 - q0q3) + bz * (q0q1 + q2q3);
        wz = bx * (q0q2 + q1q3) + bz * (IMF_R(0.5) - q1q1 - q2q2);
        /* Step 4: e/2 = a x (d/2) + m x (w/2) */
        ex = (ay * vz - az * vy) + (my * wz - mz * wy);
        ey = (az * vx - ax * vz) + (mz * wx - mx * wz);
        ez = (ax * vy - ay * vx) + (mx * wy - my * wx);
        mahony_feedback(set, x, &gx, &gy, &gz, ex, ey, ez);
    }
    return mahony_integrate(set, x, gx, gy, gz);
}

/* Keep the new state only if the update succeeded and left it finite
   (valid-attitude policy, imf_math.h). */
static void mahony_commit(imf_mahony_state_t *const dst, uint32_t *const skipped,
                          const imf_mahony_state_t *const x, const int ok)
{
    if (!(ok && imf_finite4(x->q0, x->q1, x->q2, x->q3) && imf_finite3(x->ix, x->iy, x->iz))) {
        (*skipped)++;
        return;
    }
    *dst = *x;
}

void imf_mahony_update_imu(imf_mahony_t *const self, const imf_real gx, const imf_real gy,
                           const imf_real gz, const imf_real ax, const imf_real ay,
                           const imf_real az)
{
    imf_mahony_state_t x;
    if (!(imf_finite3(gx, gy, gz) && imf_finite3(ax, ay, az))) {
        self->skipped++;
        return;
    }
    x = self->x;
    mahony_commit(&self->x, &self->skipped, &x,
                  mahony_imu_step(&self->set, &x, gx, gy, gz, ax, ay, az));
}

void imf_mahony_update(imf_mahony_t *const self, const imf_real gx, const imf_real gy,
                       const imf_real gz, const imf_real ax, const imf_real ay, const imf_real az,
                       const imf_real mx, const imf_real my, const imf_real mz)
{
    imf_mahony_state_t x;
    if (!(imf_finite3(gx, gy, gz) && imf_finite3(ax, ay, az) && imf_finite3(mx, my, mz))) {
        self->skipped++;
        return;
    }
    x = self->x;
    mahony_commit(&self->x, &self->skipped, &x,
                  mahony_ahrs_step(&self->set, &x, gx, gy, gz, ax, ay, az, mx, my, mz));
}
