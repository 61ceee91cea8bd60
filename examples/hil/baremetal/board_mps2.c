/* MPS2 board (Cortex-M4F, mps2-an386; QEMU emulates it): CMSDK UART0 and the DWT cycle
 * counter. A core or emulator without a running CYCCNT (QEMU's) reports no counter. */
#include "board.h"
#include "imf_hil.h"

#define UART0_DATA (*(volatile uint32_t *)0x40004000u)
#define UART0_STATE (*(volatile uint32_t *)0x40004004u)
#define UART0_CTRL (*(volatile uint32_t *)0x40004008u)
#define UART0_BAUDDIV (*(volatile uint32_t *)0x40004010u)
#define DEMCR (*(volatile uint32_t *)0xE000EDFCu)
#define DWT_CTRL (*(volatile uint32_t *)0xE0001000u)
#define DWT_CYCCNT (*(volatile uint32_t *)0xE0001004u)
#define CORE_CLOCK 25000000u

static uint8_t count_unit;

void board_init(void)
{
    uint32_t c0;
    volatile uint32_t spin;
    UART0_BAUDDIV = CORE_CLOCK / HIL_BAUD;
    UART0_CTRL = 3u; /* transmit and receive */
    DEMCR |= 1u << 24; /* TRCENA */
    DWT_CYCCNT = 0u;
    DWT_CTRL |= 1u; /* CYCCNTENA */
    c0 = DWT_CYCCNT;
    for (spin = 0u; spin < 100u; ++spin) {
    }
    count_unit = DWT_CYCCNT != c0 ? IMF_HIL_COUNT_CYCLES : IMF_HIL_COUNT_NONE;
}

int board_get(void)
{
    return (UART0_STATE & 2u) != 0u ? (int)(UART0_DATA & 0xFFu) : -1;
}

void board_put(uint8_t b)
{
    while ((UART0_STATE & 1u) != 0u) {
    }
    UART0_DATA = b;
}

uint32_t board_count_begin(void)
{
    return DWT_CYCCNT;
}

uint32_t board_count_end(uint32_t start)
{
    return DWT_CYCCNT - start;
}

uint8_t board_count_unit(void)
{
    return count_unit;
}
