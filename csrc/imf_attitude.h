/*
 * Initial attitude shared by every 3-D filter: from an accelerometer (and
 * magnetometer) reading at rest, from an average of such readings, or from a
 * given quaternion. The pure-Python twin is
 * python/imufuse/reference/attitude.py: the same lines in the same order.
 *
 * Frames (README.md, Conventions): the earth frame is NWU (x north, y west, z up); a level
 * sensor at rest reads acc = (0, 0, +1 g). The attitude rotates sensor to
 * earth, v_earth = R v_body, so the rows of R are the earth axes seen in the
 * sensor frame:
 *     r[0..2] = north,  r[3..5] = west,  r[6..8] = up.
 *
 * From a reading (TRIAD, no transcendental functions):
 *     up    = a / |a|
 *     west  = (up x m) / |up x m|    the horizontal part of the field, turned
 *                                    by 90 deg about up (m points north and down)
 *     north = west x up
 * Without a magnetometer (m all zero), or with a field along the vertical, the
 * heading is that of ZYX yaw = 0 (the sensor's x axis points north when
 * levelled): west = (up x e_x) / |up x e_x| = (0, up_z, -up_y) / |...|; with the
 * x axis vertical as well (pitch +-90 deg) west = e_y (ZYX roll 0).
 *
 * Each filter takes what its state holds (imf_<filter>_set_attitude): the
 * quaternion q, the matrix r, or the up vector r[6..8].
 */
#ifndef IMF_ATTITUDE_H
#define IMF_ATTITUDE_H

#include <stdint.h>
#include "imf_config.h"

#ifdef __cplusplus
extern "C" {
#endif

/* One attitude in both representations. */
typedef struct {
    imf_real q[4]; /* quaternion w, x, y, z, sensor -> earth, unit length */
    imf_real r[9]; /* rotation matrix sensor -> earth, row-major: north, west, up */
} imf_attitude_t;

/* Attitude from one accelerometer reading (any unit) and one magnetometer
   reading (any unit; all zero: none). From a reading q has w >= 0. Returns 1,
   or 0 (att unchanged) when the accelerometer is zero or not finite. */
int imf_attitude_from_acc_mag(imf_attitude_t *att, imf_real ax, imf_real ay, imf_real az,
                              imf_real mx, imf_real my, imf_real mz);

/* Attitude from a quaternion (w, x, y, z), normalised here. Returns 1, or 0
   (att unchanged) when it is zero or not finite. */
int imf_attitude_from_quat(imf_attitude_t *att, imf_real q0, imf_real q1, imf_real q2, imf_real q3);

/* Average of the first readings: the sums of the unit directions. */
typedef struct {
    imf_real ax, ay, az; /* sum of the unit accelerometer directions */
    imf_real mx, my, mz; /* sum of the unit magnetometer directions (non-zero readings) */
    uint32_t n;          /* readings summed */
    uint32_t window;     /* readings to sum (>= 1) */
} imf_attitude_window_t;

/* Start a window of `window` readings (0 counts as 1). */
void imf_attitude_window_init(imf_attitude_window_t *w, uint32_t window);

/* Add one reading (magnetometer all zero: none, or an IMU) and set att from
   the average so far. Returns 1 (att set), 0 (no accelerometer reading: all
   zero; nothing changed) or -1 (rejected: a non-finite input, or directions
   that cancel; nothing changed). The window is full when n == window. */
int imf_attitude_window_add(imf_attitude_window_t *w, imf_attitude_t *att, imf_real ax, imf_real ay,
                            imf_real az, imf_real mx, imf_real my, imf_real mz);

#ifdef __cplusplus
}
#endif

#endif /* IMF_ATTITUDE_H */
