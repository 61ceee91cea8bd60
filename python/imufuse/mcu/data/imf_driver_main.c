/* Generic driver of the imufuse MCU harness. It is the same on every target:
 *   imf_inputs.h  (generated) IMF_N samples as constant arrays in flash, one global "row"
 *                 variable per input named like the input, and imf_load_row(i);
 *   imf_driver.h  the driver: file-scope declarations plus three functions
 *                 imf_user_init(), imf_user_step(), imf_user_dump() (generated from a
 *                 Python Driver, or written by hand).
 * For every sample it loads the row, runs imf_user_step() between two counter reads and prints
 *   "S <word> <word> ... c<count>\n"
 * with every state word as a hex bit pattern. imf_user_dump() uses imf_out_f32() and friends. */
#include <stdint.h>
#include <string.h>
#include "imf_port.h"
#include "imf_inputs.h"
#if defined(__AVR__)
#include <avr/io.h>
#endif

#if defined(__GNUC__)
#define IMF_NOINLINE __attribute__((noinline))
#else
#define IMF_NOINLINE
#endif

#include "imf_out.h"

#include "imf_driver.h"

static IMF_NOINLINE void imf_step(void)
{
    imf_user_step();
}

static IMF_NOINLINE void imf_step_empty(void)
{
    __asm__ volatile("" ::: "memory");
}

/* Stack measurement: before a call, the free stack below the stack pointer is filled with a
 * pattern; after it, the lowest changed byte gives the depth the call reached. The port
 * reports the current stack pointer and the lowest usable address (__heap_start: the end of
 * .bss on both ARM and AVR). IMF_STACK_WINDOW bounds the painted band. */
#if defined(__AVR__) || defined(__arm__) || defined(__riscv)
#define IMF_HAVE_STACK 1
#ifndef IMF_STACK_WINDOW
#if defined(__AVR__)
#define IMF_STACK_WINDOW 768u
#else
#define IMF_STACK_WINDOW 4096u
#endif
#endif
#define IMF_STACK_PAINT 0xA5u
extern char __heap_start[];

static inline uintptr_t imf_sp(void)
{
#if defined(__AVR__)
    return (uintptr_t)SP;
#elif defined(__riscv)
    uintptr_t sp;
    __asm__ volatile("mv %0, sp" : "=r"(sp));
    return sp;
#else
    uintptr_t sp;
    __asm__ volatile("mov %0, sp" : "=r"(sp));
    return sp;
#endif
}

static inline uintptr_t imf_stack_low(uintptr_t sp)
{
    uintptr_t lo = (uintptr_t)__heap_start;
    if (sp - lo > IMF_STACK_WINDOW) {
        lo = sp - IMF_STACK_WINDOW;
    }
    return lo;
}

/* The caller paints [lo, sp), calls, and asks how deep the call went. */
#define IMF_STACK_PAINT_BELOW(sp, lo)                                                   \
    do {                                                                                \
        volatile uint8_t *p_ = (volatile uint8_t *)(lo);                                \
        while ((uintptr_t)p_ < (sp)) {                                                  \
            *p_++ = IMF_STACK_PAINT;                                                    \
        }                                                                               \
    } while (0)

static uint32_t imf_stack_depth(uintptr_t sp, uintptr_t lo)
{
    volatile const uint8_t *p = (volatile const uint8_t *)lo;
    while ((uintptr_t)p < sp && *p == IMF_STACK_PAINT) {
        ++p;
    }
    return (uint32_t)(sp - (uintptr_t)p);
}
#else
#define IMF_HAVE_STACK 0
#endif

int main(void)
{
    uint32_t i;
    uint32_t t0;
    uint32_t count;
#if IMF_HAVE_STACK
    uintptr_t sp;
    uintptr_t lo;
    uint32_t depth_empty;
    uint32_t depth;
    uint32_t depth_max = 0u;
#endif

    imf_port_init();
    imf_user_init();

    /* Cost of the measurement itself: the harness subtracts it from every count. */
    t0 = imf_port_count_begin();
    imf_step_empty();
    count = imf_port_count_end(t0);
    imf_port_write("K");
    imf_out_u32(count);
    imf_out_char('\n');
    imf_out_flush();
#if IMF_HAVE_STACK
    sp = imf_sp();
    lo = imf_stack_low(sp);
    IMF_STACK_PAINT_BELOW(sp, lo);
    imf_step_empty();
    depth_empty = imf_stack_depth(sp, lo);
#endif

    for (i = 0u; i < (uint32_t)IMF_N; ++i) {
        imf_load_row(i);
#if IMF_HAVE_STACK
        sp = imf_sp();
        IMF_STACK_PAINT_BELOW(sp, lo);
#endif
        t0 = imf_port_count_begin();
        imf_step();
        count = imf_port_count_end(t0);
#if IMF_HAVE_STACK
        depth = imf_stack_depth(sp, lo);
        if (depth > depth_max) {
            depth_max = depth;
        }
#endif
        imf_out_char('S');
        imf_user_dump();
        imf_out_char(' ');
        imf_out_char('c');
        imf_out_hex(count, 8u);
        imf_out_char('\n');
        imf_out_flush();
    }
#if IMF_HAVE_STACK
    /* Bytes of stack the step used beyond an empty call, and the painted band. */
    imf_port_write("M");
    imf_out_u32(depth_max - depth_empty);
    imf_out_u32((uint32_t)(sp - lo));
    imf_out_char('\n');
    imf_out_flush();
#endif
    imf_port_write("IMF_END\n");
    imf_port_exit(0);
    return 0;
}
