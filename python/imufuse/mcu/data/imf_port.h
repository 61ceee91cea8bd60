/* Port layer of the imufuse MCU harness: what the generated driver needs from a target.
 * Implementations: arm_startup.c (qemu Cortex-M machines, semihosting), riscv_port.c (qemu
 * virt RV32, semihosting), avr_port.c (simavr, UART0), host_port.c (a normal process). */
#ifndef IMF_PORT_H
#define IMF_PORT_H

#include <stdint.h>

/* Bring up output (UART) and the cycle/instruction counter. */
void imf_port_init(void);
/* Write a zero-terminated string to the harness output. */
void imf_port_write(const char *zstr);
/* End the program; status 0 is success. Never returns. */
#if defined(__GNUC__)
__attribute__((noreturn))
#endif
void imf_port_exit(int status);

/* Elapsed-count measurement around one call, in target units:
 *   avr : CPU cycles (Timer1 at clk/1 plus an overflow count)
 *   Cortex-M : instructions (SysTick under qemu -icount; 0 without -icount)
 *   RV32 : instructions (mcycle under qemu -icount: the virtual clock, 2**shift per instruction)
 *   host : 0 (use callgrind instead)
 * imf_port_count_begin() returns an opaque start value for imf_port_count_end(). */
uint32_t imf_port_count_begin(void);
uint32_t imf_port_count_end(uint32_t start);

#endif
