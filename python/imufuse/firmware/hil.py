"""Hardware in the loop: a board running the imufuse HIL runner (csrc/hil/imf_hil.c) in its
firmware, driven over a serial port with pyserial (`imufuse validate --port`).

``Link`` opens the port, reads the runner's hello (what the firmware is: its name, inputs and
state words), begins a run and streams samples, up to the board's window in flight. Lost or
corrupted bytes are repaired by repeats (the board answers a repeated sample from what it
kept, never running the update twice) and named in ``Link.events``, one line per sample.
What cannot be repaired is a TargetError naming the sample: a board that restarts (its
start-up banner arrives during the run), that stops answering, or that runs other firmware.
"""
from __future__ import annotations

import dataclasses
import time
from typing import Dict, List, Optional, Tuple

import numpy as np

from .hil_protocol import NAK_REASONS, VERSION, FrameReader, Hello, frame, parse
from .results import Cost
from .targets import TargetError

__all__ = ["Link", "BoardRun", "BoardCost", "DEFAULT_BAUD"]

DEFAULT_BAUD = 1_000_000
#: the board silent this long (seconds) with samples in flight: they are sent again
REPEAT_AFTER = 1.0
#: repeats of one sample before the link is given up
MAX_REPEATS = 16


@dataclasses.dataclass
class BoardRun:
    """The board's answers: every state word after every sample and what it cost."""
    states: List[np.ndarray]        # per state word: (N,) in its C type (int64 for integers)
    counts: Optional[np.ndarray]    # (N,) per update in hello.count_unit; None: no counter
    stack: Optional[int]            # deepest stack an update reached, bytes
    seconds: float
    repeats: int


class BoardCost(Cost):
    """The cost of one update on the board: counts and stack from the runner; flash and RAM
    are in the board's own build (its map file)."""

    def text(self) -> str:
        stack = f"{self.stack} B" if self.stack is not None else "not measured"
        return (f"cost per update on the board: {self.min} / {self.median:.0f} / {self.max} "
                f"{self.unit} (min / median / max)\nstack {stack}; flash and RAM: see the "
                "board's build (its map file)")


def _decode_word(col: bytes, t: int) -> np.ndarray:
    size = t & 0xFF
    if t & 0x100:
        return np.frombuffer(col, dtype=f"<{'i' if t & 0x200 else 'u'}{size}").astype(np.int64)
    return np.frombuffer(col, dtype="<f4" if size == 4 else "<f8").copy()


