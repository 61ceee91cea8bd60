"""`validate --port`: the HIL runner (csrc/hil) on the emulated boards' own UARTs (QEMU's
CMSDK UART0 on -serial pty, simavr's USART0 on a pseudo-terminal), driven through the real
host side (pyserial), against `validate --target` on the same build.

On a pseudo-terminal QEMU's baud rate is nominal: the bytes pass as fast as the host moves
them. simavr's UART runs at the baud rate the firmware set, in simulated time.

The firmware is examples/firmware-tests/cf.c (Eq. 2.2 as firmware writes it): with
-ffp-contract=off bit-exact, with gnu defaults on the Cortex-M4F two vfma.f32 (a planted FMA
divergence). Faults are injected by tests/hil_proxy.py between the board and the validator
(a dropped byte, a flipped bit, silence) or built into the board (a reset at sample N).
"""
import os
import re
import shutil
import subprocess
import sys

import numpy as np
import pytest

from imufuse.shared.resources import csrc_dir
from imufuse.firmware import (TARGETS, Board, FirmwareError, build_board, csrc_firmware,
                              validate)
from imufuse.mcu import ensure_toolchains
from hil_proxy import Proxy
from test_firmware_target import FW, PARAMS, _cf, _fw, _motion

pytest.importorskip("serial")
pytestmark = pytest.mark.xdist_group("hil")

N = 200


def _m7(*values):
    return pytest.param("cortex-m7", *values, marks=pytest.mark.skipif(
        "cortex-m7" not in TARGETS, reason="cortex-m7 is not a --target of this checkout yet"))


@pytest.fixture(scope="module", autouse=True)
def _toolchains():
    missing = ensure_toolchains(("m4f", "avr"))
    assert not missing, f"MCU toolchains missing: {missing}"


def _case(flags, n=N):
    dt, ins = _motion(n)
    return _fw(*_cf(), flags), dict(dt=dt, **PARAMS), ins


def _both(target, flags, baud):
    """validate --port on the board and validate --target on the same build."""
    fw, params, ins = _case(flags)
    prog = build_board(fw, "Complementary1D", params, target, baud=baud)
    try:
        with Board(prog) as b:
            vp = validate(fw, "Complementary1D", params, ins, target=target, port=b.port,
                          baud=baud, timeout=10)
    finally:
        shutil.rmtree(prog.workdir, ignore_errors=True)
    vt = validate(fw, "Complementary1D", params, ins, target=target)
    return vp, vt


def _same_report(vp, vt):
    assert vp.bit_exact == vt.bit_exact
    assert vp.comparison.first_sample == vt.comparison.first_sample
    assert vp.comparison.names == vt.comparison.names
    assert vp.got.dtype == vt.got.dtype and np.array_equal(
        vp.got.view(np.uint8), vt.got.view(np.uint8))      # every state bit, every sample
    assert [c.what for c in vp.causes] == [c.what for c in vt.causes]
    assert [c.confirmed for c in vp.causes] == [c.confirmed for c in vt.causes]
    # the counts: the runner's call of the update differs from the --target driver's by a
    # few instructions or cycles, the same for every sample
    d = vp.cost.counts - vt.cost.counts
    assert vp.cost.unit == vt.cost.unit and len(vp.cost.counts) == N
    assert d.min() == d.max() and abs(int(d[0])) <= 8, d[:5]
    assert vp.cost.stack is not None and abs(vp.cost.stack - vt.cost.stack) <= 8


@pytest.mark.parametrize("target,baud", [("cortex-m4f", 1_000_000),
                                         _m7(1_000_000), ("atmega328p", 115_200),
                                         ("atmega328p", 1_000_000)])
def test_bit_exact_firmware_same_report_as_target(target, baud):
    vp, vt = _both(target, ["-O2", "-ffp-contract=off"], baud)
    assert vp.bit_exact, vp.text()
    _same_report(vp, vt)
    assert re.search(rf"^firmware 'imufuse-hil-test' on the {target} board at /dev/pts/\d+, "
                     rf"{baud} baud \(flags -O2 -ffp-contract=off\) vs imufuse "
                     r"Complementary1D \(c, float32\):$", vp.text(), re.M), vp.text()


@pytest.mark.parametrize("target", ["cortex-m4f", _m7()])
def test_planted_fma_same_divergence_and_cause_as_target(target):
    vp, vt = _both(target, ["-O2"], 115_200)
    assert not vp.bit_exact and vp.comparison.first_sample == 0
    _same_report(vp, vt)
    text = vp.text()
    assert "vfma.f32" in text and "-ffp-contract=off (confirmed" in text
    assert "give the same states bit for bit" in text


