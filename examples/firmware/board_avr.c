/* ATmega328P board: polled UART0 (16 MHz, double speed, 2 Mbaud); ends asleep with
 * interrupts off (simavr then stops). */
#include <stdint.h>
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>
#include "board.h"

void board_init(void)
{
    UCSR0A = (uint8_t)(1u << U2X0);
    UBRR0H = 0u;
    UBRR0L = 0u;
    UCSR0C = (uint8_t)((1u << UCSZ01) | (1u << UCSZ00));
    UCSR0B = (uint8_t)(1u << TXEN0);
}

void board_write(const char *zstr)
{
    while (*zstr != '\0') {
        while ((UCSR0A & (1u << UDRE0)) == 0u) {
        }
        UDR0 = (uint8_t)*zstr++;
    }
}

void board_done(void)
{
    while ((UCSR0A & (1u << UDRE0)) == 0u) {
    }
    cli();
    set_sleep_mode(SLEEP_MODE_PWR_DOWN);
    sleep_enable();
    for (;;) {
        sleep_cpu();
    }
}
