/* An ATmega328P board for the HIL tests and benchmarks: simavr running a firmware image, its
 * USART0 on a pseudo-terminal, as a real board's UART on a USB serial adapter. Not firmware:
 * a host program, built against libsimavr by imufuse.firmware.hil_board.
 *
 *   imf_hil_simavr FIRMWARE.elf [F_CPU]
 *
 * prints "PTY <path>" once the terminal is open, then runs until the firmware sleeps with
 * interrupts off or crashes. Bytes go to the UART only while its receive FIFO has room (its
 * XON/XOFF lines), at the baud rate the firmware set, in simulated time: the UART's speed is
 * real relative to the 16 MHz clock. The simulation runs as fast as the host allows. */
#define _DEFAULT_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <pty.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <unistd.h>

#include <simavr/avr_uart.h>
#include <simavr/sim_avr.h>
#include <simavr/sim_elf.h>
#include <simavr/sim_io.h>
#include <simavr/sim_irq.h>

static int imf_master = -1;
static int imf_xoff = 0;
static avr_irq_t *imf_uart_in;
static uint8_t imf_out[4096];
static size_t imf_out_len;

static void imf_flush(void)
{
    size_t done = 0;
    while (done < imf_out_len) {
        const ssize_t w = write(imf_master, imf_out + done, imf_out_len - done);
        if (w < 0) {
            if (errno == EAGAIN) {
                usleep(100);
                continue;
            }
            break;
        }
        done += (size_t)w;
    }
    imf_out_len = 0;
}

static void imf_on_output(struct avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    (void)param;
    imf_out[imf_out_len++] = (uint8_t)value;
    if (imf_out_len == sizeof imf_out) {
        imf_flush();
    }
}

static void imf_on_xon(struct avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    (void)value;
    (void)param;
    imf_xoff = 0;
}

static void imf_on_xoff(struct avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    (void)value;
    (void)param;
    imf_xoff = 1;
}

int main(int argc, char **argv)
{
    elf_firmware_t fw;
    avr_t *avr;
    int slave;
    char name[256];
    struct termios tio;
    uint32_t flags = 0;
    unsigned long step = 0;
    uint8_t in[256];
    size_t in_len = 0;
    size_t in_pos = 0;
    int state = cpu_Running;

    if (argc < 2) {
        fprintf(stderr, "usage: %s FIRMWARE.elf [F_CPU]\n", argv[0]);
        return 2;
    }
    memset(&fw, 0, sizeof fw);
    if (elf_read_firmware(argv[1], &fw) != 0) {
        fprintf(stderr, "cannot read %s\n", argv[1]);
        return 2;
    }
    avr = avr_make_mcu_by_name("atmega328p");
    if (avr == NULL) {
        return 2;
    }
    avr_init(avr);
    avr_load_firmware(avr, &fw);
    avr->frequency = argc > 2 ? (uint32_t)strtoul(argv[2], NULL, 10) : 16000000u;

    if (openpty(&imf_master, &slave, name, NULL, NULL) != 0) {
        perror("openpty");
        return 2;
    }
    tcgetattr(slave, &tio);
    cfmakeraw(&tio);
    tcsetattr(slave, TCSANOW, &tio);
    fcntl(imf_master, F_SETFL, fcntl(imf_master, F_GETFL) | O_NONBLOCK);

    /* no sleeping while the firmware polls the UART, no console echo */
    avr_ioctl(avr, AVR_IOCTL_UART_GET_FLAGS('0'), &flags);
    flags &= ~(uint32_t)(AVR_UART_FLAG_POLL_SLEEP | AVR_UART_FLAG_STDIO);
    avr_ioctl(avr, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
    imf_uart_in = avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT),
                            imf_on_output, NULL);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XON),
                            imf_on_xon, NULL);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XOFF),
                            imf_on_xoff, NULL);
    printf("PTY %s\n", name);
    fflush(stdout);

    while (state != cpu_Done && state != cpu_Crashed) {
        state = avr_run(avr);
        if ((++step & 0x3FFu) != 0u) {
            continue;
        }
        if (imf_out_len > 0) {
            imf_flush();
        }
        if (in_pos == in_len) {
            const ssize_t r = read(imf_master, in, sizeof in);
            in_pos = 0;
            in_len = r > 0 ? (size_t)r : 0u;
        }
        while (in_pos < in_len && !imf_xoff) {
            avr_raise_irq(imf_uart_in, in[in_pos++]);
        }
    }
    imf_flush();
    close(slave);
    return state == cpu_Done ? 0 : 1;
}
