/* imufuse hardware-in-the-loop runner (see imf_hil.h for the protocol). */
#include "imf_hil.h"

#include <stddef.h>
#include <string.h>

#if defined(__GNUC__)
#define IMF_HIL_NOINLINE __attribute__((noinline))
#else
#define IMF_HIL_NOINLINE
#endif

/* The stack pointer, where the compiler lets us read it; elsewhere no stack figure. */
#if defined(__GNUC__) && IMF_HIL_STACK_BAND > 0u \
    && (defined(__arm__) || defined(__AVR__) || defined(__riscv))
#define IMF_HIL_HAVE_SP 1
#if defined(__AVR__)
#include <avr/io.h>
#define IMF_HIL_READ_SP(v) ((v) = (uintptr_t)SP)
#elif defined(__riscv)
#define IMF_HIL_READ_SP(v) __asm__ volatile("mv %0, sp" : "=r"(v))
#else
#define IMF_HIL_READ_SP(v) __asm__ volatile("mov %0, sp" : "=r"(v))
#endif
#else
#define IMF_HIL_HAVE_SP 0
#endif

#define IMF_HIL_PAINT 0xA5u
#define IMF_HIL_NO_STACK 0xFFFFu

enum { IMF_HIL_NAK_CORRUPT = 1, IMF_HIL_NAK_ORDER = 2, IMF_HIL_NAK_IDLE = 3, IMF_HIL_NAK_SIZE = 4 };

uint16_t imf_hil_crc16(uint16_t crc, const uint8_t *data, uint16_t n)
{
    uint16_t i;
    for (i = 0u; i < n; ++i) {
        uint8_t bit;
        crc = (uint16_t)(crc ^ (uint16_t)((uint16_t)data[i] << 8));
        for (bit = 0u; bit < 8u; ++bit) {
            crc = (crc & 0x8000u) != 0u ? (uint16_t)((uint16_t)(crc << 1) ^ 0x1021u)
                                        : (uint16_t)(crc << 1);
        }
    }
    return crc;
}

/* The name's characters sent in the hello (24 at most). */
static uint16_t imf_hil_name_len(const imf_hil_app_t *const app)
{
    uint16_t n = 0u;
    while (app->name != NULL && n < 24u && app->name[n] != '\0') {
        ++n;
    }
    return n;
}

/* Byte i of the hello frame, made as it is sent (no buffer): type 'h', sequence 0, version,
 * boot flag, window, input kind, inputs, state words, count unit, one type byte a word
 * (size | 0x10 integer | 0x20 signed | 0x40 declared double), the name, then crc. */
static uint8_t imf_hil_hello_byte(const imf_hil_app_t *const app, uint8_t boot, uint16_t crc,
                                  uint16_t i)
{
    uint16_t name;
    switch (i) {
    case 0u:
        return (uint8_t)'h';
    case 1u:
    case 2u:
        return 0u;
    case 3u:
        return (uint8_t)IMF_HIL_VERSION;
    case 4u:
        return boot;
    case 5u:
        return (uint8_t)IMF_HIL_WINDOW;
    case 6u:
        return app->in_kind;
    case 7u:
        return app->n_in;
    case 8u:
        return app->n_state;
    case 9u:
        return app->count_begin != NULL ? app->count_unit : (uint8_t)IMF_HIL_COUNT_NONE;
    default:
        break;
    }
    i = (uint16_t)(i - 10u);
    if (i < app->n_state) {
        const uint16_t t = app->state_types[i];
        return (uint8_t)((t & 0x0Fu) | ((t >> 4) & 0x70u));
    }
    i = (uint16_t)(i - app->n_state);
    name = imf_hil_name_len(app);
    if (i < name) {
        return (uint8_t)app->name[i];
    }
    return i == name ? (uint8_t)crc : (uint8_t)(crc >> 8);
}

/* Byte i of the frame to send: frame[i], or the hello's when frame is NULL. */
static uint8_t imf_hil_byte(const imf_hil_t *const self, const uint8_t *frame, uint8_t boot,
                            uint16_t crc, uint16_t i)
{
    return frame != NULL ? frame[i] : imf_hil_hello_byte(self->app, boot, crc, i);
}

/* COBS: every zero of the frame replaced by the distance to the next one; a block of 254
 * bytes without a zero has the code 0xFF (no zero after it). frame NULL: the hello (boot, crc). */
static void imf_hil_send(const imf_hil_t *const self, const uint8_t *frame, uint16_t n,
                         uint8_t boot, uint16_t crc)
{
    uint16_t start = 0u;
    self->app->put_byte(0u);
    while (start <= n) {
        uint16_t end = start;
        uint8_t code;
        while (end < n && (uint16_t)(end - start) < 254u
               && imf_hil_byte(self, frame, boot, crc, end) != 0u) {
            ++end;
        }
        code = (uint8_t)(end - start + 1u); /* 0xFF: 254 bytes and no zero after them */
        self->app->put_byte(code);
        while (start < end) {
            self->app->put_byte(imf_hil_byte(self, frame, boot, crc, start++));
        }
        if (code < 0xFFu) {
            start = (uint16_t)(end + 1u); /* past the zero (or the frame's end) */
        }
    }
    self->app->put_byte(0u);
}

