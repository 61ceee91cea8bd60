"""Emulated-MCU harness: build C for a microcontroller, run it in an emulator, read the state back.

Targets (see ``TARGETS``):

- ``"m4f"``  Cortex-M4F, hard float, ``qemu-system-arm -M mps2-an386`` (semihosting output)
- ``"m0"``   Cortex-M0, soft float, ``qemu-system-arm -M microbit`` (semihosting output)
- ``"avr"``  ATmega328P, ``simavr -m atmega328p -f 16000000`` (UART0 output, Timer1 cycles)
- ``"host"`` the machine's own ``cc``, run as a normal process (the bit-exactness reference)

Every build uses ``-std=c99 -O2 -ffp-contract=off`` and the warning set of ``WARN_FLAGS``.

A program is the generic driver (``data/imf_driver_main.c``) plus a generated header with the
inputs as constant arrays (in flash / PROGMEM) plus the *driver*: file-scope C and three
functions ``imf_user_init()``, ``imf_user_step()`` and ``imf_user_dump()``. ``Driver``
generates them from a few lines::

    drv = Driver(
        prelude='#include "madgwick.h"\\nstatic imf_madgwick_t f;',
        init="imf_madgwick_init(&f, 1.0f / 512.0f, 0.1f);",
        step="imf_madgwick_update(&f, gyr, acc);",     # gyr, acc: the current input rows
        state=state_words("f.q", "f32", 4),
    )
    res = run("m4f", sources=["csrc/madgwick.c"], include_dirs=["csrc"],
              driver=drv, inputs={"gyr": gyr_f32, "acc": acc_f32})
    res.state          # (N, 4) numpy.uint32: bit patterns after every sample

Without ``Driver`` the driver is C text (``driver="..."``) that defines, after the harness's
output helpers are visible::

    #include "madgwick.h"
    static imf_madgwick_t f;
    static void imf_user_init(void) { imf_madgwick_init(&f, 1.0f / 512.0f, 0.1f); }
    static void imf_user_step(void) { imf_madgwick_update(&f, gyr, acc); }
    static void imf_user_dump(void) { imf_out_f32(f.q[0]); imf_out_f32(f.q[1]); /* ... */ }

Dumpers: imf_out_f32/f64/u32/i32/u16/i16/u8/i8. Inputs appear as file-scope variables named
like the inputs, holding the current sample (``float gyr[3]``; ``int16_t rate`` for 1-D).

Output protocol (one line each): ``K <hex>`` empty-call count; per sample
``S <hex word> ... c<hex count>``; ``M <hex stack bytes> <hex painted band>``; ``IMF_END``.
Inputs live in flash (PROGMEM on AVR): the ATmega328P's 32 KB hold about 1000 samples of six
float32 words. Each run ends by itself (semihosting exit; AVR: sleep with interrupts off)
and is killed after ``timeout`` seconds.

``run(..., count=True)`` also measures every ``imf_user_step()``: CPU cycles on ``avr``
(Timer1 at clk/1), instructions on ``m4f``/``m0`` (qemu ``-icount`` and SysTick);
``callgrind_instructions()`` gives instructions per update of a host build.
``code_size()`` and ``stack_usage()`` measure objects built with the same flags.
"""
# The harness by responsibility: toolchains (targets, flags, tool lookup), driver
# (the generated C around the code under test), inputs (constant arrays in flash),
# programs (compiling and linking), emulators (running and reading the output),
# measure (code size, stack, instruction counts). The library's filters on the harness:
# library (what csrc's headers say about a filter, read with imufuse.shared.cproto), samples (the
# inputs of the filter runs), filters (FilterSpec, run_filters, the configurations).
from .toolchains import (
    AVR_OVF_ISR_CYCLES, BASE_FLAGS, DATA_DIR, ICOUNT_SHIFT, INSTALL_SCRIPT, TARGETS, WARN_FLAGS,
    HarnessError, Target, ToolchainMissing, available, cflags, ensure_toolchains, missing_tools)
from .driver import Driver, state_words
from .programs import build
from .emulators import Result, run, run_elf
from .emulators import _simavr_text as _simavr_text  # noqa: F401 (tests read simavr output)
from .measure import callgrind_instructions, code_size, stack_usage

__all__ = [
    "TARGETS",
    "WARN_FLAGS",
    "BASE_FLAGS",
    "Target",
    "Driver",
    "Result",
    "HarnessError",
    "ToolchainMissing",
    "state_words",
    "build",
    "run",
    "run_elf",
    "code_size",
    "stack_usage",
    "callgrind_instructions",
    "available",
    "missing_tools",
    "ensure_toolchains",
    "DATA_DIR",
    "INSTALL_SCRIPT",
    "cflags",
    "AVR_OVF_ISR_CYCLES",
    "ICOUNT_SHIFT",
]
