/*
 * Madgwick's gradient-descent filter. See madgwick.h. The pure-Python twin
 * is python/imufuse/reference/madgwick.py: the same lines in the same order.
 * The host's lane twin, imufuse_c/host/lanes_body.h (imufuse_c.run_filters, tune),
 * repeats these steps for several filters at once, bit for bit: change both.
 * Step numbers are those of the article's Appendix "IMU Implementations".
 */
#include "madgwick.h"

/* The settings that depend on the sample period dt (s). */
static void madgwick_set_dt(imf_madgwick_consts_t *const set, const imf_real dt)
{
    set->dt = dt;
}

void imf_madgwick_default_settings(imf_madgwick_settings_t *const settings)
{
    settings->dt = IMF_R(0.01);
    settings->beta = IMF_R(0.1);
    settings->delta_s = IMF_MADGWICK_DS_FULL;
    settings->invsqrt = IMF_INVSQRT_EXACT;
    settings->acc_gate_lo = IMF_R(-1.0);
    settings->acc_gate_hi = IMF_R(0.0);
    settings->acc_1g = IMF_R(1.0);
}

/* Settings as the twin's record gives them (q = 1, skipped = 0). */
void imf_madgwick_init(imf_madgwick_t *const self, const imf_madgwick_settings_t *const s)
{
    madgwick_set_dt(&self->set, s->dt);
    imf_acc_gate_set(&self->set.acc_gate, &self->set.acc_lo2, &self->set.acc_hi2, s->acc_gate_lo,
                     s->acc_gate_hi, s->acc_1g);
    self->set.beta = s->beta;
    self->set.delta_s = s->delta_s == IMF_MADGWICK_DS_SIMPLIFIED ? IMF_MADGWICK_DS_SIMPLIFIED
                                                                 : IMF_MADGWICK_DS_FULL;
    self->set.invsqrt = s->invsqrt == IMF_INVSQRT_FAST ? IMF_INVSQRT_FAST : IMF_INVSQRT_EXACT;
    self->skipped = 0;
    self->x.q0 = IMF_R(1.0);
    self->x.q1 = IMF_R(0.0);
    self->x.q2 = IMF_R(0.0);
    self->x.q3 = IMF_R(0.0);
}

void imf_madgwick_set_acc_gate(imf_madgwick_t *const self, const imf_real acc_gate_lo,
                               const imf_real acc_gate_hi, const imf_real acc_1g)
{
    imf_acc_gate_set(&self->set.acc_gate, &self->set.acc_lo2, &self->set.acc_hi2, acc_gate_lo,
                     acc_gate_hi, acc_1g);
}

void imf_madgwick_set_dt(imf_madgwick_t *const self, const imf_real dt)
{
    madgwick_set_dt(&self->set, dt);
}

static void madgwick_set_attitude(imf_madgwick_state_t *const x, const imf_attitude_t *const att)
{
    x->q0 = att->q[0];
    x->q1 = att->q[1];
    x->q2 = att->q[2];
    x->q3 = att->q[3];
}

void imf_madgwick_set_attitude(imf_madgwick_t *const self, const imf_attitude_t *const att)
{
    madgwick_set_attitude(&self->x, att);
}

/* Step 3: dq = 1/2 q (x) omega */
static void madgwick_rate(const imf_madgwick_state_t *const x, const imf_real gx, const imf_real gy,
                          const imf_real gz, imf_real dq[4])
{
    dq[0] = IMF_R(0.5) * (-x->q1 * gx - x->q2 * gy - x->q3 * gz);
    dq[1] = IMF_R(0.5) * (x->q0 * gx + x->q2 * gz - x->q3 * gy);
    dq[2] = IMF_R(0.5) * (x->q0 * gy - x->q1 * gz + x->q3 * gx);
    dq[3] = IMF_R(0.5) * (x->q0 * gz + x->q1 * gy - x->q2 * gx);
}

/* Step 4, full form: ds = J^T f for the gravity objective, valid for any q,
   term by term as in the article's appendix and the published code. */
