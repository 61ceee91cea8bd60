/* Generic driver of the imufuse MCU harness. It is the same on every target:
 *   imf_inputs.h  (generated) IMF_N samples as constant arrays in flash, one global "row"
 *                 variable per input named like the input, and imf_load_row(i);
 *   imf_driver.h  the driver: file-scope declarations plus three functions
 *                 imf_user_init(), imf_user_step(), imf_user_dump() (generated from a
 *                 Python Driver, or written by hand).
 * For every sample it loads the row, runs imf_user_step() between two counter reads and prints
 *   "S <word> <word> ... c<count>\n"
 * with every state word as a hex bit pattern. imf_user_dump() uses imf_out_f32() and friends. */
#include <stdint.h>
#include <string.h>
#include "imf_port.h"
#include "imf_inputs.h"

#if defined(__GNUC__)
#define IMF_NOINLINE __attribute__((noinline))
#else
#define IMF_NOINLINE
#endif

/* Output is collected in a small line buffer (2 KB RAM on AVR) and written in pieces. */
#define IMF_OUT_CAP 64
static char imf_out_buf[IMF_OUT_CAP + 1];
static uint8_t imf_out_len;

static void imf_out_flush(void)
{
    imf_out_buf[imf_out_len] = '\0';
    imf_port_write(imf_out_buf);
    imf_out_len = 0u;
}

static void imf_out_char(char c)
{
    if (imf_out_len >= IMF_OUT_CAP) {
        imf_out_flush();
    }
    imf_out_buf[imf_out_len++] = c;
}

static void imf_out_hex(uint32_t v, uint8_t ndigits)
{
    static const char digits[] = "0123456789abcdef";
    while (ndigits > 0u) {
        ndigits--;
        imf_out_char(digits[(v >> (4u * ndigits)) & 0xFu]);
    }
}

/* State dumpers for imf_user_dump(): every word is printed as its bit pattern. Integers narrower
 * than 32 bits are widened (sign-extended when signed) to 32 bits first. */
static inline void imf_out_u32(uint32_t v)
{
    imf_out_char(' ');
    imf_out_hex(v, 8u);
}

static inline void imf_out_i32(int32_t v)
{
    imf_out_u32((uint32_t)v);
}

static inline void imf_out_f32(float v)
{
    uint32_t bits;
    memcpy(&bits, &v, sizeof bits);
    imf_out_u32(bits);
}

#if IMF_HAVE_F64
static inline void imf_out_f64(double v)
{
    uint32_t w[2];
    uint64_t bits;
    memcpy(&bits, &v, sizeof bits);
    w[0] = (uint32_t)(bits >> 32);
    w[1] = (uint32_t)bits;
    imf_out_char(' ');
    imf_out_hex(w[0], 8u);
    imf_out_hex(w[1], 8u);
}
#endif

/* Widening dumpers for narrower integers. */
static inline void imf_out_i16(int16_t v)
{
    imf_out_i32((int32_t)v);
}

static inline void imf_out_u16(uint16_t v)
{
    imf_out_u32((uint32_t)v);
}

static inline void imf_out_i8(int8_t v)
{
    imf_out_i32((int32_t)v);
}

static inline void imf_out_u8(uint8_t v)
{
    imf_out_u32((uint32_t)v);
}

#include "imf_driver.h"

static IMF_NOINLINE void imf_step(void)
{
    imf_user_step();
}

static IMF_NOINLINE void imf_step_empty(void)
{
    __asm__ volatile("" ::: "memory");
}

int main(void)
{
    uint32_t i;
    uint32_t t0;
    uint32_t count;

    imf_port_init();
    imf_user_init();

    /* Cost of the measurement itself: the harness subtracts it from every count. */
    t0 = imf_port_count_begin();
    imf_step_empty();
    count = imf_port_count_end(t0);
    imf_port_write("K");
    imf_out_u32(count);
    imf_out_char('\n');
    imf_out_flush();

    for (i = 0u; i < (uint32_t)IMF_N; ++i) {
        imf_load_row(i);
        t0 = imf_port_count_begin();
        imf_step();
        count = imf_port_count_end(t0);
        imf_out_char('S');
        imf_user_dump();
        imf_out_char(' ');
        imf_out_char('c');
        imf_out_hex(count, 8u);
        imf_out_char('\n');
        imf_out_flush();
    }
    imf_port_write("IMF_END\n");
    imf_port_exit(0);
    return 0;
}
