/* imufuse hardware-in-the-loop runner: validates a filter in the firmware of a real board
 * over a serial link (`imufuse validate --port /dev/ttyACM0`).
 *
 * The host sends input samples; the runner calls the firmware's update through a small
 * adapter (imf_hil_app_t: init, update, state) and sends back every state word after every
 * sample, the update's cycle count and the stack it reached. Plain C99, no malloc, no
 * globals: the runner lives in an imf_hil_t the caller owns (about 200 bytes with the
 * defaults below for an AHRS in float32; IMF_HIL_WINDOW kept answers of IMF_HIL_MAX_STATE + 11
 * bytes make most of it), and talks through the caller's byte callbacks, so
 * any transport does (UART, USB CDC, a socket).
 *
 * Protocol version 2 (the host side is imufuse.firmware.hil_protocol; it refuses another
 * version): frames are COBS-encoded between 0x00 delimiters (a block of 254 bytes without a
 * zero has the code 0xFF, so a frame may be longer than 254 bytes); a frame is type (1
 * byte), sequence number (2, little-endian), body, CRC-16/CCITT-FALSE (2, little-endian)
 * over type, sequence and body.
 *   host 'H' hello          -> board 'h' version, boot flag, window, input kind, inputs,
 *                              state words (255 at most), count unit, state types (1 byte
 *                              each: size | 0x10 integer | 0x20 signed | 0x40 double), name
 *                              (24 chars at most)
 *   host 'B' begin a run    -> board calls init, 'b'
 *   host 'S' sample k, body -> board 'r' k: state bytes, count (4), stack bytes (2)
 *                              a repeated k (the host lost the answer): the stored answer
 *                              a sample out of order or a corrupted frame: 'n' expected k,
 *                              reason (1 corrupted, 2 out of order, 3 no run begun)
 *                              ('n' reason 4 to 'B': the state or the input is larger than
 *                              IMF_HIL_MAX_STATE or IMF_HIL_MAX_INPUT)
 * At start-up (imf_hil_init) the board sends its hello unasked, with the boot flag set: a
 * board that resets during a run is seen by its banner. Up to IMF_HIL_WINDOW samples are in
 * flight; the last IMF_HIL_WINDOW answers are kept for repeats, so a lost or corrupted byte
 * in either direction costs a repeat, never a sample. All words are little-endian (ARM,
 * AVR and RISC-V MCUs are). Version 1 carried 64 state words at most, in frames shorter
 * than 255 bytes (its state callback returned uint8_t). */
#ifndef IMF_HIL_H
#define IMF_HIL_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define IMF_HIL_VERSION 2u

/* Samples in flight and answers kept for repeats (RAM: IMF_HIL_WINDOW answers). Keep
 * IMF_HIL_WINDOW sample frames within the board's receive buffer (64 bytes on an Arduino). */
#ifndef IMF_HIL_WINDOW
#define IMF_HIL_WINDOW 2u
#endif
/* Input bytes per sample at most (an AHRS in float32: 9 * 4 = 36; 240 at most). */
#ifndef IMF_HIL_MAX_INPUT
#define IMF_HIL_MAX_INPUT 40u
#endif
/* State bytes per sample at most (RAM: IMF_HIL_WINDOW times this; RobustAHRSQ: 89 * 4 =
 * 356; 4096 at most). Up to 244 the answers' lengths are single bytes, as in version 1. */
#ifndef IMF_HIL_MAX_STATE
#define IMF_HIL_MAX_STATE 64u
#endif
#if IMF_HIL_MAX_INPUT > 240u
#error "IMF_HIL_MAX_INPUT: 240 bytes at most"
#endif
#if IMF_HIL_MAX_STATE > 4096u
#error "IMF_HIL_MAX_STATE: 4096 bytes at most"
#endif
/* Bytes painted below the runner's frame to measure the update's stack (0: not measured). */
#ifndef IMF_HIL_STACK_BAND
#if defined(__AVR__)
#define IMF_HIL_STACK_BAND 256u
#else
#define IMF_HIL_STACK_BAND 1024u
#endif
#endif

/* Input kinds: the values of one sample as the host sends them. */
#define IMF_HIL_IN_F32 1u
#define IMF_HIL_IN_F64 2u
#define IMF_HIL_IN_I16 3u
#define IMF_HIL_IN_I32 4u

/* State word types: size in bytes | IMF_HIL_INTEGER | IMF_HIL_SIGNED (| IMF_HIL_DOUBLE: a
 * state declared double, which is 4 bytes on AVR). */
