/* Integer test kernel of the MCU harness (not a filter of the library): int16 counts in,
 * int32 state, with 64-bit products, truncating division, arithmetic shifts and saturation. */
#ifndef IMK_INT_H
#define IMK_INT_H

#include <stdint.h>

typedef struct {
    int32_t angle;    /* Q16 angle, counts of the accelerometer angle scale */
    int32_t rate_i;   /* integral of the error, saturated */
    int32_t err;      /* last error */
    int32_t mean;     /* running mean of the rate input, Q8 */
} imk_int_t;

void imk_int_init(imk_int_t *const self);

/* rate: gyro counts; angle: accelerometer angle counts. */
void imk_int_update(imk_int_t *const self, int16_t rate, int16_t angle);

#endif
