#include "imk_int.h"

#if (-1 >> 1) != -1
#error "right shift of negative values must be arithmetic"
#endif

static int32_t imk_sat32(int64_t x)
{
    if (x > INT32_MAX) {
        return INT32_MAX;
    }
    if (x < INT32_MIN) {
        return INT32_MIN;
    }
    return (int32_t)x;
}

void imk_int_init(imk_int_t *const self)
{
    self->angle = 0;
    self->rate_i = 0;
    self->err = 0;
    self->mean = 0;
}

void imk_int_update(imk_int_t *const self, int16_t rate, int16_t angle)
{
    int64_t p;
    /* predict: angle += rate * dt with dt = 1/512 in Q16 -> multiply by 128 */
    p = (int64_t)self->angle + (int64_t)rate * 128 + (self->rate_i >> 10);
    self->angle = imk_sat32(p);
    /* correct */
    self->err = (int32_t)angle * 65536 / 4 - self->angle / 4;
    self->rate_i = imk_sat32((int64_t)self->rate_i + self->err / 3);
    p = (int64_t)self->err * 3277;
    self->angle = imk_sat32((int64_t)self->angle + p / 65536);
    /* running mean, Q8, truncating division */
    self->mean = self->mean + ((int32_t)rate * 256 - self->mean) / 16;
}
