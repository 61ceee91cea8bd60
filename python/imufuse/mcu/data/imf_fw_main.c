/* Driver of `imufuse validate --target`: a user's firmware on the emulated MCU, sample by
 * sample, in chunks of any number of samples.
 *
 *   imf_driver.h   (generated from the Firmware declaration) the user's headers, the filter
 *                  object, IMF_FW_ROW (input values per sample), imf_user_init(),
 *                  imf_user_load(const double *x) (the sample into the update's arguments),
 *                  imf_user_step() (the update call alone), imf_user_dump() (the state words)
 *                  and imf_fw_types[] (size and kind of every state word, in flash).
 *   imf_fw_block.c (generated) the block the host writes into the linked image before every
 *                  run: imf_fw_hdr (samples, resume flag, RAM image length, input kind), the
 *                  inputs, and the RAM image of the previous chunk.
 *
 * A chunk that resumes copies the saved image over .data and .bss instead of calling
 * imf_user_init(): the firmware's own variables, static or not, continue where the previous
 * chunk left them. At the end of a chunk the image is printed ("R <hex>"), written byte by byte
 * from the stack so that printing does not change what is printed.
 *
 * Output: text lines "T <type> ..." once, "K <hex>" the empty-call count; then one line per
 * sample, written out (flushed) before the next sample runs: 'S' and a binary record, the state
 * words' bit patterns (little-endian, 4 bytes, or 8 for a 64-bit word), the count (4 bytes) and
 * the sample's index modulo 256, escaped as imf_fw_put says (so the record holds no newline, NUL
 * or '.'); then "M <stack bytes> <painted band> <RAM image bytes> <deep>", "R <image>",
 * "IMF_END". A fault, exit or stack overflow starts a new line ("\nIMF_FAULT"): the records
 * before it are the samples that completed. A step that writes the guard band above the
 * static data prints "IMF_STACK_OVERFLOW". */
#include <stdint.h>
#include <string.h>
#include "imf_port.h"
#include "imf_out.h"
#if defined(__AVR__)
#include <avr/io.h>
#include <avr/pgmspace.h>
#define IMF_FLASH PROGMEM
#define IMF_RD8(p) pgm_read_byte(p)
#define IMF_RD32(p) pgm_read_dword(p)
#else
#define IMF_FLASH
#define IMF_RD8(p) (*(const volatile uint8_t *)(p))
#define IMF_RD32(p) (*(const volatile uint32_t *)(p))
#endif

/* imf_fw_hdr: magic, samples in this chunk, resume (0/1), RAM image bytes, input kind
 * (1 float, 2 double, 3 int16_t, 4 int32_t), values per sample, near band bytes (0: the whole
 * band painted before every step; see main). */
extern const uint32_t imf_fw_hdr[7] IMF_FLASH;
extern const uint8_t imf_fw_in[] IMF_FLASH;
extern const uint8_t imf_fw_ram[] IMF_FLASH;
extern char __data_start[], __bss_end[], __heap_start[];

#define IMF_FW_TYPE(e)                                                                  \
    ((uint32_t)sizeof(e) | (__builtin_classify_type(e) != 8 ? 0x100u : 0u) |             \
     ((__typeof__(e))-1 < (__typeof__(e))0 ? 0x200u : 0u) |                             \
     (__builtin_types_compatible_p(__typeof__(e), double) ? 0x400u : 0u))

/* Binary records. Every byte goes out as itself, except the bytes the emulators' text channels
 * do not carry (below 0x20: NUL ends a semihosting string, simavr shows control characters as
 * '.') and the two the framing uses ('.' and '~'): those as '~' and the byte plus 0x40. */
#define IMF_FW_ESC 0x7Eu

static void imf_fw_put(uint8_t b)
{
    if (b < 0x20u || b == (uint8_t)'.' || b == IMF_FW_ESC) {
        imf_out_char((char)IMF_FW_ESC);
        b = (uint8_t)(b + 0x40u);
    }
    imf_out_char((char)b);
}

