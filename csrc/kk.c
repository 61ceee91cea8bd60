/*
 * "KK" linear small-angle filter, appendix / Eq. 4.5. See kk.h. The
 * pure-Python twin is python/imufuse/reference/kk.py.
 */
#include <stddef.h>
#include "kk.h"
#include "imf_math.h"

/* The filter begins with its settings' two members, of the same types in the same order
   (checked here). init copies them (the twin's _init sets them one by one): on AVR as one
   block, a loop shorter than its 8-bit loads and stores member by member; elsewhere
   member by member, in aligned words (a block copy through pointers of unknown alignment
   is bytewise on RV32). The same values either way. */
typedef char imf_kk_head_is_its_settings[offsetof(imf_kk_t, kp) == offsetof(imf_kk_settings_t, kp)
                                                 && sizeof(imf_kk_settings_t)
                                                        == offsetof(imf_kk_t, kp) + sizeof(imf_real)
                                             ? 1
                                             : -1];

void imf_kk_default_settings(imf_kk_settings_t *const settings)
{
    settings->dt = IMF_R(0.01);
    settings->kp = IMF_R(0.01);
}

void imf_kk_init(imf_kk_t *const self, const imf_kk_settings_t *const s)
{
#if defined(__AVR__)
    memcpy(self, s, sizeof *s);
#else
    self->dt = s->dt;
    self->kp = s->kp;
#endif
    self->skipped = 0;
    self->x.pitch = IMF_R(0.0);
    self->x.roll = IMF_R(0.0);
}

void imf_kk_set_dt(imf_kk_t *const self, const imf_real dt)
{
    self->dt = dt;
}

void imf_kk_set_attitude(imf_kk_t *const self, const imf_attitude_t *const att)
{
    self->x.pitch = -att->r[6];
    self->x.roll = att->r[7];
}

void imf_kk_angles(const imf_kk_t *const self, double *const roll, double *const pitch)
{
    *roll = (double)self->x.roll;
    *pitch = (double)self->x.pitch;
}

void imf_kk_update(imf_kk_t *const self, const imf_real gx, const imf_real gy, const imf_real gz,
                   const imf_real ax, const imf_real ay, const imf_real az)
{
    imf_real n2, norm, pitch, roll;
    if (!(imf_finite3(gx, gy, gz) && imf_finite3(ax, ay, az))) {
        self->skipped++;
        return;
    }
    /* Eq. 4.5, gyro path: (w_pitch + theta_roll w_yaw) dt with w_yaw = -w_z */
    pitch = self->x.pitch + (gy - self->x.roll * gz) * self->dt;
    roll = self->x.roll + (gx + self->x.pitch * gz) * self->dt;
    n2 = ax * ax + ay * ay + az * az;
    if (n2 > IMF_R(0.0) && isfinite(n2)) {
        /* small-angle accelerometer angles, a_pitch = -a_x/|a|, a_roll = a_y/|a|;
           P controller Kp (a - theta_{n-1}) */
        norm = imf_sqrt(n2);
        pitch = pitch + self->kp * (-ax / norm - self->x.pitch);
        roll = roll + self->kp * (ay / norm - self->x.roll);
    }
    if (!imf_finite2(pitch, roll)) {
        self->skipped++;
        return;
    }
    self->x.pitch = pitch;
    self->x.roll = roll;
}
