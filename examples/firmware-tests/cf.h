/* Example firmware (docs/firmware.md, test_cf_firmware.py): Eq. 2.2 written the way
 * firmware usually writes it, with its own names and a sample counter of its own. */
#ifndef CF_H
#define CF_H
#include <stdint.h>

typedef struct {
    float theta;  /* angle, rad */
    float alpha;  /* weight of the gyro path */
    float oma;    /* 1 - alpha */
    float dt;     /* s */
    uint32_t n;   /* samples seen */
} cf_t;

void cf_init(cf_t *s, float dt, float alpha);
void cf_update(cf_t *s, float rate, float angle);

#endif