class Link:
    """A serial link to a board running the HIL runner. timeout: seconds of silence (no
    valid frame) after which the board is said to have stopped answering."""

    def __init__(self, port: str, baud: int = DEFAULT_BAUD, timeout: float = 10.0):
        import serial           # pyserial: imported here so imufuse loads without it
        self.port = port
        self.timeout = timeout
        try:
            self.ser = serial.Serial(port, baudrate=baud, timeout=0.02, write_timeout=timeout)
        except (serial.SerialException, ValueError) as err:
            raise TargetError(f"cannot open {port}: {err}") from None
        self.reader = FrameReader()
        self.events: List[str] = []
        self.hello_: Optional[Hello] = None
        self.stray = bytearray()        # bytes outside valid frames (another firmware's text)

    def close(self) -> None:
        self.ser.close()

    def __enter__(self) -> "Link":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _frames(self) -> List[Optional[Tuple[str, int, bytes]]]:
        data = self.ser.read(max(1, self.ser.in_waiting))
        out = []
        for raw in self.reader.feed(data):
            f = parse(raw)
            if f is None and len(self.stray) < 200:
                self.stray += raw
            out.append(f)
        return out

    def _say(self) -> str:
        text = bytes(self.stray).decode("latin-1")
        text = "".join(c if c.isprintable() else " " for c in text).strip()
        return f"it sent {text[:60]!r}" if text else "it sent nothing"

    def hello(self, wait: Optional[float] = None) -> Hello:
        """The runner's hello; TargetError (sample None) when none comes: no runner, other
        firmware, or no board."""
        wait = min(self.timeout, 5.0) if wait is None else wait
        self.ser.reset_input_buffer()
        end = time.monotonic() + wait
        ask = 0.0
        while time.monotonic() < end:
            if time.monotonic() >= ask:
                self.ser.write(frame(b"H", 0))
                ask = time.monotonic() + 0.3
            for f in self._frames():
                if f is not None and f[0] == "h":
                    try:
                        self.hello_ = Hello.decode(f[2])
                    except ValueError:
                        continue
                    if self.hello_.version != VERSION:
                        raise TargetError(
                            f"the board on {self.port} runs the imufuse HIL runner's protocol "
                            f"version {self.hello_.version} (firmware {self.hello_.name!r}); "
                            f"this imufuse speaks version {VERSION}: rebuild the firmware with "
                            "csrc/hil/imf_hil.c and imf_hil.h of this imufuse")
                    if not self.hello_.boot:
                        return self.hello_
        raise TargetError(f"the board on {self.port} runs other firmware or none: no imufuse "
                          f"HIL hello within {wait:g} s ({self._say()})")

    def expect(self, name: str, n_in: int, n_state: int, fixed: bool,
               dtype: Optional[str]) -> Optional[str]:
        """The precision to compare in ("float32", "float64"; dtype for an integer state);
        TargetError when the board's runner serves another layout than the declaration's
        (another firmware: named by the name it gives)."""
        h = self.hello_ or self.hello()
        ints, sizes = {bool(t & 0x100) for t in h.types}, {t & 0xFF for t in h.types}
        if (h.in_dtype is None or h.n_in != n_in or len(h.types) != n_state
                or ints != {fixed} or (not fixed and len(sizes) != 1)):
            raise TargetError(f"the board on {self.port} runs {h.name!r} ({h.layout()}); the "
                              f"firmware declared for {name} has {n_in} inputs and {n_state} "
                              "state words")
        if fixed:
            return dtype
        board = "float32" if sizes == {4} else "float64"
        if dtype and dtype != board:
            raise TargetError(f"the board's state is {board}, asked to compare with {dtype}")
        return board

    def _begin(self) -> None:
        end = time.monotonic() + min(self.timeout, 5.0)
        ask = 0.0
        while time.monotonic() < end:
            if time.monotonic() >= ask:
                self.ser.write(frame(b"B", 0))
                ask = time.monotonic() + 0.3
            for f in self._frames():
                if f is not None and f[0] == "b":
                    return
                if f is not None and f[0] == "n" and f[2][:1] == b"\x04":
                    raise TargetError(
                        f"the board's runner is built with IMF_HIL_MAX_STATE or "
                        f"IMF_HIL_MAX_INPUT smaller than this firmware's state "
                        f"({sum(t & 0xFF for t in self.hello_.types) if self.hello_ else '?'} "
                        "bytes) or sample: raise them (csrc/hil/imf_hil.h)", 0)
        raise TargetError(f"the board on {self.port} does not begin a run (no answer within "
                          f"{min(self.timeout, 5.0):g} s)", 0)

    def run(self, rows: np.ndarray) -> BoardRun:
        """Every sample (rows: (N, n_in) in the hello's input type) through the board."""
        h = self.hello_ or self.hello()
        assert h.in_dtype is not None
        rows = np.ascontiguousarray(rows, dtype=h.in_dtype)
        n = len(rows)
        nbytes = sum(t & 0xFF for t in h.types)
        t0 = time.monotonic()
        self._begin()
        answers: Dict[int, bytes] = {}
        base = nxt = 0
        sent_at: Dict[int, float] = {}
        last_heard = time.monotonic()
        corrupted = 0                   # corrupted frames from the board not yet placed
        named: set = set()
        rewound = (-1, 0.0)
        repeats = 0

        tries: Dict[int, int] = {}

        def send(k: int) -> None:
            tries[k] = tries.get(k, 0) + 1
            if tries[k] > MAX_REPEATS:
                last = self.events[-1] if self.events else "no answer"
                raise TargetError(f"the link failed at sample {k}: sent {MAX_REPEATS} times "
                                  f"without a valid answer (last: {last})", k)
            self.ser.write(frame(b"S", k, rows[k].tobytes()))
            sent_at[k] = time.monotonic()

        def event(k: int, what: str) -> None:
            if (k, what) not in named:
                named.add((k, what))
                self.events.append(f"sample {k}: {what}; sent again, recovered")

        while base < n:
            while nxt < n and nxt < base + h.window:
                send(nxt)
                nxt += 1
            now = time.monotonic()
            for f in self._frames():
                if f is None:
                    corrupted += 1
                    continue
                last_heard = time.monotonic()
                kind, seq, body = f
                k = base + ((seq - base) & 0xFFFF)
                if kind == "h" and Hello.decode(body).boot:
                    raise TargetError(f"the board restarted at sample {base} (its start-up "
                                      "banner arrived during the run)", base)
                if kind == "n":
                    reason = body[0] if body else 1
                    if reason == 3:
                        raise TargetError(f"the board restarted at sample {base} (it answers "
                                          "as after a reset: no run begun)", base)
                    if base <= k < nxt and (rewound[0] != k or now - rewound[1] > REPEAT_AFTER):
                        event(k, f"the board received {NAK_REASONS.get(reason, 'a bad frame')}")
                        rewound = (k, now)
                        repeats += nxt - k
                        nxt = k
                    continue
                if kind != "r" or not base <= k < nxt or len(body) != nbytes + 6:
                    continue
                answers.setdefault(k, body)
                for j in range(base, k):
                    if j not in answers and now - sent_at.get(j, 0.0) > 0.05:
                        event(j, "its answer came back corrupted (CRC)" if corrupted
                              else "its answer was lost")
                        corrupted = max(corrupted - 1, 0)
                        send(j)
                        repeats += 1
                while base in answers:
                    base += 1
            now = time.monotonic()
            if base < n and now - last_heard > self.timeout:
                raise TargetError(f"the board stopped answering at sample {base} (nothing "
                                  f"within {self.timeout:g} s on {self.port})", base)
            if base < nxt and min(now - sent_at.get(base, now), now - last_heard) > REPEAT_AFTER:
                # nothing for the oldest sample: its frame or its answer was lost whole
                event(base, "no answer (a frame lost on the way)" if not corrupted else
                      "its answer came back corrupted (CRC)")
                corrupted = 0
                repeats += nxt - base
                nxt = base
        data = b"".join(answers[k] for k in range(n))
        rec = np.frombuffer(data, dtype=np.uint8).reshape(n, nbytes + 6)
        states, off = [], 0
        for t in h.types:
            size = t & 0xFF
            states.append(_decode_word(rec[:, off:off + size].tobytes(), t))
            off += size
        counts = rec[:, nbytes:nbytes + 4].copy().view("<u4").reshape(n).astype(np.int64)
        stacks = rec[:, nbytes + 4:].copy().view("<u2").reshape(n).astype(np.int64)
        stack = None if (stacks == 0xFFFF).any() or n == 0 else int(stacks.max())
        return BoardRun(states, counts if h.count_unit else None, stack,
                        time.monotonic() - t0, repeats)
