/* Cortex-M board: ARM semihosting (SYS_WRITE0, SYS_EXIT), shown by a debugger or by
 * qemu -semihosting. */
#include "board.h"

static int semihost(int op, const void *arg)
{
    register int r0 __asm__("r0") = op;
    register const void *r1 __asm__("r1") = arg;
    __asm__ volatile("bkpt 0xab" : "+r"(r0) : "r"(r1) : "memory");
    return r0;
}

void board_init(void) {}

void board_write(const char *zstr)
{
    (void)semihost(0x04, zstr); /* SYS_WRITE0 */
}

void board_done(void)
{
    (void)semihost(0x18, (const void *)0x20026); /* SYS_EXIT, ADP_Stopped_ApplicationExit */
    for (;;) {
    }
}