/* a 32-bit word, little-endian */
static void imf_fw_put32(uint32_t v)
{
    imf_fw_put((uint8_t)v);
    imf_fw_put((uint8_t)(v >> 8));
    imf_fw_put((uint8_t)(v >> 16));
    imf_fw_put((uint8_t)(v >> 24));
}

static __inline__ void imf_fw_out64(uint32_t hi, uint32_t lo)
{
    imf_fw_put32(lo);
    imf_fw_put32(hi);
}

static __inline__ void imf_fw_out_u64(unsigned long long v)
{
    imf_fw_out64((uint32_t)(v >> 32), (uint32_t)v);
}

static __inline__ void imf_fw_out_double(double v)
{
    unsigned long long b = 0u;
    memcpy(&b, &v, sizeof v);
    imf_fw_out_u64(b);
}

static __inline__ void imf_fw_out_f32(float v)
{
    uint32_t b;
    memcpy(&b, &v, sizeof b);
    imf_fw_put32(b);
}

/* Every state word as its bit pattern: floats of 4 bytes as f32, of 8 as f64, integers
 * widened to 32 bits (64 when wider). */
#define IMF_FW_DUMP(e)                                                                  \
    do {                                                                                \
        if (__builtin_classify_type(e) != 8) {                                          \
            if (sizeof(e) > 4u) {                                                       \
                imf_fw_out_u64((unsigned long long)(e));                                \
            } else if ((IMF_FW_TYPE(e) & 0x200u) != 0u) {                               \
                imf_fw_put32((uint32_t)(int32_t)(e));                                   \
            } else {                                                                    \
                imf_fw_put32((uint32_t)(e));                                            \
            }                                                                           \
        } else if (sizeof(e) == 4u) {                                                   \
            float imf_t_ = (float)(e);                                                  \
            imf_fw_out_f32(imf_t_);                                                     \
        } else {                                                                        \
            double imf_t_ = (double)(e);                                                \
            imf_fw_out_double(imf_t_);                                                  \
        }                                                                               \
    } while (0)

extern const uint32_t imf_fw_types[] IMF_FLASH;
#include "imf_driver.h"

#if defined(__GNUC__)
#define IMF_NOINLINE __attribute__((noinline))
#else
#define IMF_NOINLINE
#endif

static IMF_NOINLINE void imf_step(void)
{
    imf_user_step();
}

static IMF_NOINLINE void imf_step_empty(void)
{
    __asm__ volatile("" ::: "memory");
}

/* exit() of the firmware, named in the output, then the emulation ends: newlib's and picolibc's exit() call
 * _exit (ARM); avr-libc's would end in a loop with interrupts off, so exit itself is replaced. */
#if defined(__arm__) || defined(__riscv) || defined(__AVR__)
static void imf_fw_exit(int status)
{
    imf_port_write("\nIMF_EXIT ");
    imf_out_i32((int32_t)status);
    imf_out_char('\n');
    imf_out_flush();
    imf_port_exit(1);
    for (;;) {
    }
}
#endif
#if defined(__arm__) || defined(__riscv)
void _exit(int status);
void _exit(int status)
{
    imf_fw_exit(status);
}
#elif defined(__AVR__)
void exit(int status) __attribute__((noreturn));
void exit(int status)
{
    imf_fw_exit(status);
    for (;;) {
    }
}
#endif

#if defined(__AVR__)
/* Set once main has run: a jump to the reset vector (a NULL function pointer) starts main again
 * with it set, since .noinit survives the C start-up; simavr's RAM starts zeroed. */
static uint16_t imf_fw_booted __attribute__((section(".noinit")));
#endif

static double imf_fw_x[IMF_FW_ROW];