/* type, sequence number, body already in frame[3..3+body); appends the CRC, returns the
 * frame's length. */
static uint16_t imf_hil_seal(uint8_t *frame, uint8_t type, uint16_t seq, uint16_t body)
{
    uint16_t crc;
    frame[0] = type;
    frame[1] = (uint8_t)seq;
    frame[2] = (uint8_t)(seq >> 8);
    crc = imf_hil_crc16(0xFFFFu, frame, (uint16_t)(3u + body));
    frame[3u + body] = (uint8_t)crc;
    frame[4u + body] = (uint8_t)(crc >> 8);
    return (uint16_t)(5u + body);
}

/* The hello, made byte by byte as it is sent (its type list may be longer than a buffer). */
static void imf_hil_hello(const imf_hil_t *const self, uint8_t boot)
{
    const uint16_t n =
        (uint16_t)(10u + self->app->n_state + imf_hil_name_len(self->app)); /* without CRC */
    uint16_t crc = 0xFFFFu;
    uint16_t i;
    for (i = 0u; i < n; ++i) {
        const uint8_t b = imf_hil_hello_byte(self->app, boot, 0u, i);
        crc = imf_hil_crc16(crc, &b, 1u);
    }
    imf_hil_send(self, NULL, (uint16_t)(n + 2u), boot, crc);
}

static void imf_hil_nak(const imf_hil_t *const self, uint8_t reason)
{
    uint8_t f[3u + 1u + 2u];
    f[3] = reason;
    imf_hil_send(self, f, imf_hil_seal(f, 'n', self->expected, 1u), 0u, 0u);
}

static void imf_hil_empty(const void *in)
{
    (void)in;
}

/* One call of fn: its count (less an empty call's) and the stack below the caller's. */
static IMF_HIL_NOINLINE uint32_t imf_hil_call(const imf_hil_t *const self, void (*fn)(const void *),
                                              const void *in, uint16_t *stack)
{
    const imf_hil_app_t *const app = self->app;
    uint32_t t0 = 0u;
    uint32_t count = 0u;
#if IMF_HIL_HAVE_SP
    uintptr_t sp;
    volatile uint8_t *p;
    IMF_HIL_READ_SP(sp);
    /* paint the band below the stack pointer; the update's frames overwrite it */
    for (p = (volatile uint8_t *)(sp - IMF_HIL_STACK_BAND); (uintptr_t)p < sp; ++p) {
        *p = IMF_HIL_PAINT;
    }
#endif
    if (app->count_begin != NULL) {
        t0 = app->count_begin();
    }
    fn(in);
    if (app->count_begin != NULL) {
        count = app->count_end(t0);
    }
#if IMF_HIL_HAVE_SP
    for (p = (volatile uint8_t *)(sp - IMF_HIL_STACK_BAND); (uintptr_t)p < sp; ++p) {
        if (*p != IMF_HIL_PAINT) {
            break;
        }
    }
    /* the whole band written: the update went deeper than the band, no figure */
    *stack = (uintptr_t)p == sp - IMF_HIL_STACK_BAND ? (uint16_t)IMF_HIL_NO_STACK
                                                     : (uint16_t)(sp - (uintptr_t)p);
#else
    *stack = (uint16_t)IMF_HIL_NO_STACK;
#endif
    return count;
}

static void imf_hil_sample(imf_hil_t *const self, const uint8_t *body, uint8_t n)
{
    const imf_hil_app_t *const app = self->app;
    uint8_t *const a = self->answer[self->expected % IMF_HIL_WINDOW];
    uint16_t len;
    uint16_t stack;
    uint32_t count;
    memcpy(self->in.b, body, n);
    if (app->load != NULL) {
        app->load(self->in.b);
    }
    count = imf_hil_call(self, app->update, self->in.b, &stack);
    count = count >= self->overhead ? count - self->overhead : 0u;
    if (stack != IMF_HIL_NO_STACK) {
        stack = stack >= self->stack_empty ? (uint16_t)(stack - self->stack_empty) : 0u;
    }
    len = app->state(a + 3);
    a[3u + len] = (uint8_t)count;
    a[4u + len] = (uint8_t)(count >> 8);
    a[5u + len] = (uint8_t)(count >> 16);
    a[6u + len] = (uint8_t)(count >> 24);
    a[7u + len] = (uint8_t)stack;
    a[8u + len] = (uint8_t)(stack >> 8);
    self->answer_len[self->expected % IMF_HIL_WINDOW] =
        (imf_hil_len_t)imf_hil_seal(a, 'r', self->expected, (uint16_t)(len + 6u));
    imf_hil_send(self, a, self->answer_len[self->expected % IMF_HIL_WINDOW], 0u, 0u);
    self->expected++;
}

