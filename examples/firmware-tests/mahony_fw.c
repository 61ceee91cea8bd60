#include "mahony_fw.h"

imf_mahony_imu_q_t att;

int att_init(void)
{
    const imf_qscale_t kg = {FW_KG_M, FW_KG_S};
    const imf_qscale_t kp = {FW_KP_M, FW_KP_S};
    const imf_qscale_t ki = {FW_KI_M, FW_KI_S};
    return imf_mahony_imu_q_init_consts(&att, kg, kp, ki, 32);
}

void att_update(int16_t gx, int16_t gy, int16_t gz, int16_t ax, int16_t ay, int16_t az)
{
    const int16_t g[3] = {gx, gy, gz};
    const int16_t a[3] = {ax, ay, az};
    imf_mahony_imu_q_update_v(&att, g, a);
}
