/* RV32 port of the imufuse MCU harness for qemu's virt board (-bios none): start-up, output
 * through semihosting (SYS_WRITE0, a line buffer at a time, as on the Cortex-M machines: the
 * board's NS16550 UART costs qemu two device accesses and a host write per character, ten
 * times the run), the end of the emulation through the SiFive test device at 0x100000, and
 * the instruction counter.
 * Reset sets the stack, tp (the thread-local block of picolibc's errno) and the trap vector,
 * turns the FPU on when the build uses one (mstatus.FS), copies .data and .tdata, clears .tbss
 * and .bss, runs the constructors, then main(). A trap (an illegal instruction, a misaligned
 * or faulting access) prints IMF_FAULT and ends the run. */
#include <stdint.h>
#include "imf_port.h"

extern uint32_t __data_load[], __data_start[], __data_end[];
extern uint32_t __bss_start[], __bss_end[];
typedef void (*imf_init_t)(void);
extern imf_init_t __init_array_start[], __init_array_end[];
extern int main(void);

void imf_reset_handler(void);
void imf_c_start(void);
void imf_trap_handler(void);

__asm__(".section .imf_reset, \"ax\", @progbits\n"
        ".globl imf_reset_handler\n"
        "imf_reset_handler:\n"
        ".option push\n"
        ".option norelax\n"
        ".option arch, +zicsr\n"
        "    la sp, __stack_top\n"
        "    la tp, __tls_base\n"
        "    la t0, imf_trap_handler\n"
        "    csrw mtvec, t0\n"
#if defined(__riscv_flen)
        "    li t0, 0x2000\n" /* mstatus.FS = Initial: floating-point instructions allowed */
        "    csrs mstatus, t0\n"
        "    csrw fcsr, zero\n"
#endif
        "    j imf_c_start\n"
        ".option pop\n"
        ".text\n");

#define IMF_TEST_DEV (*(volatile uint32_t *)0x00100000u)

/* RISC-V semihosting (the Arm operations: a0 the operation, a1 its argument), entered by the
 * three uncompressed instructions slli/ebreak/srai within one page (aligned: qemu reads all
 * three); qemu runs with -semihosting-config enable=on,target=native (emulators.py) */
__attribute__((noinline)) static uintptr_t imf_semihost(uintptr_t op, const void *arg)
{
    register uintptr_t a0 __asm__("a0") = op;
    register const void *a1 __asm__("a1") = arg;
    __asm__ volatile(".option push\n"
                     ".option norvc\n"
                     ".balign 16\n"
                     "slli zero, zero, 0x1f\n"
                     "ebreak\n"
                     "srai zero, zero, 0x7\n"
                     ".option pop\n"
                     : "+r"(a0)
                     : "r"(a1)
                     : "memory");
    return a0;
}

void imf_port_write(const char *zstr)
{
    (void)imf_semihost(0x04u, zstr); /* SYS_WRITE0 */
}

void imf_port_exit(int status)
{
    /* SiFive test device: 0x5555 ends qemu with status 0, (code << 16) | 0x3333 with code */
    for (;;) {
        IMF_TEST_DEV = status == 0 ? 0x5555u : ((1u << 16) | 0x3333u);
    }
}

void imf_port_init(void)
{
}

/* mcycle: under qemu -icount it reads the virtual clock, which advances 2**shift ns per
 * instruction (the harness divides); without -icount it reads the host's clock. */
uint32_t imf_port_count_begin(void)
{
    uint32_t c;
    __asm__ volatile(".option push\n.option arch, +zicsr\ncsrr %0, mcycle\n.option pop" : "=r"(c)::"memory");
    return c;
}

uint32_t imf_port_count_end(uint32_t start)
{
    uint32_t c;
    __asm__ volatile(".option push\n.option arch, +zicsr\ncsrr %0, mcycle\n.option pop" : "=r"(c)::"memory");
    return c - start;
}

__attribute__((aligned(4), noreturn)) void imf_trap_handler(void)
{
    imf_port_write("\nIMF_FAULT\n");
    imf_port_exit(1);
}

void imf_c_start(void)
{
    uint32_t *src = __data_load;
    uint32_t *dst = __data_start;
    imf_init_t *f;
    while (dst < __data_end) {
        *dst++ = *src++;
    }
    for (dst = __bss_start; dst < __bss_end; ++dst) {
        *dst = 0u;
    }
    for (f = __init_array_start; f < __init_array_end; ++f) {
        (*f)();
    }
    imf_port_exit(main());
}
