"""A pseudo-terminal between the validator and an emulated board's UART that injects one
fault into the frames of one sample (test helper of tests/test_hil*.py):

    drop    the frame's 4th byte goes missing        (to the board or back to the host)
    flip    a bit of the frame's 4th byte is changed (to the board or back to the host)
    silence once the board has answered the sample before, nothing passes either way

The frames are found with imufuse.firmware.hil_protocol, so the fault hits the sample asked
for the first time it passes, and only then.
"""
import os
import select
import threading
import tty

from imufuse.firmware.hil_protocol import parse


class Proxy:
    def __init__(self, board_port, fault=None, sample=0, to_board=True):
        self.fault, self.sample, self.to_board = fault, sample, to_board
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.port = os.ttyname(self.slave)
        self.board = os.open(board_port, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(self.board)
        self.done = False          # the fault was injected
        self.silent = False
        self.stop = False
        self.bufs = {self.master: bytearray(), self.board: bytearray()}
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _hit(self, raw, towards_board):
        if self.done or self.fault is None or towards_board != self.to_board:
            return raw
        f = parse(raw)
        if f is None or f[0] != ("S" if towards_board else "r") or f[1] != self.sample:
            return raw
        self.done = True
        if self.fault == "drop":
            return raw[:3] + raw[4:]
        if self.fault == "flip":
            b = raw[3] ^ 0x10 if raw[3] != 0x10 else 0x30   # never 0x00, a delimiter
            return raw[:3] + bytes([b]) + raw[4:]
        return raw

    def _forward(self, src, dst):
        try:
            data = os.read(src, 4096)
        except OSError:
            self.stop = True
            return
        buf = self.bufs[src]
        buf += data
        out = bytearray()
        while True:
            i = buf.find(b"\0")
            if i < 0:
                break
            raw = bytes(buf[:i])
            del buf[:i + 1]
            if not self.silent:
                out += self._hit(raw, src == self.master) + b"\0"
            if self.fault == "silence" and src == self.board:
                f = parse(raw)
                if f is not None and f[0] == "r" and f[1] == self.sample - 1:
                    self.silent = self.done = True
        if out:
            os.write(dst, bytes(out))

    def _run(self):
        while not self.stop:
            r, _, _ = select.select([self.master, self.board], [], [], 0.05)
            for fd in r:
                self._forward(fd, self.board if fd == self.master else self.master)

    def close(self):
        self.stop = True
        self.thread.join(2)
        for fd in (self.master, self.slave, self.board):
            os.close(fd)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