static void madgwick_ds_full(const imf_madgwick_state_t *const x, const imf_real ax,
                             const imf_real ay, const imf_real az, imf_real s[4])
{
    const imf_real q0 = x->q0, q1 = x->q1, q2 = x->q2, q3 = x->q3;
    const imf_real two_q0 = IMF_R(2.0) * q0;
    const imf_real two_q1 = IMF_R(2.0) * q1;
    const imf_real two_q2 = IMF_R(2.0) * q2;
    const imf_real two_q3 = IMF_R(2.0) * q3;
    const imf_real four_q0 = IMF_R(4.0) * q0;
    const imf_real four_q1 = IMF_R(4.0) * q1;
    const imf_real four_q2 = IMF_R(4.0) * q2;
    const imf_real eight_q1 = IMF_R(8.0) * q1;
    const imf_real eight_q2 = IMF_R(8.0) * q2;
    const imf_real q0q0 = q0 * q0;
    const imf_real q1q1 = q1 * q1;
    const imf_real q2q2 = q2 * q2;
    const imf_real q3q3 = q3 * q3;
    s[0] = four_q0 * q2q2 + two_q2 * ax + four_q0 * q1q1 - two_q1 * ay;
    s[1] = four_q1 * q3q3 - two_q3 * ax + IMF_R(4.0) * q0q0 * q1 - two_q0 * ay - four_q1
           + eight_q1 * q1q1 + eight_q1 * q2q2 + four_q1 * az;
    s[2] = IMF_R(4.0) * q0q0 * q2 + two_q0 * ax + four_q2 * q3q3 - two_q3 * ay - four_q2
           + eight_q2 * q1q1 + eight_q2 * q2q2 + four_q2 * az;
    s[3] = IMF_R(4.0) * q1q1 * q3 - two_q1 * ax + IMF_R(4.0) * q2q2 * q3 - two_q2 * ay;
}

/* Step 4, simplified form (article, note below the appendix): for a unit q
   ds = 4 (q1^2 + q2^2) q + 2 (q2 ax - q1 ay, -q3 ax - q0 ay + 2 q1 az,
                               q0 ax - q3 ay + 2 q2 az, -q1 ax - q2 ay). */
static void madgwick_ds_simplified(const imf_madgwick_state_t *const x, const imf_real ax,
                                   const imf_real ay, const imf_real az, imf_real s[4])
{
    const imf_real q0 = x->q0, q1 = x->q1, q2 = x->q2, q3 = x->q3;
    const imf_real c = IMF_R(4.0) * (q1 * q1 + q2 * q2);
    s[0] = c * q0 + IMF_R(2.0) * (q2 * ax - q1 * ay);
    s[1] = c * q1 + IMF_R(2.0) * (-q3 * ax - q0 * ay + IMF_R(2.0) * q1 * az);
    s[2] = c * q2 + IMF_R(2.0) * (q0 * ax - q3 * ay + IMF_R(2.0) * q2 * az);
    s[3] = c * q3 + IMF_R(2.0) * (-q1 * ax - q2 * ay);
}

/* ds = J^T f for the gravity and the magnetic objective (AHRS), with the
   published intermediates and order. f1..f3: predicted minus measured
   gravity direction; f4..f6: the same for the field, the reference field
   being (bx, 0, bz) in the earth frame (two_bx = 2 bx, two_bz = 2 bz). */
