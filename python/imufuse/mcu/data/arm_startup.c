/* Minimal Cortex-M start-up for the imufuse MCU harness (qemu mps2-an386 and microbit).
 * The initial stack pointer is the first word of the vector table; the linker script
 * places it in front of imf_vectors. Reset copies .data, clears .bss, enables the FPU
 * when the build uses one, runs main() and ends the emulation through semihosting. */
#include <stdint.h>
#include "imf_port.h"

extern uint32_t __data_load[], __data_start[], __data_end[];
extern uint32_t __bss_start[], __bss_end[];
/* constructors (C++ static objects, C __attribute__((constructor))): the linker script's
 * .init_array, run after .data and .bss are set up and before main */
typedef void (*imf_init_t)(void);
extern imf_init_t __init_array_start[], __init_array_end[];
extern int main(void);

typedef void (*imf_vector_t)(void);

void imf_reset_handler(void);
static void imf_fault_handler(void);

/* Semihosting: BKPT 0xAB, operation in r0, parameter in r1, result in r0. */
static int imf_semihost(int op, const void *arg)
{
    register int r0 __asm__("r0") = op;
    register const void *r1 __asm__("r1") = arg;
    __asm__ volatile("bkpt 0xab" : "+r"(r0) : "r"(r1) : "memory");
    return r0;
}

#define IMF_SYS_WRITE0 0x04
#define IMF_SYS_EXIT 0x18
#define IMF_ADP_APPLICATION_EXIT 0x20026
#define IMF_ADP_RUNTIME_ERROR 0x20023

void imf_port_write(const char *zstr)
{
    (void)imf_semihost(IMF_SYS_WRITE0, zstr);
}

void imf_port_exit(int status)
{
    /* 32-bit semihosting passes only the reason: qemu exits 0 for ApplicationExit, 1 otherwise. */
    uintptr_t reason = status == 0 ? IMF_ADP_APPLICATION_EXIT : IMF_ADP_RUNTIME_ERROR;
    for (;;) {
        (void)imf_semihost(IMF_SYS_EXIT, (const void *)reason);
    }
}

/* SysTick: under qemu -icount the core clock advances a fixed time per instruction, so the
 * down-counter gives instruction counts (see imf_port.h). */
#define IMF_SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define IMF_SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define IMF_SYST_CVR (*(volatile uint32_t *)0xE000E018u)

void imf_port_init(void)
{
    IMF_SYST_CSR = 0u;
    IMF_SYST_RVR = 0x00FFFFFFu;
    IMF_SYST_CVR = 0u;
    IMF_SYST_CSR = 5u; /* enable, processor clock, no interrupt */
}

uint32_t imf_port_count_begin(void)
{
    return IMF_SYST_CVR;
}

/* SysTick counts down through 24 bits; the harness converts ticks to instructions. */
uint32_t imf_port_count_end(uint32_t start)
{
    uint32_t now = IMF_SYST_CVR;
    return (start - now) & 0x00FFFFFFu;
}

static void imf_fault_handler(void)
{
    imf_port_write("\nIMF_FAULT\n");
    imf_port_exit(1);
}

void imf_reset_handler(void)
{
    uint32_t *src = __data_load;
    uint32_t *dst = __data_start;
    while (dst < __data_end) {
        *dst++ = *src++;
    }
    for (dst = __bss_start; dst < __bss_end; ++dst) {
        *dst = 0u;
    }
#if defined(__ARM_FP)
    /* CPACR: full access to CP10 and CP11 before the first FPU instruction. */
    *(volatile uint32_t *)0xE000ED88u |= 0xFu << 20;
    __asm__ volatile("dsb\n\tisb" ::: "memory");
#endif
    {
        imf_init_t *f;
        for (f = __init_array_start; f < __init_array_end; ++f) {
            (*f)();
        }
    }
    imf_port_exit(main());
}

/* Entries 1..15 of the vector table; entry 0 (initial SP) comes from the linker script. */
__attribute__((section(".imf_vectors"), used)) const imf_vector_t imf_vectors[15] = {
    imf_reset_handler, imf_fault_handler, imf_fault_handler, imf_fault_handler,
    imf_fault_handler, imf_fault_handler, 0, 0, 0, 0,
    imf_fault_handler, imf_fault_handler, 0, imf_fault_handler, imf_fault_handler,
};