static void imf_fw_load(uint32_t i, uint32_t kind, uint32_t row)
{
    uint32_t j;
    uint8_t w[8];
    const uint32_t size = kind == 2u ? 8u : kind == 3u ? 2u : 4u;
    for (j = 0u; j < row; ++j) {
        uint32_t b;
        const uint8_t *src = &imf_fw_in[(i * row + j) * size];
        for (b = 0u; b < size; ++b) {
            w[b] = IMF_RD8(src + b);
        }
        if (kind == 1u) {
            float v;
            memcpy(&v, w, sizeof v);
            imf_fw_x[j] = (double)v;
        } else if (kind == 2u && sizeof(double) == 8u) {
            double v;
            memcpy(&v, w, sizeof v);
            imf_fw_x[j] = v;
        } else if (kind == 3u) {
            int16_t v;
            memcpy(&v, w, sizeof v);
            imf_fw_x[j] = (double)v;
        } else {
            int32_t v;
            memcpy(&v, w, sizeof v);
            imf_fw_x[j] = (double)v;
        }
    }
    imf_user_load(imf_fw_x);
}

/* Stack: the band below the stack pointer is painted before every step and read after it;
 * a guard band just above the static data is painted once and must stay intact. */
#define IMF_FW_PAINT 0xA5u
#define IMF_FW_GUARD 16u
#if defined(__AVR__)
#define IMF_FW_WINDOW 1024u
#else
#define IMF_FW_WINDOW 8192u
#endif

static __inline__ uintptr_t imf_fw_sp(void)
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

/* Painting and reading the band: the 32-bit cores write and compare a word (four cells) at a
 * time, the AVR eight bytes per loop; the lowest changed byte is found exactly as byte by byte
 * (a word is skipped only when all four of its bytes still hold the paint). */
#define IMF_FW_PAINT32 0xA5A5A5A5u
/* Both run inside main's frame (inlined): a call's own frame would lie in the band it paints. */
#if defined(__GNUC__)
#define IMF_FW_INLINE __inline__ __attribute__((always_inline))
#else
#define IMF_FW_INLINE
#endif

static IMF_FW_INLINE void imf_fw_paint(uintptr_t lo, uintptr_t hi)
{
    volatile uint8_t *p = (volatile uint8_t *)lo;
#if defined(__AVR__)
    uint16_t n8 = (uint16_t)((hi - lo) >> 3);
    if (hi > lo && n8 != 0u) {
        /* st X+: two cycles a byte */
        uint8_t *x = (uint8_t *)lo;
        __asm__ volatile("1: st X+, %[v]\n\tst X+, %[v]\n\tst X+, %[v]\n\tst X+, %[v]\n\t"
                         "st X+, %[v]\n\tst X+, %[v]\n\tst X+, %[v]\n\tst X+, %[v]\n\t"
                         "sbiw %[n], 1\n\tbrne 1b"
                         : "+x"(x), [n] "+w"(n8)
                         : [v] "r"((uint8_t)IMF_FW_PAINT)
                         : "memory", "cc");
        p = x;
    }
#else
    volatile uint32_t *w;
    while (((uintptr_t)p & 3u) != 0u && (uintptr_t)p < hi) {
        *p++ = IMF_FW_PAINT;
    }
    w = (volatile uint32_t *)p;
    while ((uintptr_t)w + 16u <= hi) {
        w[0] = IMF_FW_PAINT32;
        w[1] = IMF_FW_PAINT32;
        w[2] = IMF_FW_PAINT32;
        w[3] = IMF_FW_PAINT32;
        w += 4;
    }
    while ((uintptr_t)w + 4u <= hi) {
        *w++ = IMF_FW_PAINT32;
    }
    p = (volatile uint8_t *)w;
#endif
    while ((uintptr_t)p < hi) {
        *p++ = IMF_FW_PAINT;
    }
}

