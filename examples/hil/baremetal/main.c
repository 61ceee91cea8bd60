/* HIL example: your filter behind the imufuse HIL runner. The three adapter functions are all
 * the runner needs from a firmware: init, update (one sample), state (the words to compare). */
#include <string.h>

#include "board.h"
#include "imf_hil.h"

#if defined(HIL_ROBUST_AHRS_Q)
#include "robust_q.h"

static imf_robust_ahrs_q_t filt;
/* every word of RobustAHRSQ's state: 89 int32 (with B6's, whether its code is compiled in or
   not); IMF_HIL_MAX_STATE (CMakeLists.txt) must hold them */
#define HIL_STATE_BYTES sizeof(imf_robust_ahrs_q_state_t)
#define HIL_N_STATE (HIL_STATE_BYTES / sizeof(int32_t))
typedef char hil_state_fits_the_runner[HIL_STATE_BYTES <= IMF_HIL_MAX_STATE ? 1 : -1];
static uint16_t types[HIL_N_STATE];

static void fw_types(void)
{
    uint8_t j;
    for (j = 0u; j < (uint8_t)HIL_N_STATE; ++j) {
        types[j] = IMF_HIL_T_I32;
    }
}

static void fw_init(void)
{
    imf_robust_ahrs_q_settings_t s;
    imf_robust_ahrs_q_default_settings(&s);
    (void)imf_robust_ahrs_q_init(&filt, &s);
}

static void fw_update(const void *in)
{
    const int16_t *x = (const int16_t *)in; /* gyr, acc, mag: int16 counts */
    imf_robust_ahrs_q_update_v(&filt, x, x + 3, x + 6);
}

static uint16_t fw_state(uint8_t *out)
{
    memcpy(out, &filt.x, sizeof filt.x); /* all 89 words, in RobustAHRSQ's state order */
    return (uint16_t)sizeof filt.x;
}
#define HIL_NAME "example RobustAHRSQ"
#define HIL_IN IMF_HIL_IN_I16
#else
#include "madgwick.h"

static imf_madgwick_t filt;
static const uint16_t types[4] = { IMF_HIL_T_F32, IMF_HIL_T_F32, IMF_HIL_T_F32, IMF_HIL_T_F32 };
#define HIL_STATE_BYTES sizeof filt.x
#define HIL_N_STATE 4u

static void fw_types(void)
{
}

static void fw_init(void)
{
    imf_madgwick_settings_t s;
    imf_madgwick_default_settings(&s); /* dt 0.01 s, beta 0.1 */
    imf_madgwick_init(&filt, &s);
}

static void fw_update(const void *in)
{
    const float *x = (const float *)in; /* gyr rad/s, acc, mag */
    imf_madgwick_update(&filt, x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7], x[8]);
}

static uint16_t fw_state(uint8_t *out)
{
    memcpy(out, &filt.x, sizeof filt.x); /* q0..q3 */
    return (uint16_t)sizeof filt.x;
}
#define HIL_NAME "example MadgwickAHRS"
#define HIL_IN IMF_HIL_IN_F32
#endif

#if defined(HIL_RUNNER)
static imf_hil_app_t app = { HIL_NAME,
                             HIL_IN,
                             9u,
                             (uint8_t)HIL_N_STATE,
                             types,
                             fw_init,
                             NULL,
                             fw_update,
                             fw_state,
                             board_get,
                             board_put,
                             board_count_begin,
                             board_count_end,
                             IMF_HIL_COUNT_CYCLES };
static imf_hil_t hil;

int main(void)
{
    board_init();
    fw_types();
    app.count_unit = board_count_unit();
    if (app.count_unit == IMF_HIL_COUNT_NONE) {
        app.count_begin = NULL; /* no counter on this board: the host is told so */
    }
    imf_hil_init(&hil, &app);
    for (;;) {
        (void)imf_hil_poll(&hil);
    }
}
#else
/* The filter alone, on samples from the UART: what the firmware costs without the runner. */
int main(void)
{
    uint8_t in[9u * 4u];
    uint8_t st[HIL_STATE_BYTES];
    uint8_t k = 0u;
    board_init();
    fw_init();
    for (;;) {
        const int c = board_get();
        if (c >= 0) {
            in[k++] = (uint8_t)c;
            if (k == (uint8_t)sizeof in) {
                k = 0u;
                fw_update(in);
                board_put(fw_state(st) == 0u ? 0u : st[0]);
            }
        }
        (void)types;
        (void)fw_types;
    }
}
#endif
