/* ATmega328P at 16 MHz: USART0 (polled: the bytes of a window wait in the UART and in the
 * host's repeats) and Timer1 at clk/1 as the cycle counter (one overflow is caught: updates
 * up to 131071 cycles). */
#include <avr/io.h>

#include "board.h"
#include "imf_hil.h"

void board_init(void)
{
    const uint16_t ubrr = (uint16_t)((F_CPU / 8UL + HIL_BAUD / 2UL) / HIL_BAUD - 1UL);
    UCSR0A = (uint8_t)(1u << U2X0);
    UBRR0H = (uint8_t)(ubrr >> 8);
    UBRR0L = (uint8_t)ubrr;
    UCSR0C = (uint8_t)((1u << UCSZ01) | (1u << UCSZ00));
    UCSR0B = (uint8_t)((1u << TXEN0) | (1u << RXEN0));
    TCCR1A = 0u;
}

int board_get(void)
{
    return (UCSR0A & (1u << RXC0)) != 0u ? (int)UDR0 : -1;
}

void board_put(uint8_t b)
{
    while ((UCSR0A & (1u << UDRE0)) == 0u) {
    }
    UDR0 = b;
}

uint32_t board_count_begin(void)
{
    TCCR1B = 0u;
    TCNT1 = 0u;
    TIFR1 = (uint8_t)(1u << TOV1);
    TCCR1B = (uint8_t)(1u << CS10);
    return 0u;
}

uint32_t board_count_end(uint32_t start)
{
    const uint16_t t = TCNT1;
    const uint8_t ovf = (uint8_t)(TIFR1 & (1u << TOV1));
    TCCR1B = 0u;
    (void)start;
    return (ovf != 0u && t < 0x8000u ? 65536UL : 0UL) + t;
}

uint8_t board_count_unit(void)
{
    return IMF_HIL_COUNT_CYCLES;
}
