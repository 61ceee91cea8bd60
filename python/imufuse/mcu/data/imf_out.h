/* Output helpers of the imufuse MCU harness drivers (imf_driver_main.c, imf_fw_main.c):
 * a small line buffer written through the port, hex words, and the state dumpers. Include
 * after imf_port.h. */
#ifndef IMF_OUT_H
#define IMF_OUT_H

#include <stdint.h>
#include <string.h>
#include "imf_port.h"

#ifndef IMF_HAVE_F64
#if defined(__AVR__)
#define IMF_HAVE_F64 0 /* double is 32 bits */
#else
#define IMF_HAVE_F64 1
#endif
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
static __inline__ void imf_out_u32(uint32_t v)
{
    imf_out_char(' ');
    imf_out_hex(v, 8u);
}

static __inline__ void imf_out_i32(int32_t v)
{
    imf_out_u32((uint32_t)v);
}

static __inline__ void imf_out_f32(float v)
{
    uint32_t bits;
    memcpy(&bits, &v, sizeof bits);
    imf_out_u32(bits);
}

#if IMF_HAVE_F64
static __inline__ void imf_out_f64(double v)
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
static __inline__ void imf_out_i16(int16_t v)
{
    imf_out_i32((int32_t)v);
}

static __inline__ void imf_out_u16(uint16_t v)
{
    imf_out_u32((uint32_t)v);
}

static __inline__ void imf_out_i8(int8_t v)
{
    imf_out_i32((int32_t)v);
}

static __inline__ void imf_out_u8(uint8_t v)
{
    imf_out_u32((uint32_t)v);
}

#endif