# ---------------------------------------------------------------------------
# faults, each named in one line with its sample

@pytest.fixture(scope="module")
def m4f_board():
    fw, params, ins = _case(["-O2", "-ffp-contract=off"])
    prog = build_board(fw, "Complementary1D", params, "cortex-m4f")
    yield fw, params, ins, prog
    shutil.rmtree(prog.workdir, ignore_errors=True)


def _through(m4f_board, **fault):
    fw, params, ins, prog = m4f_board
    with Board(prog) as b, Proxy(b.port, **fault) as p:
        v = validate(fw, "Complementary1D", params, ins, target="cortex-m4f", port=p.port,
                     timeout=2)
        assert p.done, "the fault was not injected"
        return v


@pytest.mark.parametrize("fault,to_board,k,line", [
    ("drop", True, 57, "sample 57: the board received a corrupted frame (CRC or framing); "
                       "sent again, recovered"),
    ("flip", True, 120, "sample 120: the board received a corrupted frame (CRC or framing); "
                        "sent again, recovered"),
    ("drop", False, 190, "sample 190: its answer came back corrupted (CRC); sent again, "
                         "recovered"),
    ("flip", False, 33, "sample 33: its answer came back corrupted (CRC); sent again, "
                        "recovered"),
])
def test_a_lost_or_corrupted_byte_is_repaired_and_named(m4f_board, fault, to_board, k, line):
    v = _through(m4f_board, fault=fault, sample=k, to_board=to_board)
    # every sample compared, the same bits as without the fault
    assert v.bit_exact and len(v.got) == N
    links = [n for n in v.notes if n.startswith("link:")]
    assert links == ["link: " + line], links


def test_silence_names_the_sample(m4f_board):
    with pytest.raises(FirmwareError, match=r"^the board stopped answering at sample 150 "
                                            r"\(nothing within 2 s on /dev/pts/\d+\)$"):
        _through(m4f_board, fault="silence", sample=150)


def test_a_reset_mid_run_names_the_sample():
    fw, params, ins = _case(["-O2", "-ffp-contract=off"])
    prog = build_board(fw, "Complementary1D", params, "cortex-m4f", reset_at=90)
    with Board(prog) as b:
        with pytest.raises(FirmwareError, match=r"^the board restarted at sample 90 \(its "
                                                r"start-up banner arrived during the run\)$"):
            validate(fw, "Complementary1D", params, ins, target="cortex-m4f", port=b.port,
                     timeout=5)


def test_other_firmware_is_named():
    """A board whose runner serves another firmware: its name and layout."""
    fw, params, ins = _case(["-O2", "-ffp-contract=off"])
    other = csrc_firmware("MadgwickIMU", csrc_dir(), cflags=["-O2", "-ffp-contract=off"])
    prog = build_board(other, "MadgwickIMU", dict(dt=params["dt"]), "cortex-m4f",
                       board_name="attitude-kalman 2.1")
    with Board(prog) as b:
        with pytest.raises(FirmwareError, match=r"^the board on /dev/pts/\d+ runs 'attitude-"
                           r"kalman 2.1' \(6 float32 inputs, 4 state words \(float32\)\); the "
                           r"firmware declared for Complementary1D has 2 inputs and 1 state "
                           r"words$"):
            validate(fw, "Complementary1D", params, ins, target="cortex-m4f", port=b.port,
                     timeout=5)


