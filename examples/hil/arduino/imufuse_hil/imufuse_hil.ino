/*
 * imufuse_hil: validate a filter on the board itself, from a PC:
 *
 *     imufuse validate ... --port /dev/ttyACM0 --baud 115200
 *
 * The filter here is the imufuse Arduino library's MadgwickAHRS (float32, its default
 * settings: dt 0.01 s, beta 0.1); put your own filter in the three adapter functions
 * (fw_init, fw_update, fw_state). Copy csrc/hil/imf_hil.c and csrc/hil/imf_hil.h of imufuse
 * next to this file (the sketch folder), install the imufuse library (imufuse export arduino).
 *
 * Boards: Arduino Uno (ATmega328P; Timer1 counts the update's cycles) and Arm boards (Cortex-M3,
 * M4, M7, M33: the DWT cycle counter; Cortex-M0 boards report no counter). The runner keeps
 * two samples in flight: their frames (44 bytes each here) must fit the core's receive
 * buffer while an update runs (64 bytes on the Uno: one frame waits while the other runs).
 */
#include <string.h>
#include <imufuse.h>
#include "imf_hil.h"

static imf_madgwick_t filt;
static const uint16_t types[4] = {IMF_HIL_T_F32, IMF_HIL_T_F32, IMF_HIL_T_F32, IMF_HIL_T_F32};

static void fw_init(void)
{
    imf_madgwick_settings_t s;
    imf_madgwick_default_settings(&s);
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

static int get_byte(void)
{
    return Serial.read(); /* -1 when none is waiting */
}

static void put_byte(uint8_t b)
{
    Serial.write(b);
}

#if defined(__AVR__)
/* Timer1 at clk/1 around the update (one overflow caught: up to 131071 cycles) */
static uint32_t count_begin(void)
{
    TCCR1A = 0;
    TCCR1B = 0;
    TCNT1 = 0;
    TIFR1 = _BV(TOV1);
    TCCR1B = _BV(CS10);
    return 0;
}

static uint32_t count_end(uint32_t start)
{
    const uint16_t t = TCNT1;
    const uint8_t ovf = TIFR1 & _BV(TOV1);
    TCCR1B = 0;
    (void)start;
    return (ovf && t < 0x8000u ? 65536UL : 0UL) + t;
}
#define COUNT_UNIT IMF_HIL_COUNT_CYCLES
#elif defined(__ARM_ARCH_7M__) || defined(__ARM_ARCH_7EM__) || defined(__ARM_ARCH_8M_MAIN__)
/* the DWT cycle counter of the Cortex-M3/M4/M7/M33 */
#define DEMCR_REG (*(volatile uint32_t *)0xE000EDFCu)
#define DWT_CTRL_REG (*(volatile uint32_t *)0xE0001000u)
#define DWT_CYCCNT_REG (*(volatile uint32_t *)0xE0001004u)
static uint32_t count_begin(void)
{
    return DWT_CYCCNT_REG;
}

static uint32_t count_end(uint32_t start)
{
    return DWT_CYCCNT_REG - start;
}
#define COUNT_UNIT IMF_HIL_COUNT_CYCLES
#define COUNTER_SETUP() (DEMCR_REG |= 1UL << 24, DWT_CYCCNT_REG = 0, DWT_CTRL_REG |= 1UL)
#else
#define count_begin NULL
#define count_end NULL
#define COUNT_UNIT IMF_HIL_COUNT_NONE
#endif
#ifndef COUNTER_SETUP
#define COUNTER_SETUP() ((void)0)
#endif

static const imf_hil_app_t app = {"MadgwickAHRS sketch", IMF_HIL_IN_F32, 9, 4, types, fw_init,
                                  NULL, fw_update, fw_state, get_byte, put_byte, count_begin,
                                  count_end, COUNT_UNIT};
static imf_hil_t hil;

void setup()
{
    Serial.begin(115200);
    while (!Serial) {
        /* boards with native USB: wait for the port to open */
    }
    COUNTER_SETUP();
    imf_hil_init(&hil, &app);
}

void loop()
{
    imf_hil_poll(&hil);
}