static IMF_FW_INLINE uint32_t imf_fw_depth(uintptr_t sp, uintptr_t lo)
{
    volatile const uint8_t *p = (volatile const uint8_t *)lo;
#if defined(__AVR__)
    uint16_t n8 = (uint16_t)((sp - lo) >> 3);
    if (sp > lo && n8 != 0u) {
        /* eight bytes compared as one number (cpi, then cpc keeps Z only while equal); a group
         * with a changed byte is stepped back over and read byte by byte below */
        const uint8_t *x = (const uint8_t *)lo;
        uint8_t t;
        __asm__ volatile("1: ld %[t], X+\n\tcpi %[t], 0xA5\n\t"
                         "ld %[t], X+\n\tcpc %[t], %[v]\n\tld %[t], X+\n\tcpc %[t], %[v]\n\t"
                         "ld %[t], X+\n\tcpc %[t], %[v]\n\tld %[t], X+\n\tcpc %[t], %[v]\n\t"
                         "ld %[t], X+\n\tcpc %[t], %[v]\n\tld %[t], X+\n\tcpc %[t], %[v]\n\t"
                         "ld %[t], X+\n\tcpc %[t], %[v]\n\t"
                         "brne 2f\n\tsbiw %[n], 1\n\tbrne 1b\n\trjmp 3f\n"
                         "2: sbiw r26, 8\n"
                         "3:"
                         : "+x"(x), [n] "+w"(n8), [t] "=&d"(t)
                         : [v] "r"((uint8_t)IMF_FW_PAINT)
                         : "memory", "cc");
        p = x;
    }
#else
    while (((uintptr_t)p & 3u) != 0u && (uintptr_t)p < sp && *p == IMF_FW_PAINT) {
        ++p;
    }
    if (((uintptr_t)p & 3u) == 0u) {
        volatile const uint32_t *w = (volatile const uint32_t *)p;
        while ((uintptr_t)w + 16u <= sp &&
               ((w[0] ^ IMF_FW_PAINT32) | (w[1] ^ IMF_FW_PAINT32) | (w[2] ^ IMF_FW_PAINT32) |
                (w[3] ^ IMF_FW_PAINT32)) == 0u) {
            w += 4;
        }
        while ((uintptr_t)w + 4u <= sp && *w == IMF_FW_PAINT32) {
            ++w;
        }
        p = (volatile const uint8_t *)w;
    }
#endif
    while ((uintptr_t)p < sp && *p == IMF_FW_PAINT) {
        ++p;
    }
    return (uint32_t)(sp - (uintptr_t)p);
}

static int imf_fw_guard_ok(void)
{
    volatile const uint8_t *p = (volatile const uint8_t *)__heap_start;
    uint32_t k;
    for (k = 0u; k < IMF_FW_GUARD; ++k) {
        if (p[k] != IMF_FW_PAINT) {
            return 0;
        }
    }
    return 1;
}

/* The RAM image, printed without touching .data/.bss: the line is built on the stack. */
static IMF_NOINLINE void imf_fw_print_image(uint32_t len)
{
    static const char digits[] = "0123456789abcdef";
    char line[2 * 32 + 1];
    const volatile uint8_t *p = (const volatile uint8_t *)__data_start;
    uint32_t k = 0u;
    imf_port_write("R ");
    while (k < len) {
        uint32_t m = 0u;
        while (m < 32u && k < len) {
            const uint8_t b = p[k++];
            line[2u * m] = digits[b >> 4];
            line[2u * m + 1u] = digits[b & 0xFu];
            ++m;
        }
        line[2u * m] = '\0';
        imf_port_write(line);
    }
    imf_port_write("\n");
}