static void madgwick_ds_ahrs(const imf_madgwick_state_t *const x, const imf_real ax,
                             const imf_real ay, const imf_real az, const imf_real mx,
                             const imf_real my, const imf_real mz, imf_real s[4])
{
    const imf_real q0 = x->q0, q1 = x->q1, q2 = x->q2, q3 = x->q3;
    const imf_real two_q0 = IMF_R(2.0) * q0;
    const imf_real two_q1 = IMF_R(2.0) * q1;
    const imf_real two_q2 = IMF_R(2.0) * q2;
    const imf_real two_q3 = IMF_R(2.0) * q3;
    const imf_real two_q0mx = two_q0 * mx;
    const imf_real two_q0my = two_q0 * my;
    const imf_real two_q0mz = two_q0 * mz;
    const imf_real two_q1mx = two_q1 * mx;
    const imf_real two_q0q2 = two_q0 * q2;
    const imf_real two_q2q3 = two_q2 * q3;
    const imf_real q0q0 = q0 * q0;
    const imf_real q0q1 = q0 * q1;
    const imf_real q0q2 = q0 * q2;
    const imf_real q0q3 = q0 * q3;
    const imf_real q1q1 = q1 * q1;
    const imf_real q1q2 = q1 * q2;
    const imf_real q1q3 = q1 * q3;
    const imf_real q2q2 = q2 * q2;
    const imf_real q2q3 = q2 * q3;
    const imf_real q3q3 = q3 * q3;
    imf_real hx, hy, two_bx, two_bz, four_bx, four_bz, f1, f2, f3, f4, f5, f6;
    /* the field in the earth frame, h = R m (expanded) */
    hx = mx * q0q0 - two_q0my * q3 + two_q0mz * q2 + mx * q1q1 + two_q1 * my * q2 + two_q1 * mz * q3
         - mx * q2q2 - mx * q3q3;
    hy = two_q0mx * q3 + my * q0q0 - two_q0mz * q1 + two_q1mx * q2 - my * q1q1 + my * q2q2
         + two_q2 * mz * q3 - my * q3q3;
    two_bx = imf_sqrt(hx * hx + hy * hy);
    two_bz = -two_q0mx * q2 + two_q0my * q1 + mz * q0q0 + two_q1mx * q3 - mz * q1q1
             + two_q2 * my * q3 - mz * q2q2 + mz * q3q3;
    four_bx = IMF_R(2.0) * two_bx;
    four_bz = IMF_R(2.0) * two_bz;
    /* objective function f */
    f1 = IMF_R(2.0) * q1q3 - two_q0q2 - ax;
    f2 = IMF_R(2.0) * q0q1 + two_q2q3 - ay;
    f3 = IMF_R(1.0) - IMF_R(2.0) * q1q1 - IMF_R(2.0) * q2q2 - az;
    f4 = two_bx * (IMF_R(0.5) - q2q2 - q3q3) + two_bz * (q1q3 - q0q2) - mx;
    f5 = two_bx * (q1q2 - q0q3) + two_bz * (q0q1 + q2q3) - my;
    f6 = two_bx * (q0q2 + q1q3) + two_bz * (IMF_R(0.5) - q1q1 - q2q2) - mz;
    /* gradient J^T f */
    s[0] = -two_q2 * f1 + two_q1 * f2 - two_bz * q2 * f4 + (-two_bx * q3 + two_bz * q1) * f5
           + two_bx * q2 * f6;
    s[1] = two_q3 * f1 + two_q0 * f2 - IMF_R(4.0) * q1 * f3 + two_bz * q3 * f4
           + (two_bx * q2 + two_bz * q0) * f5 + (two_bx * q3 - four_bz * q1) * f6;
    s[2] = -two_q0 * f1 + two_q3 * f2 - IMF_R(4.0) * q2 * f3 + (-four_bx * q2 - two_bz * q0) * f4
           + (two_bx * q1 + two_bz * q3) * f5 + (two_bx * q0 - four_bz * q2) * f6;
    s[3] = two_q1 * f1 + two_q2 * f2 + (-four_bx * q3 + two_bz * q1) * f4
           + (-two_bx * q0 + two_bz * q2) * f5 + two_bx * q1 * f6;
}

/* Steps 5 and 6: normalise ds, dq' = dq - beta ds. A zero (or subnormal)
   ds is the exact optimum: it has no direction and is left as it is (no
   correction). Returns 0 if ds overflowed (the sample is rejected). */
static int madgwick_feedback(const imf_madgwick_consts_t *const set, imf_real s[4], imf_real dq[4])
{
    if (imf_normalise4(&s[0], &s[1], &s[2], &s[3], set->invsqrt) == IMF_NORM_HUGE) {
        return 0;
    }
    dq[0] -= set->beta * s[0];
    dq[1] -= set->beta * s[1];
    dq[2] -= set->beta * s[2];
    dq[3] -= set->beta * s[3];
    return 1;
}

/* Steps 7 and 8: q_n = q_{n-1} + dq' dt, then normalise. Returns 0 when q
   cannot be normalised (the sample is rejected). */
static int madgwick_integrate(const imf_madgwick_consts_t *const set, imf_madgwick_state_t *const x,
                              const imf_real dq[4])
{
    x->q0 += dq[0] * set->dt;
    x->q1 += dq[1] * set->dt;
    x->q2 += dq[2] * set->dt;
    x->q3 += dq[3] * set->dt;
    return imf_normalise4(&x->q0, &x->q1, &x->q2, &x->q3, set->invsqrt) == IMF_NORM_OK;
}

