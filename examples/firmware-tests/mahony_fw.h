/* Example fixed-point firmware (docs/firmware.md): imufuse's
 * MahonyIMUQ taken into a project the way firmware does it (a global filter, the sensor's
 * counts as six int16 arguments, constants computed once on a host and given as macros). */
#ifndef MAHONY_FW_H
#define MAHONY_FW_H
#include <stdint.h>
#include "mahony_q.h"

extern imf_mahony_imu_q_t att;

int att_init(void);
void att_update(int16_t gx, int16_t gy, int16_t gz, int16_t ax, int16_t ay, int16_t az);

#endif
