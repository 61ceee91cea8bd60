/* Test kernel of the MCU harness (not a filter of the library): float32 quaternion
 * integration with an accelerometer correction, using sqrtf and division. */
#ifndef IMK_QUAT_H
#define IMK_QUAT_H

typedef struct {
    float q[4];   /* attitude quaternion [w, x, y, z] */
    float e[3];   /* last correction term, rad/s */
    float anorm;  /* last accelerometer norm, input units */
    float dt;     /* sample period, s */
    float kp;     /* correction gain, 1/s */
} imk_quat_t;

/* dt: sample period in seconds; kp: proportional gain in 1/s. */
void imk_quat_init(imk_quat_t *const self, float dt, float kp);

/* gyr: rad/s; acc: any unit (normalised here). */
void imk_quat_update(imk_quat_t *const self, const float gyr[3], const float acc[3]);

#endif