/* One update; returns 0 if a normalisation failed (the sample is rejected). */
static int madgwick_imu_step(const imf_madgwick_consts_t *const set, imf_madgwick_state_t *const x,
                             const imf_real gx, const imf_real gy, const imf_real gz, imf_real ax,
                             imf_real ay, imf_real az)
{
    imf_real dq[4], s[4];
    madgwick_rate(x, gx, gy, gz, dq);
    if (!imf_is_zero3(ax, ay, az)
        && imf_acc_gate_pass(set->acc_gate, set->acc_lo2, set->acc_hi2, ax, ay, az)) {
        /* Step 2: normalise a */
        if (imf_normalise3(&ax, &ay, &az, set->invsqrt) != IMF_NORM_OK) {
            return 0;
        }
        if (set->delta_s == IMF_MADGWICK_DS_SIMPLIFIED) {
            madgwick_ds_simplified(x, ax, ay, az, s);
        } else {
            madgwick_ds_full(x, ax, ay, az, s);
        }
        if (!madgwick_feedback(set, s, dq)) {
            return 0;
        }
    }
    return madgwick_integrate(set, x, dq);
}

static int madgwick_ahrs_step(const imf_madgwick_consts_t *const set, imf_madgwick_state_t *const x,
                              const imf_real gx, const imf_real gy, const imf_real gz, imf_real ax,
                              imf_real ay, imf_real az, imf_real mx, imf_real my, imf_real mz)
{
    imf_real dq[4], s[4];
    if (imf_is_zero3(mx, my, mz)) {
        /* no magnetometer reading: the IMU update */
        return madgwick_imu_step(set, x, gx, gy, gz, ax, ay, az);
    }
    madgwick_rate(x, gx, gy, gz, dq);
    if (!imf_is_zero3(ax, ay, az)
        && imf_acc_gate_pass(set->acc_gate, set->acc_lo2, set->acc_hi2, ax, ay, az)) {
        if (imf_normalise3(&ax, &ay, &az, set->invsqrt) != IMF_NORM_OK
            || imf_normalise3(&mx, &my, &mz, set->invsqrt) != IMF_NORM_OK) {
            return 0;
        }
        madgwick_ds_ahrs(x, ax, ay, az, mx, my, mz, s);
        if (!madgwick_feedback(set, s, dq)) {
            return 0;
        }
    }
    return madgwick_integrate(set, x, dq);
}

/* Keep the new state only if the update succeeded and left it finite
   (valid-attitude policy, imf_math.h). */
static void madgwick_commit(imf_madgwick_state_t *const dst, uint32_t *const skipped,
                            const imf_madgwick_state_t *const x, const int ok)
{
    if (!(ok && imf_finite4(x->q0, x->q1, x->q2, x->q3))) {
        (*skipped)++;
        return;
    }
    *dst = *x;
}

void imf_madgwick_update_imu(imf_madgwick_t *const self, const imf_real gx, const imf_real gy,
                             const imf_real gz, const imf_real ax, const imf_real ay,
                             const imf_real az)
{
    imf_madgwick_state_t x;
    if (!(imf_finite3(gx, gy, gz) && imf_finite3(ax, ay, az))) {
        self->skipped++;
        return;
    }
    x = self->x;
    madgwick_commit(&self->x, &self->skipped, &x,
                    madgwick_imu_step(&self->set, &x, gx, gy, gz, ax, ay, az));
}

void imf_madgwick_update(imf_madgwick_t *const self, const imf_real gx, const imf_real gy,
                         const imf_real gz, const imf_real ax, const imf_real ay, const imf_real az,
                         const imf_real mx, const imf_real my, const imf_real mz)
{
    imf_madgwick_state_t x;
    if (!(imf_finite3(gx, gy, gz) && imf_finite3(ax, ay, az) && imf_finite3(mx, my, mz))) {
        self->skipped++;
        return;
    }
    x = self->x;
    madgwick_commit(&self->x, &self->skipped, &x,
                    madgwick_ahrs_step(&self->set, &x, gx, gy, gz, ax, ay, az, mx, my, mz));
}