/* A received frame, decoded: check it and answer. */
static uint16_t imf_hil_frame(imf_hil_t *const self, const uint8_t *f, uint8_t n)
{
    uint16_t seq;
    uint16_t behind;
    const uint8_t in_bytes = (uint8_t)(self->app->n_in
                                       * (self->app->in_kind == IMF_HIL_IN_F64   ? 8u
                                          : self->app->in_kind == IMF_HIL_IN_I16 ? 2u
                                                                                 : 4u));
    if (n < 5u
        || imf_hil_crc16(0xFFFFu, f, (uint16_t)(n - 2u))
               != (uint16_t)(f[n - 2u] | (uint16_t)((uint16_t)f[n - 1u] << 8))) {
        imf_hil_nak(self, IMF_HIL_NAK_CORRUPT);
        return 0u;
    }
    seq = (uint16_t)(f[1] | (uint16_t)((uint16_t)f[2] << 8));
    if (f[0] == 'H') {
        imf_hil_hello(self, 0u);
        return 0u;
    }
    if (f[0] == 'B') {
        uint8_t ack[5];
        uint16_t bytes = 0u;
        uint8_t j;
        for (j = 0u; j < self->app->n_state; ++j) {
            bytes = (uint16_t)(bytes + (self->app->state_types[j] & 0xFFu));
        }
        if (bytes > IMF_HIL_MAX_STATE || in_bytes > IMF_HIL_MAX_INPUT) {
            imf_hil_nak(self, IMF_HIL_NAK_SIZE);
            return 0u;
        }
        self->app->init();
        self->expected = 0u;
        self->running = 1u;
        imf_hil_send(self, ack, imf_hil_seal(ack, 'b', seq, 0u), 0u, 0u);
        return 0u;
    }
    if (f[0] != 'S' || n != (uint8_t)(5u + in_bytes)) {
        imf_hil_nak(self, IMF_HIL_NAK_CORRUPT);
        return 0u;
    }
    if (!self->running) {
        imf_hil_nak(self, IMF_HIL_NAK_IDLE);
        return 0u;
    }
    if (seq == self->expected) {
        imf_hil_sample(self, f + 3, in_bytes);
        return 1u;
    }
    behind = (uint16_t)(self->expected - seq);
    if (behind >= 1u && behind <= IMF_HIL_WINDOW && behind <= self->expected) {
        /* a repeat: the host lost the answer; the update is not run twice */
        imf_hil_send(self, self->answer[seq % IMF_HIL_WINDOW],
                     self->answer_len[seq % IMF_HIL_WINDOW], 0u, 0u);
        return 0u;
    }
    imf_hil_nak(self, IMF_HIL_NAK_ORDER);
    return 0u;
}

void imf_hil_init(imf_hil_t *const self, const imf_hil_app_t *const app)
{
    uint16_t stack = 0u;
    memset(self, 0, sizeof *self);
    self->app = app;
    self->overhead = imf_hil_call(self, imf_hil_empty, self->in.b, &stack);
    self->stack_empty = stack;
    imf_hil_hello(self, 1u);
}

uint16_t imf_hil_poll(imf_hil_t *const self)
{
    uint16_t ran = 0u;
    int c;
    while ((c = self->app->get_byte()) >= 0) {
        if (c != 0) {
            if (self->rx_len < (uint8_t)sizeof self->rx) {
                self->rx[self->rx_len++] = (uint8_t)c;
            } else {
                self->rx_over = 1u;
            }
            continue;
        }
        if (self->rx_len > 0u) {
            /* COBS decode in place: the decoded frame is one byte shorter */
            uint8_t r = 0u;
            uint8_t w = 0u;
            uint8_t ok = (uint8_t)!self->rx_over;
            while (ok && r < self->rx_len) {
                const uint8_t code = self->rx[r++];
                uint8_t k;
                if (code == 0u || r + code - 1u > self->rx_len) {
                    ok = 0u;
                    break;
                }
                for (k = 1u; k < code; ++k) {
                    self->rx[w++] = self->rx[r++];
                }
                if (code < 0xFFu && r < self->rx_len) {
                    self->rx[w++] = 0u;
                }
            }
            if (ok) {
                ran = (uint16_t)(ran + imf_hil_frame(self, self->rx, w));
            } else {
                imf_hil_nak(self, IMF_HIL_NAK_CORRUPT);
            }
        }
        self->rx_len = 0u;
        self->rx_over = 0u;
    }
    return ran;
}
