/* The board of the HIL example: a UART and a counter (board_mps2.c, board_avr.c). */
#ifndef BOARD_H
#define BOARD_H

#include <stdint.h>

/* Bring up the UART at HIL_BAUD and the counter. */
void board_init(void);
/* A received byte 0..255, or -1 when none is waiting. */
int board_get(void);
/* Send one byte (waits while the transmitter is full). */
void board_put(uint8_t b);
/* Counts around one update: begin returns a start value, end the counts since. */
uint32_t board_count_begin(void);
uint32_t board_count_end(uint32_t start);
/* IMF_HIL_COUNT_CYCLES, or IMF_HIL_COUNT_NONE where the board has no cycle counter. */
uint8_t board_count_unit(void);

#endif
