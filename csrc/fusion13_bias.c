/*
 * FusionBias (x-io Fusion 1.3, imufusion 1.3.3). See fusion13_bias.h. The pure-Python twin is
 * FusionBias in python/imufuse/reference/fusion13.py: the same lines in the same order.
 */
#include "fusion13_bias.h"

/* Cutoff frequency of the bias filter, Hz. */
#define IMF_FUSION13_BIAS_CUTOFF IMF_R(0.02)

void imf_fusion13_bias_default_settings(imf_fusion13_bias_settings_t *const settings)
{
    settings->sample_rate = IMF_R(100.0);
    settings->stationary_threshold = IMF_R(3.0);
    settings->stationary_period = IMF_R(3.0);
}

void imf_fusion13_bias_set_settings(imf_fusion13_bias_t *const self,
                                    const imf_fusion13_bias_settings_t *const settings)
{
    self->set.stationary_threshold = settings->stationary_threshold;
    /* 2 pi fc T, left to right */
    self->set.filter_coefficient = IMF_R(2.0) * IMF_FUSION_PI * IMF_FUSION13_BIAS_CUTOFF
                                   * (IMF_R(1.0) / settings->sample_rate);
    self->set.timeout = (uint32_t)(settings->stationary_period * settings->sample_rate);
}

void imf_fusion13_bias_init(imf_fusion13_bias_t *const self,
                            const imf_fusion13_bias_settings_t *const settings)
{
    imf_fusion13_bias_settings_t defaults;
    imf_fusion13_bias_default_settings(&defaults);
    imf_fusion13_bias_set_settings(self, settings != NULL ? settings : &defaults);
    self->skipped = 0;
    self->x.timer = 0;
    self->x.offset_x = IMF_R(0.0);
    self->x.offset_y = IMF_R(0.0);
    self->x.offset_z = IMF_R(0.0);
}

void imf_fusion13_bias_update(imf_fusion13_bias_t *const self, const imf_real *const g,
                              imf_real *const out)
{
    imf_fusion13_bias_state_t *const x = &self->x;
    const imf_real threshold = self->set.stationary_threshold;
    imf_real cx, cy, cz;
    if (!imf_finite3(g[0], g[1], g[2])) {
        self->skipped++;
        out[0] = g[0];
        out[1] = g[1];
        out[2] = g[2];
        return;
    }
    /* corrected gyroscope */
    cx = g[0] - x->offset_x;
    cy = g[1] - x->offset_y;
    cz = g[2] - x->offset_z;
    out[0] = cx;
    out[1] = cy;
    out[2] = cz;
    /* moving: the stationary timer starts again */
    if (imf_fusion_fabs(cx) > threshold || imf_fusion_fabs(cy) > threshold
        || imf_fusion_fabs(cz) > threshold) {
        x->timer = 0;
        return;
    }
    if (x->timer < self->set.timeout) {
        x->timer++;
        return;
    }
    /* stationary long enough: the offset follows the corrected gyroscope */
    x->offset_x = x->offset_x + cx * self->set.filter_coefficient;
    x->offset_y = x->offset_y + cy * self->set.filter_coefficient;
    x->offset_z = x->offset_z + cz * self->set.filter_coefficient;
}

void imf_fusion13_bias_get_state(const imf_fusion13_bias_t *const self, imf_real *const out)
{
    out[0] = self->x.offset_x;
    out[1] = self->x.offset_y;
    out[2] = self->x.offset_z;
    out[3] = (imf_real)self->x.timer;
}

void imf_fusion13_bias_set_state(imf_fusion13_bias_t *const self, const imf_real *const in)
{
    self->x.offset_x = in[0];
    self->x.offset_y = in[1];
    self->x.offset_z = in[2];
    self->x.timer = (uint32_t)in[3];
}
