"""The wire format of the hardware-in-the-loop runner (csrc/hil/imf_hil.h), protocol version
2: COBS frames between 0x00 delimiters (a block of 254 bytes without a zero has the code 0xFF,
so a frame may be longer than 254 bytes: a state of up to 255 words); a frame is type,
sequence number (2 bytes), body, CRC-16/CCITT-FALSE (2 bytes) over type, sequence and body,
all little-endian. Version 1 (a runner of imufuse before it) carried 64 state words at most.
"""
from __future__ import annotations

import dataclasses
import struct
from typing import Dict, List, Optional, Tuple

import numpy as np

__all__ = ["VERSION", "crc16", "cobs_encode", "cobs_decode", "frame", "parse", "Hello", "IN_KINDS",
           "COUNT_UNITS", "NAK_REASONS", "FrameReader"]

#: the protocol version of csrc/hil/imf_hil.h (IMF_HIL_VERSION); a board's hello with another
#: is refused (imufuse.firmware.hil.Link.hello)
VERSION = 2
#: input kinds of the hello: numpy dtype of the values the host sends
IN_KINDS: Dict[int, np.dtype] = {1: np.dtype("<f4"), 2: np.dtype("<f8"), 3: np.dtype("<i2"), 4: np.dtype("<i4")}
COUNT_UNITS = {0: "", 1: "cycles", 2: "instructions"}
NAK_REASONS = {1: "a corrupted frame (CRC or framing)", 2: "a frame out of order (one lost)",
               3: "no run begun", 4: "a state or input larger than the runner's buffers"}


def crc16(data: bytes, crc: int = 0xFFFF) -> int:
    """CRC-16/CCITT-FALSE: polynomial 0x1021, initial 0xFFFF, no reflection."""
    for b in data:
        crc ^= b << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) & 0xFFFF if crc & 0x8000 else (crc << 1) & 0xFFFF
    return crc


def cobs_encode(data: bytes) -> bytes:
    out = bytearray()
    for block in data.split(b"\0"):
        while len(block) >= 254:
            out += b"\xff" + block[:254]
            block = block[254:]
        out.append(len(block) + 1)
        out += block
    return bytes(out)


def cobs_decode(data: bytes) -> Optional[bytes]:
    """The frame, or None when the encoding is broken (a lost or changed byte)."""
    out = bytearray()
    i = 0
    while i < len(data):
        code = data[i]
        if code == 0 or i + code > len(data):
            return None
        out += data[i + 1:i + code]
        i += code
        if code < 0xFF and i < len(data):
            out.append(0)
    return bytes(out)


def frame(kind: bytes, seq: int, body: bytes = b"") -> bytes:
    """One frame on the wire, delimiters included."""
    f = kind + struct.pack("<H", seq & 0xFFFF) + body
    return b"\0" + cobs_encode(f + struct.pack("<H", crc16(f))) + b"\0"


def parse(raw: bytes) -> Optional[Tuple[str, int, bytes]]:
    """(type, sequence number, body) of a received frame, or None when it is corrupted."""
    f = cobs_decode(raw)
    if f is None or len(f) < 5 or crc16(f[:-2]) != struct.unpack("<H", f[-2:])[0]:
        return None
    return chr(f[0]), struct.unpack("<H", f[1:3])[0], f[3:-2]


@dataclasses.dataclass
class Hello:
    """What the board's runner says about itself."""
    version: int
    boot: bool
    window: int
    in_dtype: Optional[np.dtype]
    n_in: int
    types: List[int]                # per state word: size | 0x100 integer | 0x200 signed
    count_unit: str
    name: str

    @classmethod
    def decode(cls, body: bytes) -> "Hello":
        if len(body) < 7:
            raise ValueError("short hello")
        version, boot, window, kind, n_in, n_state, unit = body[:7]
        if len(body) < 7 + n_state:
            raise ValueError("short hello")
        # one byte a word on the wire: size | 0x10 integer | 0x20 signed | 0x40 double
        types = [(b & 0x0F) | ((b & 0x70) << 4) for b in body[7:7 + n_state]]
        name = body[7 + n_state:].decode("utf-8", "replace")
        return cls(version, bool(boot), max(window, 1), IN_KINDS.get(kind), n_in, types,
                   COUNT_UNITS.get(unit, ""), name)

    def layout(self) -> str:
        kinds = sorted({("int" if t & 0x100 else "float") + str(8 * (t & 0xFF)) for t in self.types})
        inp = self.in_dtype.name if self.in_dtype is not None else "unknown"
        return (f"{self.n_in} {inp} inputs, {len(self.types)} state words "
                f"({', '.join(kinds) or 'none'})")


class FrameReader:
    """Splits received bytes into frames; keeps the text of bytes outside frames (a banner
    of other firmware)."""

    def __init__(self) -> None:
        self.buf = bytearray()

    def feed(self, data: bytes) -> List[bytes]:
        self.buf += data
        out = []
        while True:
            i = self.buf.find(b"\0")
            if i < 0:
                break
            if i > 0:
                out.append(bytes(self.buf[:i]))
            del self.buf[:i + 1]
        if len(self.buf) > 4096:       # no delimiter for that long: not this protocol
            out.append(bytes(self.buf))
            self.buf.clear()
        return out
