/*
 * Minimal firmware: feed recorded samples to an imufuse filter.
 *
 * The filter is the Mahony&Madgwick single-axis filter with a PI controller (article Eq. 3.6),
 * float32, 100 Hz: Kp = 2 /s, Ki = 0.3 /s^2. After every sample the program writes the state
 * (theta, I) as float32 bit patterns, then the number of skipped samples:
 *     "<theta hex> <I hex>\n" ... "skipped <n>\n" "end\n"
 * so a host build, an MCU build and the Python reference can be compared bit for bit.
 *
 * Only csrc/ is needed: filters_1d.c, filters_1d.h, imf_config.h, imf_math.h.
 */
#include <stdint.h>
#include <string.h>

#include "board.h"
#include "filters_1d.h"

/* The recorded samples live in flash; on AVR that needs PROGMEM and a copy out of it. */
#if defined(__AVR__)
#include <avr/pgmspace.h>
#define EXAMPLE_FLASH PROGMEM
#define EXAMPLE_READ(dst, src, n) memcpy_P((dst), (src), (n))
#else
#define EXAMPLE_FLASH
#define EXAMPLE_READ(dst, src, n) memcpy((dst), (src), (n))
#endif

#include "recorded_samples.h"

static void write_hex32(uint32_t v, char *out)
{
    static const char digits[] = "0123456789abcdef";
    int k;
    for (k = 7; k >= 0; --k) {
        out[k] = digits[v & 0xFu];
        v >>= 4;
    }
}

static void write_state(const imf_mahony1d_bias_t *f)
{
    char line[19];
    uint32_t bits;
    memcpy(&bits, &f->x.theta, sizeof bits);
    write_hex32(bits, line);
    line[8] = ' ';
    memcpy(&bits, &f->x.i, sizeof bits);
    write_hex32(bits, line + 9);
    line[17] = '\n';
    line[18] = '\0';
    board_write(line);
}

int main(void)
{
    static imf_mahony1d_bias_t filter;
    imf_mahony1d_bias_settings_t settings;
    char tail[20];
    uint32_t k;

    board_init();
    imf_mahony1d_bias_default_settings(&settings); /* Kp 2 1/s, Ki 0.3 1/s^2, Eq. 3.6 */
    settings.dt = RECORDED_DT;
    imf_mahony1d_bias_init(&filter, &settings);
    for (k = 0u; k < RECORDED_N; ++k) {
        float sample[2];
        EXAMPLE_READ(sample, recorded[k], sizeof sample);
        imf_mahony1d_bias_update(&filter, sample[0], sample[1]); /* rad/s, rad */
        write_state(&filter);
    }
    memcpy(tail, "skipped ", 8);
    write_hex32(filter.skipped, tail + 8);
    tail[16] = '\n';
    tail[17] = '\0';
    board_write(tail);
    board_write("end\n");
    board_done();
    return 0;
}