#define IMF_HIL_INTEGER 0x100u
#define IMF_HIL_SIGNED 0x200u
#define IMF_HIL_DOUBLE 0x400u
#define IMF_HIL_T_F32 4u
#define IMF_HIL_T_F64 (8u | IMF_HIL_DOUBLE)
#define IMF_HIL_T_I16 (2u | IMF_HIL_INTEGER | IMF_HIL_SIGNED)
#define IMF_HIL_T_I32 (4u | IMF_HIL_INTEGER | IMF_HIL_SIGNED)
#define IMF_HIL_T_U32 (4u | IMF_HIL_INTEGER)

/* Count units of imf_hil_app_t.count_end. */
#define IMF_HIL_COUNT_NONE 0u
#define IMF_HIL_COUNT_CYCLES 1u
#define IMF_HIL_COUNT_INSTRUCTIONS 2u

/* What the runner needs from the firmware and the board. */
typedef struct {
    const char *name;            /* the firmware's identity, sent in the hello (24 chars) */
    uint8_t in_kind;             /* IMF_HIL_IN_F32 ... */
    uint8_t n_in;                /* input values per sample */
    uint8_t n_state;             /* state words */
    const uint16_t *state_types; /* n_state IMF_HIL_T_... */
    void (*init)(void);          /* start a run: the filter's init */
    /* optional (NULL: none): store the sample where update reads it, outside the count */
    void (*load)(const void *in);
    /* one sample: n_in values of in_kind (aligned for double), counted */
    void (*update)(const void *in);
    /* the state words into out, each in its own size; returns the bytes written (at most
       IMF_HIL_MAX_STATE) */
    uint16_t (*state)(uint8_t *out);
    int (*get_byte)(void);                 /* a received byte 0..255, or -1 when none is waiting */
    void (*put_byte)(uint8_t b);           /* send one byte (may block) */
    uint32_t (*count_begin)(void);         /* a start value (NULL: no counter) */
    uint32_t (*count_end)(uint32_t start); /* counts since start, in count_unit */
    uint8_t count_unit;                    /* IMF_HIL_COUNT_... */
} imf_hil_app_t;

#define IMF_HIL_ANSWER (3u + IMF_HIL_MAX_STATE + 6u + 2u) /* header, state, count, stack, CRC */
#define IMF_HIL_FRAME (3u + IMF_HIL_MAX_INPUT + 2u)       /* header, sample, CRC */

/* The length of a kept answer: one byte while the answers fit in 255 bytes. */
#if IMF_HIL_MAX_STATE + 11u > 255u
typedef uint16_t imf_hil_len_t;
#else
typedef uint8_t imf_hil_len_t;
#endif

/* The runner. All members private. */
typedef struct {
    const imf_hil_app_t *app;                       /* the firmware and board callbacks */
    uint8_t rx[IMF_HIL_FRAME + 2u];                 /* the COBS frame being received */
    uint8_t rx_len;                                 /* bytes of it so far */
    uint8_t rx_over;                                /* 1: the frame was longer than rx (dropped) */
    uint8_t running;                                /* 1: a run has begun */
    uint16_t expected;                              /* the next sample's sequence number */
    uint8_t answer[IMF_HIL_WINDOW][IMF_HIL_ANSWER]; /* the last answers, for repeats */
    imf_hil_len_t answer_len[IMF_HIL_WINDOW];       /* their lengths, bytes */
    uint32_t overhead;                              /* counts of an empty call */
    uint16_t stack_empty;                           /* stack of an empty call, bytes */
    union {
        double d[(IMF_HIL_MAX_INPUT + 7u) / 8u]; /* alignment for double inputs */
        uint8_t b[IMF_HIL_MAX_INPUT];            /* the sample's input bytes */
    } in;                                        /* the sample being run */
} imf_hil_t;

/* Set up the runner on app (which must outlive it) and send the start-up banner (the hello
 * with the boot flag). */
void imf_hil_init(imf_hil_t *const self, const imf_hil_app_t *const app);

/* Read the bytes waiting (app->get_byte until -1) and answer each complete frame; call it
 * from the main loop. Returns the number of samples run. */
uint16_t imf_hil_poll(imf_hil_t *const self);

/* CRC-16/CCITT-FALSE (polynomial 0x1021, initial 0xFFFF) of n bytes, continuing crc. */
uint16_t imf_hil_crc16(uint16_t crc, const uint8_t *data, uint16_t n);

#ifdef __cplusplus
}
#endif

#endif
