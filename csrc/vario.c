/*
 * Variometer of Nair (2016). See vario.h. The pure-Python twin is
 * python/imufuse/reference/vario.py: the same lines in the same order.
 * Step numbers are those of Nair's "Prediction" and "Update" lists.
 */
#include "vario.h"

void imf_vario_default_settings(imf_vario_settings_t *const settings)
{
    settings->var_z = IMF_R(300.0);
    settings->var_acc = IMF_R(200.0);
    settings->var_bias = IMF_R(1.0);
    settings->p_z = IMF_R(1.0);
    settings->p_v = IMF_R(1.0);
    settings->p_b = IMF_R(100000.0);
    settings->z0 = IMF_R(0.0);
    settings->v0 = IMF_R(0.0);
    settings->b0 = IMF_R(0.0);
    settings->z0_from_baro = 1;
    settings->predict = IMF_VARIO_PREDICT_SEED;
}

void imf_vario_init(imf_vario_t *const self, const imf_vario_settings_t *const s)
{
    self->set.var_z = s->var_z;
    self->set.var_acc = s->var_acc;
    self->set.var_bias = s->var_bias;
    self->set.predict =
        s->predict == IMF_VARIO_PREDICT_MODEL ? IMF_VARIO_PREDICT_MODEL : IMF_VARIO_PREDICT_SEED;
    self->skipped = 0;
    self->started = s->z0_from_baro ? 0 : 1;
    self->x.z = s->z0;
    self->x.v = s->v0;
    self->x.b = s->b0;
    self->x.pzz = s->p_z;
    self->x.pzv = IMF_R(0.0);
    self->x.pzb = IMF_R(0.0);
    self->x.pvv = s->p_v;
    self->x.pvb = IMF_R(0.0);
    self->x.pbb = s->p_b;
}

/* Step 1: P = F P F^T + Q, with A = F P (rows 0 and 1; row 2 of F P is
   row 2 of P) and F's entries dt and h = -(-dt^2/2). */
static void vario_predict_covariance(const imf_vario_consts_t *const set,
                                     imf_vario_state_t *const x, const imf_real dt)
{
    const imf_real dt2 = dt * dt;
    const imf_real dt3 = dt2 * dt;
    const imf_real dt4 = dt2 * dt2;
    const imf_real h = IMF_R(0.5) * dt2;
    const imf_real a00 = x->pzz + dt * x->pzv - h * x->pzb;
    const imf_real a01 = x->pzv + dt * x->pvv - h * x->pvb;
    const imf_real a02 = x->pzb + dt * x->pvb - h * x->pbb;
    const imf_real a11 = x->pvv - dt * x->pvb;
    const imf_real a12 = x->pvb - dt * x->pbb;
    x->pzz = a00 + dt * a01 - h * a02 + IMF_R(0.25) * dt4 * set->var_acc;
    x->pzv = a01 - dt * a02 + IMF_R(0.5) * dt3 * set->var_acc;
    x->pzb = a02;
    x->pvv = a11 - dt * a12 + dt2 * set->var_acc;
    x->pvb = a12;
    x->pbb = x->pbb + set->var_bias;
}

/* Step 2: a priori state, accel_real = accel_meas - b */
static void vario_predict_state(const imf_vario_consts_t *const set, imf_vario_state_t *const x,
                                const imf_real accel, const imf_real dt)
{
    const imf_real acc = accel - x->b;
    if (set->predict == IMF_VARIO_PREDICT_MODEL) {
        /* the first row of F: z += v dt + (a - b) dt^2/2, with the old v */
        x->z = x->z + x->v * dt + IMF_R(0.5) * dt * dt * acc;
        x->v = x->v + acc * dt;
    } else {
        /* as Nair writes it: v first, then z with the new v */
        x->v = x->v + acc * dt;
        x->z = x->z + x->v * dt;
    }
}

/* Steps 3-7: innovation, its covariance, gain, a posteriori state and
   covariance P = (I - K H) P. */
static void vario_correct(const imf_vario_consts_t *const set, imf_vario_state_t *const x,
                          const imf_real baro_alt)
{
    /* Step 3: y = m - H x */
    const imf_real y = baro_alt - x->z;
    /* Step 4: s = pzz + sigma_z^2 */
    const imf_real s = x->pzz + set->var_z;
    /* Step 5: K = P H^T / s */
    const imf_real inv_s = IMF_R(1.0) / s;
    const imf_real kz = x->pzz * inv_s;
    const imf_real kv = x->pzv * inv_s;
    const imf_real kb = x->pzb * inv_s;
    const imf_real pzz = x->pzz, pzv = x->pzv, pzb = x->pzb;
    /* Step 6: x = x + K y */
    x->z = x->z + kz * y;
    x->v = x->v + kv * y;
    x->b = x->b + kb * y;
    /* Step 7: P = P - K [pzz pzv pzb] */
    x->pzz = pzz - kz * pzz;
    x->pzv = pzv - kz * pzv;
    x->pzb = pzb - kz * pzb;
    x->pvv = x->pvv - kv * pzv;
    x->pvb = x->pvb - kv * pzb;
    x->pbb = x->pbb - kb * pzb;
}

static int vario_finite(const imf_vario_state_t *const x)
{
    return imf_finite3(x->z, x->v, x->b) && imf_finite3(x->pzz, x->pzv, x->pzb)
           && imf_finite3(x->pvv, x->pvb, x->pbb);
}

void imf_vario_update(imf_vario_t *const self, const imf_real accel, const imf_real baro_alt,
                      const imf_real dt)
{
    imf_vario_state_t x;
    if (!(imf_finite3(accel, baro_alt, dt) && dt > IMF_R(0.0))) {
        self->skipped++;
        return;
    }
    if (!self->started) {
        /* z0 = the first barometer altitude */
        self->x.z = baro_alt;
        self->started = 1;
        return;
    }
    x = self->x;
    vario_predict_covariance(&self->set, &x, dt);
    vario_predict_state(&self->set, &x, accel, dt);
    vario_correct(&self->set, &x, baro_alt);
    if (!vario_finite(&x)) {
        self->skipped++;
        return;
    }
    self->x = x;
}

imf_real imf_vertical_accel(const imf_real q0, const imf_real q1, const imf_real q2,
                            const imf_real q3, const imf_real ax, const imf_real ay,
                            const imf_real az, const imf_real sign, const imf_real one_g,
                            const imf_real scale)
{
    /* Nair (2016): the third row of the rotation matrix of q, times a */
    const imf_real az_earth = (IMF_R(2.0) * q1 * q3 - IMF_R(2.0) * q0 * q2) * ax
                              + (IMF_R(2.0) * q2 * q3 + IMF_R(2.0) * q0 * q1) * ay
                              + (q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3) * az;
    return (sign * az_earth - one_g) * scale;
}
