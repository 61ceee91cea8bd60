/*
 * FusionOffset (Longbin's Fusion walkthrough, imufusion 1.2.3). See fusion_offset.h. Twin:
 * python/imufuse/reference/fusion.py (FusionOffset).
 */
#include "fusion_offset.h"

#define IMF_FUSION_OFFSET_CUTOFF IMF_R(0.02)   /* Hz */
#define IMF_FUSION_OFFSET_TIMEOUT 5u           /* s */
#define IMF_FUSION_OFFSET_THRESHOLD IMF_R(3.0) /* degrees per second */

void imf_fusion_offset_init(imf_fusion_offset_t *const self, const uint32_t sample_rate)
{
    /* 2 pi fc dt, dt = 1 / fs rounded once */
    self->set.filter_coefficient = IMF_R(2.0) * IMF_FUSION_PI * IMF_FUSION_OFFSET_CUTOFF
                                   * (IMF_R(1.0) / (imf_real)sample_rate);
    self->set.timeout = IMF_FUSION_OFFSET_TIMEOUT * sample_rate;
    self->skipped = 0;
    self->x.timer = 0;
    self->x.offset_x = IMF_R(0.0);
    self->x.offset_y = IMF_R(0.0);
    self->x.offset_z = IMF_R(0.0);
}

void imf_fusion_offset_update(imf_fusion_offset_t *const self, const imf_real *const g,
                              imf_real *const out)
{
    imf_fusion_offset_state_t *const x = &self->x;
    /* subtract the current offset estimate */
    const imf_real wx = g[0] - x->offset_x;
    const imf_real wy = g[1] - x->offset_y;
    const imf_real wz = g[2] - x->offset_z;
    out[0] = wx;
    out[1] = wy;
    out[2] = wz;
    if (!imf_finite3(g[0], g[1], g[2])) {
        self->skipped++;
        return;
    }
    /* moving: start the rest timer again */
    if (imf_fusion_fabs(wx) > IMF_FUSION_OFFSET_THRESHOLD
        || imf_fusion_fabs(wy) > IMF_FUSION_OFFSET_THRESHOLD
        || imf_fusion_fabs(wz) > IMF_FUSION_OFFSET_THRESHOLD) {
        x->timer = 0;
        return;
    }
    /* at rest, but not yet for the timeout */
    if (x->timer < self->set.timeout) {
        x->timer++;
        return;
    }
    /* at rest long enough: low-pass the offset towards the measurement */
    x->offset_x = x->offset_x + wx * self->set.filter_coefficient;
    x->offset_y = x->offset_y + wy * self->set.filter_coefficient;
    x->offset_z = x->offset_z + wz * self->set.filter_coefficient;
}

void imf_fusion_offset_get_state(const imf_fusion_offset_t *const self, imf_real *const out)
{
    out[0] = self->x.offset_x;
    out[1] = self->x.offset_y;
    out[2] = self->x.offset_z;
    out[3] = (imf_real)self->x.timer;
}

void imf_fusion_offset_set_state(imf_fusion_offset_t *const self, const imf_real *const in)
{
    self->x.offset_x = in[0];
    self->x.offset_y = in[1];
    self->x.offset_z = in[2];
    self->x.timer = (uint32_t)in[3];
}
