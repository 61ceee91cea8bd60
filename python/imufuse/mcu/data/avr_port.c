/* ATmega328P port of the imufuse MCU harness for simavr: polled UART0 output and a
 * Timer1 (clk/1) cycle counter extended to 32 bits by an overflow interrupt. */
#include <stdint.h>
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>
#include "imf_port.h"

static volatile uint16_t imf_t1_overflows;

ISR(TIMER1_OVF_vect)
{
    imf_t1_overflows++;
}

void imf_port_init(void)
{
    /* UART0 at the fastest rate (U2X, UBRR 0: F_CPU/8); simavr times bytes by the baud rate. */
    UCSR0A = (uint8_t)(1u << U2X0);
    UBRR0H = 0u;
    UBRR0L = 0u;
    UCSR0C = (uint8_t)((1u << UCSZ01) | (1u << UCSZ00));
    UCSR0B = (uint8_t)(1u << TXEN0);
    TCCR1A = 0u;
    TCCR1B = 0u;
    TIMSK1 = (uint8_t)(1u << TOIE1);
    sei();
}

void imf_port_write(const char *zstr)
{
    while (*zstr != '\0') {
        while ((UCSR0A & (1u << UDRE0)) == 0u) {
        }
        UDR0 = (uint8_t)*zstr++;
    }
}

void imf_port_exit(int status)
{
    /* Wait for the transmitter to drain, then sleep with interrupts off: simavr stops. */
    while ((UCSR0A & (1u << UDRE0)) == 0u) {
    }
    (void)status;
    cli();
    set_sleep_mode(SLEEP_MODE_PWR_DOWN);
    sleep_enable();
    for (;;) {
        sleep_cpu();
    }
}

/* The counter runs only between begin and end: begin clears it and starts Timer1 at clk/1,
 * end stops it and adds 65536 for every overflow, including one still pending. The
 * overflow interrupt's own cycles are included in the count; the harness knows their
 * number (IMF_AVR_OVF_ISR_CYCLES in the Python side) and subtracts them. */
uint32_t imf_port_count_begin(void)
{
    TCCR1B = 0u;
    TCNT1 = 0u;
    TIFR1 = (uint8_t)(1u << TOV1);
    imf_t1_overflows = 0u;
    TCCR1B = (uint8_t)(1u << CS10);
    return 0u;
}

uint32_t imf_port_count_end(uint32_t start)
{
    uint16_t ticks;
    uint32_t ovf;
    uint8_t pending;
    cli();
    ticks = TCNT1;
    pending = (uint8_t)(TIFR1 & (1u << TOV1));
    TCCR1B = 0u;
    ovf = imf_t1_overflows;
    /* An overflow still pending belongs to this count only if it came before the read. */
    if (pending != 0u && ticks < 0x8000u) {
        ovf++;
    }
    TIFR1 = (uint8_t)(1u << TOV1);
    sei();
    (void)start;
    return (ovf << 16) + ticks;
}