def test_cli_port_silence_exits_5(m4f_board, tmp_path):
    fw, params, ins, prog = m4f_board
    with Board(prog) as b, Proxy(b.port, fault="silence", sample=100) as p:
        proc = subprocess.run(
            [sys.executable, "-m", "imufuse", "validate", os.path.join(FW, "cf.c"), "--header",
             "cf.h", "-I", FW, "--filter", "Complementary1D", "--init", "cf_init", "--update",
             "cf_update", "--state", "theta=theta", "--cflags", "-O2 -ffp-contract=off",
             "--port", p.port, "--baud", "115200", "--timeout", "2", "--duration", "2"],
            capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 5, proc.stdout + proc.stderr
    err = [ln for ln in (proc.stdout + proc.stderr).splitlines() if "sample 100" in ln]
    assert len(err) == 1 and "the board stopped answering at sample 100" in err[0], \
        proc.stdout + proc.stderr


BANNER = r"""
#include <avr/io.h>
int main(void)
{
    const char *s;
    UCSR0A = 1u << U2X0; UBRR0H = 0u; UBRR0L = 1u;   /* 1 Mbaud at 16 MHz */
    UCSR0C = (1u << UCSZ01) | (1u << UCSZ00); UCSR0B = 1u << TXEN0;
    for (;;) {
        for (s = "Booting v2.1 (IMU demo)\r\n"; *s; ++s) {
            while (!(UCSR0A & (1u << UDRE0))) {}
            UDR0 = *s;
        }
    }
}
"""


def test_a_board_without_the_runner_is_named_with_what_it_sends(tmp_path):
    (tmp_path / "banner.c").write_text(BANNER)
    elf = tmp_path / "banner.elf"
    subprocess.run(["avr-gcc", "-mmcu=atmega328p", "-Os", str(tmp_path / "banner.c"), "-o",
                    str(elf)], check=True)
    fw, params, ins = _case(["-O2", "-ffp-contract=off"])
    with Board(elf=elf, target="atmega328p") as b:
        with pytest.raises(FirmwareError, match=r"^the board on /dev/pts/\d+ runs other firmware "
                           r"or none: no imufuse HIL hello within 2 s \(it sent '.*Booting v2\.1 "
                           r"\(IMU demo\)"):
            validate(fw, "Complementary1D", params, ins, port=b.port, timeout=2)


def test_robust_ahrs_q_all_89_words_through_the_generated_board(tmp_path):
    """build_board sizes the runner's state to the firmware's (RobustAHRSQ: 89 int32 words,
    356 bytes; the default 64 would refuse it): every word bit for bit, the counts as
    --target's."""
    from test_hil_examples import N_Q, Q_PARAMS, _robust_q_case
    fw, ins = _robust_q_case(tmp_path)
    prog = build_board(fw, "RobustAHRSQ", Q_PARAMS, "cortex-m4f")
    try:
        assert sum(t.size for t in prog.types) == 356
        with Board(prog) as b:
            vp = validate(fw, "RobustAHRSQ", Q_PARAMS, ins, target="cortex-m4f", port=b.port,
                          timeout=10)
    finally:
        shutil.rmtree(prog.workdir, ignore_errors=True)
    assert vp.bit_exact and vp.got.shape == (N_Q, 89), vp.text()
    assert vp.comparison.dtype == "int32", vp.text()     # the board's words, not int64
    vt = validate(fw, "RobustAHRSQ", Q_PARAMS, ins, target="cortex-m4f")
    assert np.array_equal(vp.got, vt.got)
    d = vp.cost.counts - vt.cost.counts
    assert d.min() == d.max() and abs(int(d[0])) <= 8, d[:5]


# ---------------------------------------------------------------------------
# the protocol on the host: long frames, the version

RUNNER_HOST = r"""
#include <stdio.h>
#include "imf_hil.h"

static int32_t x[85];
static uint16_t types[85];
static int eof;

static void fw_init(void)
{
    int j;
    for (j = 0; j < 85; ++j) {
        x[j] = j == 69 ? 0 : 0x11223344;          /* zeros among runs of 254+ bytes */
    }
}

static void fw_update(const void *in)
{
    const int16_t *v = (const int16_t *)in;
    int j;
    for (j = 0; j < 85; ++j) {
        x[j] = x[j] == 0 ? 0 : (int32_t)(((uint32_t)x[j] * 2654435761u + (uint16_t)v[j % 9])
                                         | 0x01010101u);
    }
}

static uint16_t fw_state(uint8_t *out)
{
    int j, b;
    for (j = 0; j < 85; ++j) {
        for (b = 0; b < 4; ++b) {
            out[4 * j + b] = (uint8_t)((uint32_t)x[j] >> (8 * b));
        }
    }
    return 340u;
}

static int get_byte(void)
{
    const int c = getchar();
    eof = c == EOF;
    return eof ? -1 : c;
}

static void put_byte(uint8_t b)
{
    putchar(b);
}

int main(void)
{
    static imf_hil_app_t app = {"host runner", IMF_HIL_IN_I16, 9, 85, types, fw_init, NULL,
                                fw_update, fw_state, get_byte, put_byte, NULL, NULL, 0};
    static imf_hil_t hil;
    int j;
    for (j = 0; j < 85; ++j) {
        types[j] = IMF_HIL_T_I32;
    }
    imf_hil_init(&hil, &app);
    while (!eof) {
        (void)imf_hil_poll(&hil);
    }
    return 0;
}
"""


def _runner_host(tmp_path, *defs):
    src = tmp_path / "runner_host.c"
    src.write_text(RUNNER_HOST)
    exe = tmp_path / f"runner_host{len(defs)}"
    subprocess.run([os.environ.get("CC", "cc"), "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror",
                    *defs, "-I", str(csrc_dir() / "hil"), "-o", str(exe), str(src),
                    str(csrc_dir() / "hil" / "imf_hil.c")], check=True)
    return exe


def test_runner_carries_85_words_in_frames_longer_than_a_cobs_block(tmp_path):
    """The runner built with IMF_HIL_MAX_STATE 340 (85 int32 words), on the host
    through stdin/stdout: its hello lists 85 words, its 351-byte answers (blocks of 254 bytes
    without a zero inside) are byte for byte what the host side encodes, a repeated sample
    gets the kept answer, a corrupted frame a NAK. Built with the default (64 bytes) it refuses
    to begin."""
    from imufuse.firmware.hil_protocol import VERSION, FrameReader, Hello, frame, parse
    ins = (np.arange(5 * 9, dtype=np.int16).reshape(5, 9) * 1009).astype("<i2")
    bad = bytearray(frame(b"S", 5, ins[0].tobytes()))
    bad[5] ^= 0x10
    req = (frame(b"H", 0) + frame(b"B", 0)
           + b"".join(frame(b"S", k, ins[k].tobytes()) for k in range(5))
           + frame(b"S", 3, ins[3].tobytes()) + bytes(bad))
    exe = _runner_host(tmp_path, "-DIMF_HIL_MAX_STATE=340u")
    raws = FrameReader().feed(subprocess.run([str(exe)], input=req, capture_output=True,
                                             check=True).stdout)
    frames = [parse(r) for r in raws]
    assert [f[:2] for f in frames] == [("h", 0), ("h", 0), ("b", 0)] + [
        ("r", k) for k in range(5)] + [("r", 3), ("n", 5)]
    for raw, (kind, seq, body) in zip(raws, frames):
        assert b"\0" + raw + b"\0" == frame(kind.encode(), seq, body)
    hello = Hello.decode(frames[1][2])
    assert (hello.version, hello.boot, hello.name) == (VERSION, False, "host runner")
    assert hello.types == [0x304] * 85 and hello.in_dtype == np.dtype("<i2")
    answers = [f[2] for f in frames[3:8]]
    assert all(len(a) == 340 + 6 for a in answers) and max(len(r) for r in raws) > 340
    assert any(b"\0" not in a[i:i + 254] for a in answers for i in range(len(a) - 254))
    assert frames[8][2] == answers[3] and frames[9][2] == b"\x01"
    x = np.where(np.arange(85) == 69, 0, 0x11223344).astype(np.uint32)
    for k in range(5):
        v = ins[k][np.arange(85) % 9].astype(np.uint16).astype(np.uint32)
        x = np.where(x == 0, 0, (x * np.uint32(2654435761) + v) | np.uint32(0x01010101))
        assert np.frombuffer(answers[k][:340], "<u4").tolist() == x.tolist()
    small = _runner_host(tmp_path)
    out = subprocess.run([str(small)], input=frame(b"B", 0), capture_output=True).stdout
    assert [parse(r)[:3] for r in FrameReader().feed(out)][-1] == ("n", 0, b"\x04")


def test_a_runner_of_another_protocol_version_is_refused():
    """A board whose runner is of protocol version 1 (64 words at most a frame): named, with
    what to do."""
    import threading
    import tty
    from imufuse.firmware import hil_protocol
    from imufuse.firmware.hil import Link
    from imufuse.firmware.targets import TargetError
    master, slave = os.openpty()
    tty.setraw(slave)
    old = hil_protocol.frame(b"h", 0, bytes([1, 0, 2, 1, 9, 4, 1]) + bytes([4] * 4)
                             + b"attitude 1.0")

    def board():
        seen = b""
        while b"\0" not in seen[1:]:
            seen += os.read(master, 64)
        os.write(master, old)

    threading.Thread(target=board, daemon=True).start()
    try:
        with Link(os.ttyname(slave), timeout=2) as link:
            with pytest.raises(TargetError, match=r"^the board on /dev/pts/\d+ runs the imufuse "
                               r"HIL runner's protocol version 1 \(firmware 'attitude 1\.0'\); "
                               r"this imufuse speaks version 2: rebuild the firmware with "
                               r"csrc/hil/imf_hil\.c and imf_hil\.h of this imufuse$"):
                link.hello()
    finally:
        os.close(master)
        os.close(slave)
