/* The HIL runner on the emulated boards of imufuse's tests and benchmarks (QEMU mps2 boards'
 * CMSDK UART0, simavr's ATmega328P USART0): the program `validate --target` builds, with the
 * runner in place of its driver's init. Included by the driver imufuse.firmware.hil_board
 * generates, after the firmware's generated driver (imf_hil_fw_init, imf_user_load,
 * imf_user_step, imf_user_dump through IMF_FW_DUMP into imf_hil_out, imf_fw_types,
 * IMF_FW_ROW), with IMF_HIL_NAME, IMF_HIL_IN_KIND, IMF_HIL_BAUD and the count conversion
 * defined. Counts come from the harness port (imf_port.h: SysTick under qemu -icount, converted
 * to instructions here; Timer1 cycles on AVR, less the overflow interrupt's).
 *
 * Fault for the tests: IMF_HIL_RESET_AT k restarts the board before sample k (a jump to the
 * reset handler, as a watchdog or a brown-out would). */
#include "imf_hil.h"
#include "imf_hil.c"

#if defined(__AVR__)
#include <avr/io.h>

static void imf_hil_uart_init(void)
{
    const uint16_t ubrr = (uint16_t)((F_CPU / 8UL + IMF_HIL_BAUD / 2UL) / IMF_HIL_BAUD - 1UL);
    UCSR0A = (uint8_t)(1u << U2X0);
    UBRR0H = (uint8_t)(ubrr >> 8);
    UBRR0L = (uint8_t)ubrr;
    UCSR0C = (uint8_t)((1u << UCSZ01) | (1u << UCSZ00));
    UCSR0B = (uint8_t)((1u << TXEN0) | (1u << RXEN0));
}

static int imf_hil_get(void)
{
    if ((UCSR0A & (1u << RXC0)) == 0u) {
        return -1;
    }
    return (int)UDR0;
}

static void imf_hil_put(uint8_t b)
{
    while ((UCSR0A & (1u << UDRE0)) == 0u) {
    }
    UDR0 = b;
}

static uint32_t imf_hil_count_end(uint32_t start)
{
    const uint32_t c = imf_port_count_end(start);
    return c - (c >> 16) * (uint32_t)IMF_HIL_OVF_CYCLES;
}
#define IMF_HIL_UNIT IMF_HIL_COUNT_CYCLES
#else
/* CMSDK APB UART0 of the mps2 boards */
#define IMF_HIL_UART_DATA (*(volatile uint32_t *)0x40004000u)
#define IMF_HIL_UART_STATE (*(volatile uint32_t *)0x40004004u)
#define IMF_HIL_UART_CTRL (*(volatile uint32_t *)0x40004008u)
#define IMF_HIL_UART_BAUDDIV (*(volatile uint32_t *)0x40004010u)

static void imf_hil_uart_init(void)
{
    IMF_HIL_UART_BAUDDIV = (uint32_t)(IMF_HIL_CLOCK / IMF_HIL_BAUD);
    IMF_HIL_UART_CTRL = 3u; /* transmit and receive */
}

static int imf_hil_get(void)
{
    if ((IMF_HIL_UART_STATE & 2u) == 0u) {
        return -1;
    }
    return (int)(IMF_HIL_UART_DATA & 0xFFu);
}

static void imf_hil_put(uint8_t b)
{
    while ((IMF_HIL_UART_STATE & 1u) != 0u) {
    }
    IMF_HIL_UART_DATA = b;
}

/* SysTick ticks under qemu -icount, as instructions (IMF_HIL_TICKS_NUM / _DEN per tick) */
static uint32_t imf_hil_count_end(uint32_t start)
{
    const uint32_t t = imf_port_count_end(start);
    return (uint32_t)(((uint64_t)t * IMF_HIL_TICKS_NUM + IMF_HIL_TICKS_DEN / 2u)
                      / IMF_HIL_TICKS_DEN);
}
#define IMF_HIL_UNIT IMF_HIL_COUNT_INSTRUCTIONS
#endif

static uint16_t imf_hil_types[sizeof imf_fw_types / sizeof imf_fw_types[0]];
static uint16_t imf_hil_samples;

static void imf_hil_load(const void *in)
{
    double x[IMF_FW_ROW];
    uint8_t j;
    for (j = 0u; j < (uint8_t)IMF_FW_ROW; ++j) {
#if IMF_HIL_IN_KIND == 1
        x[j] = (double)((const float *)in)[j];
#elif IMF_HIL_IN_KIND == 2
        x[j] = ((const double *)in)[j];
#elif IMF_HIL_IN_KIND == 3
        x[j] = (double)((const int16_t *)in)[j];
#else
        x[j] = (double)((const int32_t *)in)[j];
#endif
    }
#if defined(IMF_HIL_RESET_AT)
    if (imf_hil_samples == (uint16_t)(IMF_HIL_RESET_AT)) {
#if defined(__AVR__)
        {
            /* the harness's boot mark lives in .noinit: a restart, not a second boot */
            extern char __noinit_start[], __noinit_end[];
            char *p;
            for (p = __noinit_start; p < __noinit_end; ++p) {
                *p = 0;
            }
        }
        __asm__ volatile("jmp 0");
#else
        *(volatile uint32_t *)0xE000ED0Cu = 0x05FA0004u; /* AIRCR: SYSRESETREQ */
        for (;;) {
        }
#endif
    }
#endif
    imf_hil_samples++;
    imf_user_load(x);
}

static void imf_hil_update(const void *in)
{
    (void)in;
    imf_user_step();
}

static void imf_hil_init_fw(void)
{
    imf_hil_samples = 0u;
    imf_hil_fw_init();
}

static uint16_t imf_hil_state(uint8_t *out)
{
    imf_hil_out = out;
    imf_user_dump();
    return (uint16_t)(imf_hil_out - out);
}

static const imf_hil_app_t imf_hil_app = {
    IMF_HIL_NAME,      IMF_HIL_IN_KIND,
    IMF_FW_ROW,        (uint8_t)(sizeof imf_fw_types / sizeof imf_fw_types[0]),
    imf_hil_types,     imf_hil_init_fw,
    imf_hil_load,      imf_hil_update,
    imf_hil_state,     imf_hil_get,
    imf_hil_put,       imf_port_count_begin,
    imf_hil_count_end, IMF_HIL_UNIT
};

static imf_hil_t imf_hil;

/* the driver's init: the runner, forever */
static void imf_user_init(void)
{
    uint8_t j;
    for (j = 0u; j < (uint8_t)(sizeof imf_hil_types / sizeof imf_hil_types[0]); ++j) {
        imf_hil_types[j] = (uint16_t)IMF_RD32(&imf_fw_types[j]);
    }
    imf_hil_uart_init();
    imf_hil_init(&imf_hil, &imf_hil_app);
    for (;;) {
        (void)imf_hil_poll(&imf_hil);
    }
}