int main(void)
{
    const uint32_t n = IMF_RD32(&imf_fw_hdr[1]);
    const uint32_t resume = IMF_RD32(&imf_fw_hdr[2]);
    const uint32_t image = IMF_RD32(&imf_fw_hdr[3]);
    const uint32_t kind = IMF_RD32(&imf_fw_hdr[4]);
    const uint32_t row = IMF_RD32(&imf_fw_hdr[5]);
    const uint32_t near = IMF_RD32(&imf_fw_hdr[6]);
    const uint32_t ram = (uint32_t)(__bss_end - __data_start);
    uint32_t i;
    uint32_t t0;
    uint32_t count;
    uintptr_t sp;
    uintptr_t lo;
    uintptr_t mid;
    uint32_t deep = 0u;
    uint32_t depth_empty;
    uint32_t depth;
    uint32_t depth_max = 0u;

#if defined(__AVR__)
    if (imf_fw_booted == 0xB007u) {
        imf_port_init();
        imf_port_write("\nIMF_RESET\n");
        imf_port_exit(1);
    }
    imf_fw_booted = 0xB007u;
#endif
    if (resume != 0u) {
        /* the firmware's RAM as the previous chunk left it (before any output) */
        volatile uint8_t *dst = (volatile uint8_t *)__data_start;
        uint32_t k;
        for (k = 0u; k < image && k < ram; ++k) {
            dst[k] = IMF_RD8(&imf_fw_ram[k]);
        }
    }
    imf_port_init();
    if (resume == 0u) {
        imf_user_init();
    }
    imf_port_write("\nT");
    for (i = 0u; i < (uint32_t)(sizeof imf_fw_types / sizeof imf_fw_types[0]); ++i) {
        imf_out_u32(IMF_RD32(&imf_fw_types[i]));
    }
    imf_out_char('\n');
    imf_out_flush();

    t0 = imf_port_count_begin();
    imf_step_empty();
    count = imf_port_count_end(t0);
    imf_port_write("K");
    imf_out_u32(count);
    imf_out_char('\n');
    imf_out_flush();

    sp = imf_fw_sp();
    lo = (uintptr_t)__heap_start + IMF_FW_GUARD;
    if (sp - lo > IMF_FW_WINDOW) {
        lo = sp - IMF_FW_WINDOW;
    }
    imf_fw_paint((uintptr_t)__heap_start, (uintptr_t)__heap_start + IMF_FW_GUARD);
    imf_fw_paint(lo, sp);
    imf_step_empty();
    depth_empty = imf_fw_depth(sp, lo);
    /* With a near band (the host's choice), only [mid, sp) is painted and read around every
     * step: [lo, mid) keeps its paint from above unless something reaches below mid. A step whose
     * lowest changed byte is mid itself, or a byte below mid found changed at the end, makes
     * the chunk "deep" (M's fourth word) and the host runs it again with the whole band painted
     * before every step; otherwise every step found [lo, sp) painted, as it would have been. */
    mid = (near != 0u && sp - lo > near) ? sp - near : lo;

    for (i = 0u; i < n; ++i) {
        imf_fw_load(i, kind, row);
        imf_fw_paint(mid, sp);
        t0 = imf_port_count_begin();
        imf_step();
        count = imf_port_count_end(t0);
        depth = imf_fw_depth(sp, mid);
        if (mid != lo && depth >= (uint32_t)(sp - mid)) {
            deep = 1u;
        }
        if (depth > depth_max) {
            depth_max = depth;
        }
        if (!imf_fw_guard_ok()) {
            imf_port_write("\nIMF_STACK_OVERFLOW\n");
            imf_port_exit(1);
        }
        imf_out_char('S');
        imf_user_dump();
        imf_fw_put32(count);
        imf_fw_put((uint8_t)i);
        imf_out_char('\n');
        imf_out_flush();
    }
    if (mid != lo && imf_fw_depth(mid, lo) != 0u) {
        deep = 1u;
    }
    imf_port_write("M");
    imf_out_u32(depth_max - depth_empty);
    imf_out_u32((uint32_t)(sp - lo));
    imf_out_u32(ram);
    imf_out_u32(deep);
    imf_out_char('\n');
    imf_out_flush();
    imf_fw_print_image(ram);
    imf_port_write("IMF_END\n");
    imf_port_exit(0);
    return 0;
}
