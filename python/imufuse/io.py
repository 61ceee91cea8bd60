"""Log files: reading IMU logs (CSV, NPZ, HDF5) and writing filter outputs.

A CSV log has a header row; columns by name, any order, extra columns ignored:
  time                     s (or ms, us: a unit in the header, or time_unit)
  gyr_x gyr_y gyr_z        rad/s or deg/s
  acc_x acc_y acc_z        g or m/s^2
  mag_x mag_y mag_z        optional, any unit (the filters normalise it)
  q_w q_x q_y q_z          optional reference orientation, sensor -> earth
  movement                 optional mask (0/1) of the samples that count for errors
  rate angle               optional single-axis inputs (rad/s, rad) for the 1D filters

Headers are recognised (`recognise`): imufuse's names, and common spellings,
starting with x-io's ("Time (s)", "Gyroscope X (deg/s)", "Accelerometer X (g)",
"Magnetometer X (uT)"), also gx/gyro_x/accel_x/ax/qw/quat_w ..., in any case.
A unit in parentheses or brackets after the name is read ("(deg/s)", "[m/s^2]").
A column map ({name: header}) names columns explicitly; it wins over recognition.

Units: an explicit gyr_unit / acc_unit (the command line's --gyr-unit,
--acc-unit) wins; else the header's unit; else rad/s and g. A header unit that
contradicts an explicit one gives a warning.

Delimiter (",", ";", tab, "|" or whitespace) and a byte-order mark (UTF-8,
UTF-16) are detected. Decimal commas ("0,25") are read when the delimiter is
not a comma (with a note); with a comma delimiter they are an error that says so.

Values are read with numpy's C parser (numpy.loadtxt); a row that it cannot
read is located again line by line, so errors name the line: "log.csv:7:
column gyr_x: not a number: 'abc'". "nan" and "inf" are numbers (the filters
skip such samples). Time must increase strictly.

Sample period: the filters use the time column's real intervals (Log.dts,
sample k integrated over t[k] - t[k-1]; the first sample over the median
interval), or with a given rate or fixed_rate=True one fixed period: 1/rate,
or 1/(1/median interval rounded to 9 significant digits) (Log.dt).

NPZ / HDF5 logs hold arrays in the layout of the BROAD dataset: gyr (N, 3)
rad/s, acc (N, 3) m/s^2, mag (N, 3) uT, quat_ref (N, 4) sensor -> ENU with
NaN rows, movement (N,) bool, rate () Hz; optionally time (N,) s. The HDF5
files of BROAD name them imu_gyr, imu_acc, imu_mag, opt_quat, movement,
sampling_rate (h5py is needed for HDF5).

Single-axis filters read `rate` and `angle` when both are present; otherwise
they are derived (axis "x": rate = gyr_x, angle = atan2(acc_y, acc_z), the
roll; axis "y": rate = gyr_y, angle = atan2(-acc_x, acc_z), the pitch; both
exact for rotation about that axis alone).
"""
import codecs
import csv
import difflib
import json
import math
import os
import re
from dataclasses import dataclass, field
from typing import Optional

import numpy as np
from imufuse_c._csvout import iter_blocks as _csv_blocks

from ._atomic import replacing
from .plausible import check_log
from ._resources import _path

GRAVITY = 9.80665
GYR = ("gyr_x", "gyr_y", "gyr_z")
ACC = ("acc_x", "acc_y", "acc_z")
MAG = ("mag_x", "mag_y", "mag_z")
QUAT = ("q_w", "q_x", "q_y", "q_z")
KNOWN = ("time", *GYR, *ACC, *MAG, *QUAT, "movement", "rate", "angle")
GYR_UNITS = {"rad/s": 1.0, "deg/s": math.pi / 180.0}
ACC_UNITS = {"g": 1.0, "m/s2": 1.0 / GRAVITY, "m/s^2": 1.0 / GRAVITY}
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
#: how unit spellings in headers are read
_UNIT_SPELLINGS = {
    "rad/s": "rad/s", "rads": "rad/s", "rad/sec": "rad/s", "radians/s": "rad/s",
    "deg/s": "deg/s", "dps": "deg/s", "°/s": "deg/s", "degrees/s": "deg/s", "deg/sec": "deg/s",
    "g": "g", "gee": "g",
    "m/s^2": "m/s^2", "m/s2": "m/s^2", "m/s²": "m/s^2", "m/s/s": "m/s^2", "ms^-2": "m/s^2",
    "ut": "uT", "µt": "uT", "μt": "uT", "microtesla": "uT", "gauss": "gauss", "mg": "mgauss",
    "nt": "nT", "au": "a.u.", "a.u.": "a.u.",
    "s": "s", "sec": "s", "seconds": "s", "ms": "ms", "us": "us", "µs": "us", "μs": "us",
    "ns": "ns",
}
_KIND_UNITS = {"gyr": GYR_UNITS, "acc": ACC_UNITS, "time": TIME_UNITS}

# recognised header names (normalised: lower case, unit removed, runs of
# space/-/./: turned into "_")
_ALIASES = {"time": ["time", "t", "timestamp", "time_s", "times", "seconds", "sec"],
            "movement": ["movement", "moving", "mask"],
            "rate": ["rate"], "angle": ["angle"]}
for _ax in "xyz":
    _ALIASES[f"gyr_{_ax}"] = [f"gyr_{_ax}", f"gyro_{_ax}", f"gyroscope_{_ax}", f"g{_ax}",
                              f"gyr{_ax}", f"gyro{_ax}", f"w{_ax}", f"omega_{_ax}",
                              f"angular_velocity_{_ax}", f"rot_{_ax}", f"gyroscope{_ax}"]
    _ALIASES[f"acc_{_ax}"] = [f"acc_{_ax}", f"accel_{_ax}", f"accelerometer_{_ax}",
                              f"acceleration_{_ax}", f"a{_ax}", f"acc{_ax}", f"accel{_ax}",
                              f"accelerometer{_ax}"]
    _ALIASES[f"mag_{_ax}"] = [f"mag_{_ax}", f"magn_{_ax}", f"magnetometer_{_ax}",
                              f"magnetic_field_{_ax}", f"m{_ax}", f"mag{_ax}",
                              f"magnetometer{_ax}"]
for _c in "wxyz":
    _ALIASES[f"q_{_c}"] = [f"q_{_c}", f"q{_c}", f"quat_{_c}", f"quaternion_{_c}",
                           f"quat{_c}", f"ref_q_{_c}", f"q_ref_{_c}", f"quat_ref_{_c}"]
_RECOGNISE = {a: canon for canon, names in _ALIASES.items() for a in names}


class LogError(ValueError):
    """A log that cannot be used; `kind` is "file" (missing, unreadable),
    "data" (columns, values, time) or "usage" (a bad column map)."""

    def __init__(self, message, kind="data"):
        super().__init__(message)
        self.kind = kind


@dataclass
class Log:
    path: str
    columns: dict                 # known column name -> (N,) float64, units converted
    header: list                  # every column of the file, in order
    dt: Optional[float] = None    # fixed sample period (median interval or 1/rate), s
    warnings: list = field(default_factory=list)
    sources: dict = field(default_factory=dict)   # known name -> header it came from
    units: dict = field(default_factory=dict)     # "gyr"/"acc"/"mag"/"time" -> (unit, where from)
    fixed_rate: bool = True       # True: every sample at dt; False: dts (the time column)
    ref_frame: Optional[str] = None  # frame of q_w..q_z when the format says (BROAD: "ENU")
    suspicions: list = field(default_factory=list)  # the plausibility warnings (also in warnings)

    def __len__(self):
        return len(next(iter(self.columns.values()))) if self.columns else 0

    def has(self, *names):
        return all(n in self.columns for n in names)

    def vec(self, names):
        return np.column_stack([self.columns[n] for n in names])

    def _cached(self, key, names, make):
        """make() computed once while the columns it reads (the same array objects), dt and
        fixed_rate stay as they were; read-only, since every access shares it. A column
        replaced (imufuse.preprocess) or dt changed gives a new array."""
        cache = self.__dict__.get("_cache")
        if cache is None:
            cache = self.__dict__["_cache"] = {}
        hit = cache.get(key)
        cols = self.columns
        if hit is not None:
            (arrays, dt, fixed), value = hit
            if dt == self.dt and fixed == self.fixed_rate:
                for n, a in zip(names, arrays):
                    if cols.get(n) is not a:
                        break
                else:
                    return value
        token = (tuple(cols.get(n) for n in names), self.dt, self.fixed_rate)
        value = make()
        if isinstance(value, np.ndarray):
            value.flags.writeable = False
        cache[key] = (token, value)
        return value

    @property
    def t(self):
        """Sample times, s: the time column, else k * dt."""
        if "time" in self.columns:
            return self.columns["time"]
        return self._cached("t", (), lambda: np.arange(len(self)) * self.dt)

    @property
    def dts(self):
        """Per-sample periods (N,), s: None at a fixed rate, else the time
        column's intervals (the first sample: the median interval, dt)."""
        if self.fixed_rate or "time" not in self.columns:
            return None

        def make():
            d = np.empty(len(self))
            d[0] = self.dt
            np.subtract(self.columns["time"][1:], self.columns["time"][:-1], out=d[1:])
            return d
        return self._cached("dts", ("time",), make)

    @property
    def gyr(self):
        """(N, 3) gyroscope, rad/s (computed once; read-only)."""
        return self._cached("gyr", GYR, lambda: self.vec(GYR))

    @property
    def acc(self):
        """(N, 3) accelerometer, g (computed once; read-only)."""
        return self._cached("acc", ACC, lambda: self.vec(ACC))

    @property
    def mag(self):
        """(N, 3) magnetometer, or None (computed once; read-only)."""
        return self._cached("mag", MAG, lambda: self.vec(MAG) if self.has(*MAG) else None)

    @property
    def q_ref(self):
        """(N, 4) reference quaternion w, x, y, z, or None (computed once; read-only)."""
        return self._cached("q_ref", QUAT, lambda: self.vec(QUAT) if self.has(*QUAT) else None)

    @property
    def movement(self):
        m = self.columns.get("movement")
        return None if m is None else m != 0


# ---------------------------------------------------------------------------
# header recognition

_UNIT_RE = re.compile(r"^(.*?)\s*[\(\[]\s*([^\)\]]*?)\s*[\)\]]\s*$")


def split_unit(header):
    """'Gyroscope X (deg/s)' -> ('Gyroscope X', 'deg/s'); no unit -> (header, None).
    The unit is given in its canonical spelling when known, else as written."""
    m = _UNIT_RE.match(header.strip())
    if not m:
        return header.strip(), None
    name, unit = m.group(1), m.group(2)
    return name, _UNIT_SPELLINGS.get(unit.lower().replace(" ", ""), unit)


def _norm(name):
    return re.sub(r"[\s\-\.:/]+", "_", name.strip().lower()).strip("_")


def recognise(header):
    """{known name: header index} for the headers imufuse recognises. When
    several headers could be one column, the closer spelling wins (`time`
    before `t`); a header whose unit belongs to another quantity ("T (degC)")
    is not taken for time."""
    best = {}
    for i, h in enumerate(header):
        name, unit = split_unit(h)
        canon = _RECOGNISE.get(_norm(name))
        if canon is None:
            continue
        if canon == "time" and unit is not None and unit not in TIME_UNITS:
            continue
        rank = _ALIASES[canon].index(_norm(name))
        if canon not in best or rank < best[canon][0]:
            best[canon] = (rank, i)
    return {k: i for k, (r, i) in best.items()}


def read_csv_rows(path):
    """The non-blank rows of a small text CSV file (calibrate, vario), as lists of cells;
    LogError naming the file for a file that is not text (a binary file, another encoding,
    NUL bytes) or that does not exist."""
    path = os.fspath(path)
    if not os.path.exists(path):
        raise LogError(f"{path}: no such file", "file")
    try:
        with open(path, newline="", encoding="utf-8") as fh:
            return [r for r in csv.reader(fh) if any(c.strip() for c in r)]
    except UnicodeDecodeError as e:
        raise LogError(f"{path}: not a UTF-8 text CSV log (byte {e.start}: {e.reason}); "
                       "save it as UTF-8 text") from None
    except csv.Error as e:
        raise LogError(f"{path}: not a CSV log ({e})") from None
    except IsADirectoryError:
        raise LogError(f"{path}: is a directory, not a log file", "file") from None


def duplicate_columns(header):
    """{known name: [header indices]} for names that two or more headers spell equally
    closely (e.g. 'gyr_x' twice): recognise() cannot choose between them."""
    seen = {}
    for i, h in enumerate(header):
        name, unit = split_unit(h)
        canon = _RECOGNISE.get(_norm(name))
        if canon is None or (canon == "time" and unit is not None and unit not in TIME_UNITS):
            continue
        seen.setdefault((canon, _ALIASES[canon].index(_norm(name))), []).append(i)
    best = recognise(header)
    return {c: idx for (c, r), idx in seen.items() if len(idx) > 1 and best.get(c) in idx}


def parse_column_map(text):
    """'gyr_x="Gyroscope X (deg/s)",gyr_y=...' -> {name: header}."""
    out = {}
    for item in next(csv.reader([text], skipinitialspace=True)) if text.strip() else ():
        if not item.strip():
            continue
        if "=" not in item:
            raise LogError(f"column map {item!r}: expected NAME=HEADER (e.g. "
                           'gyr_x="Gyroscope X (deg/s)")', "usage")
        k, v = item.split("=", 1)
        out[k.strip()] = v.strip().strip('"').strip("'")
    return out


def read_column_map(path):
    """A mapping file: a JSON object {name: header}, or lines NAME = HEADER
    ('#' starts a comment)."""
    try:
        with open(path, encoding="utf-8-sig") as fh:
            text = fh.read()
    except (OSError, UnicodeDecodeError) as e:
        raise LogError(f"{path}: cannot read the column map: {e}", "file") from None
    if text.lstrip().startswith("{"):
        try:
            m = json.loads(text)
        except ValueError as e:
            raise LogError(f"{path}: not a JSON column map: {e}") from None
        if not isinstance(m, dict) or not all(isinstance(v, str) for v in m.values()):
            raise LogError(f"{path}: the JSON column map must be an object of name: header strings")
        return dict(m)
    out = {}
    for ln, line in enumerate(text.splitlines(), 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        if "=" not in line:
            raise LogError(f"{path}:{ln}: expected NAME = HEADER, got {line!r}")
        k, v = line.split("=", 1)
        out[k.strip()] = v.strip().strip('"').strip("'")
    return out


def _close(name, candidates):
    return difflib.get_close_matches(name, candidates, n=2, cutoff=0.6)


def _apply_map(path, header, found, column_map):
    for k, h in column_map.items():
        if k not in KNOWN:
            c = _close(k, KNOWN)
            raise LogError(f"column map: {k!r} is not a log column"
                           + (f" (did you mean {' or '.join(map(repr, c))}?)" if c else "")
                           + f"; expected one of {', '.join(KNOWN)}", "usage")
        if h not in header:
            stripped = [x for x in header if x.strip().lower() == h.strip().lower()]
            if len(stripped) == 1:
                h = stripped[0]
            else:
                c = _close(h, header)
                raise LogError(f"{path}: column map {k}={h!r}: no such column in the header"
                               + (f" (did you mean {' or '.join(map(repr, c))}?)" if c else "")
                               + f"; columns found: {', '.join(map(repr, header))}")
        found[k] = header.index(h)
    return found


def _missing(names, header, used=()):
    msgs = []
    unknown = [h for h in header if h not in used]
    for n in names:
        lower = [h for h in unknown if h.strip().lower() == n]
        close = lower or _close(n, unknown) or _close(n, [_norm(split_unit(h)[0]) for h in unknown])
        if close and close[0] not in header:          # matched on a normalised name
            close = [h for h in unknown if _norm(split_unit(h)[0]) in close]
        msgs.append(f"{n}" + (f" (did you mean {' or '.join(repr(c) for c in close)}?)"
                              if close else ""))
    return msgs


def require(log, names, why=""):
    """LogError naming every missing column of `names`, with close matches."""
    miss = [n for n in names if n not in log.columns]
    if miss:
        raise LogError(f"{log.path}: missing column{'s' if len(miss) > 1 else ''} "
                       f"{', '.join(_missing(miss, log.header, set(log.sources.values())))}"
                       f"{' ' + why if why else ''}; columns found: "
                       f"{', '.join(map(repr, log.header))} (name columns with --columns "
                       f'NAME="HEADER", e.g. gyr_x="Gyro X")')


# ---------------------------------------------------------------------------
# CSV format detection

_BOMS = ((codecs.BOM_UTF8, "utf-8-sig"), (codecs.BOM_UTF16_LE, "utf-16"),
         (codecs.BOM_UTF16_BE, "utf-16"))
_DELIMS = (",", ";", "\t", "|")
_DEC_COMMA = re.compile(r"^\s*[-+]?\d+,\d+(?:[eE][-+]?\d+)?\s*$")


def _nul_tail_start(path, block=1 << 20):
    """Where the run of NUL bytes that ends the file starts (the file's size when it does not
    end in NUL): SD-card loggers preallocate their files and fill them from the start. The
    last block holding text is found by galloping back from the end, then bisecting, in
    blocks: a few reads and constant memory whatever the tail's length (the caller only sizes
    its buffers from this; the reader itself stops at the first NUL)."""
    size = os.path.getsize(path)
    with open(path, "rb") as fh:
        def text_end(k):
            """The end of the text in block k (its last non-NUL byte + 1), or 0."""
            fh.seek(k * block)
            return len(fh.read(block).rstrip(b"\0"))

        last = (size - 1) // block if size else -1
        if last < 0:
            return 0
        if text_end(last):
            return last * block + text_end(last)
        # gallop: blocks last - 1, last - 2, last - 4, ... until one holds text
        hi, step = last, 1            # block hi is all NUL
        lo = -1
        while hi - step >= 0:
            k = hi - step
            if text_end(k):
                lo = k
                break
            hi, step = k, step * 2
        if lo < 0:
            if text_end(0):
                lo = 0
            else:
                return 0
        # bisect between lo (text) and hi (all NUL)
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if text_end(mid):
                lo = mid
            else:
                hi = mid
        return lo * block + text_end(lo)


def _lines_until_nul(fh, state, max_line=1 << 20):
    """The text lines of fh up to the first NUL byte, read in pieces (a NUL-filled tail has no
    newline to end a line): memory bounded by max_line, not by the file. state gets "nul"
    (lines read before it) and "cut" (a partial row dropped before it)."""
    buf = ""
    n = 0
    while True:
        piece = fh.readline(1 << 16)
        if not piece:
            if buf:
                yield buf
            return
        k = piece.find("\0")
        if k >= 0:
            buf += piece[:k]
            state["nul"] = n
            if buf.strip():
                state["cut"] = buf.strip()[:40]
            return
        buf += piece
        if buf.endswith("\n") or buf.endswith("\r"):
            n += 1
            yield buf
            buf = ""
        elif len(buf) > max_line:
            raise LogError(f"a line longer than {max_line} characters after data line {n}: "
                           "not a CSV log")


def _open_text(path):
    """(encoding, first lines) of a text file; LogError when it is not one."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(1 << 16)
    except IsADirectoryError:
        raise LogError(f"{path}: is a directory, not a log file", "file") from None
    except OSError as e:
        raise LogError(f"{path}: cannot read: {e.strerror or e}", "file") from None
    enc = "utf-8"
    for bom, name in _BOMS:
        if head.startswith(bom):
            enc = name
            break
    if enc == "utf-8" and b"\0" in head:
        k = head.index(b"\0")
        if k > 0 and not head[k:].strip(b"\0") and _nul_tail_start(path) <= k:
            head = head[:k]          # a preallocated file: text, then only NUL to the end
    if enc == "utf-8" and b"\0" in head:
        raise LogError(f"{path}: not a text (CSV) log: it contains NUL bytes "
                       "(expected a header row of column names)")
    try:
        text = head.decode(enc)
    except UnicodeDecodeError as e:
        # a multi-byte character cut at the end of the block is fine
        if e.start < len(head) - 4 or len(head) < (1 << 16):
            raise LogError(f"{path}: not {enc.upper()} text at byte {e.start} (expected a CSV "
                           "log; save it as UTF-8)") from None
        text = head[:e.start].decode(enc)
    return enc, text.splitlines()


def _sniff(lines):
    """(delimiter or None for whitespace, header fields)."""
    first = next((ln for ln in lines if ln.strip()), "")
    best, fields = ",", None
    for d in _DELIMS:
        f = next(csv.reader([first], delimiter=d))
        if fields is None or len(f) > len(fields):
            best, fields = d, f
    if len(fields) == 1 and len(first.split()) > 1:
        return None, first.split()
    return best, fields


# ---------------------------------------------------------------------------
# reading

def _numbers_slow(path, enc, delim, header_line, idx, decimal_comma, loader_error):
    """Locate a bad row line by line (only after the fast reader failed); raise
    LogError naming the line. loader_error: the fast reader's message."""
    names = {i: h for h, i in idx.items()}
    ncol = None
    csv.field_size_limit(1 << 24)
    with open(path, newline="", encoding=enc) as fh:
        for _ in range(header_line):
            fh.readline()
        lines = _lines_until_nul(fh, {})          # never into a NUL-filled tail
        if delim is None:
            rows = ((ln.split()) for ln in lines)
            reader = None
        else:
            reader = csv.reader(lines, delimiter=delim)
            rows = reader
        ln = header_line
        try:
            for r in rows:
                ln = reader.line_num + header_line if reader is not None else ln + 1
                if not any(c.strip() for c in r) or r[0].lstrip().startswith("#"):
                    continue
                if ncol is None:
                    ncol = len(r)
                if len(r) <= max(idx.values()):
                    raise LogError(f"{path}:{ln}: {len(r)} values, the header has "
                                   f"{max(idx.values()) + 1 if ncol is None else ncol} columns")
                for i, name in names.items():
                    s = r[i].strip()
                    if decimal_comma:
                        s = s.replace(",", ".")
                    try:
                        float(s)
                    except ValueError:
                        if len(s) > 60:
                            s = s[:60] + "..."
                        raise LogError(f"{path}:{ln}: column {name}: not a number: {s!r}") from None
        except csv.Error as e:
            raise LogError(f"{path}:{ln + 1}: unreadable CSV: {e}") from None
    raise LogError(f"{path}: cannot read the values: {loader_error}")


_BLOCK = 100_000


def _no_extra_values(lines, delim, width, first):
    """The lines, each checked to hold at most ``width`` values (a trailing delimiter
    allowed): a row with more values than the header has columns is shifted or damaged, and
    reading its first columns would give numbers from the wrong columns. ``first``: the line
    number of the first line."""
    for i, ln in enumerate(lines):
        s = ln.rstrip()
        if s.endswith(delim):
            s = s[:-1]
        if s.count(delim) >= width and '"' not in s and not s.lstrip().startswith("#"):
            raise LogError(f"line {first + i}: {s.count(delim) + 1} values under a header of "
                           f"{width} columns")
        yield ln


def _loadtxt_blocks(fh, delim, usecols, rows_hint):
    """numpy.loadtxt block by block into one array sized from the file
    (numpy's reader grows its own buffer: read at once, a long log would
    need about twice its size in memory)."""
    import warnings
    out, n = None, 0
    while True:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)      # "input contained no data" at EOF
            a = np.loadtxt(fh, delimiter=delim, usecols=usecols, ndmin=2, dtype=np.float64,
                           quotechar='"', comments="#", max_rows=_BLOCK)
        if out is None:
            out = np.empty((max(rows_hint, len(a), 1), len(usecols)))
        if n + len(a) > len(out):
            grown = np.empty((max(2 * len(out), n + len(a)), len(usecols)))
            grown[:n] = out[:n]
            out = grown
        out[n:n + len(a)] = a
        n += len(a)
        if len(a) < _BLOCK:
            return out[:n]


def _read_csv(path, column_map, time_unit):
    enc, lines = _open_text(path)
    if not lines or not any(ln.strip() for ln in lines):
        raise LogError(f"{path}: empty file (expected a header row of column names, "
                       "e.g. time,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z)")
    header_line = next(i for i, ln in enumerate(lines) if ln.strip()) + 1
    delim, header = _sniff(lines)
    header = [h.strip() for h in header]
    data = [ln for ln in lines[header_line:header_line + 50] if ln.strip()]
    notes = []
    found = recognise(header)
    for canon, idx in duplicate_columns(header).items():
        if not column_map or canon not in column_map:
            raise LogError(f"{path}: columns {' and '.join(str(i + 1) for i in idx)} are both "
                           f"{canon} ({', '.join(repr(header[i]) for i in idx)}); name the one "
                           f'to use with --columns {canon}="HEADER"')
    if column_map:
        found = _apply_map(path, header, found, column_map)
    if not found:
        numeric = all(re.fullmatch(r"[-+0-9.eE]+", h or "x") for h in header)
        raise LogError(f"{path}: no known column in the header "
                       f"{', '.join(map(repr, header[:12]))}{' ...' if len(header) > 12 else ''}"
                       + (" (the first row holds numbers: the log needs a header row)"
                          if numeric else "")
                       + "; expected time, gyr_x..z, acc_x..z[, mag_x..z, q_w..q_z] or "
                       "headers such as 'Gyroscope X (deg/s)'; name columns with --columns "
                       'NAME="HEADER"')
    decimal_comma = False
    if data:
        cells = (next(csv.reader([data[0]], delimiter=delim)) if delim else data[0].split())
        dc = [c for c in cells if _DEC_COMMA.match(c)]
        if delim != "," and dc:
            decimal_comma = True
            notes.append(f"decimal commas ({dc[0]!r}) read as decimal points")
        elif delim == "," and len(cells) > len(header) and any(
                re.fullmatch(r"\s*[-+]?\d+", c) for c in cells[1:]):
            raise LogError(f"{path}:{header_line + 1}: {len(cells)} values under a header of "
                           f"{len(header)} columns: decimal commas (e.g. '0,25') cannot be told "
                           "from the comma delimiter; write the log with a decimal point, or with "
                           "';' or tabs between the values")
    usecols = sorted(set(found.values()))
    nul_state: dict = {}
    try:
        with open(path, encoding=enc, newline="") as fh:
            for _ in range(header_line):
                fh.readline()
            if decimal_comma:
                M = np.loadtxt((ln.replace(",", ".") for ln in fh), delimiter=delim,
                               usecols=usecols, ndmin=2, dtype=np.float64, quotechar='"',
                               comments="#")
            else:
                width = len(data[0]) + 1 if data else 64     # bytes per row, first row
                # sized from the text, not from a NUL-filled tail of a preallocated file
                rows = int(_nul_tail_start(path) / max(width, 8) * 1.05)
                lines_in = _lines_until_nul(fh, nul_state)
                if delim:
                    lines_in = _no_extra_values(lines_in, delim, len(header), header_line + 1)
                M = _loadtxt_blocks(lines_in, delim, usecols, rows)
    except LogError as e:
        raise LogError(f"{path}: {e}") from None
    except (ValueError, IndexError) as e:
        _numbers_slow(path, enc, delim, header_line, found, decimal_comma, e)
    except MemoryError:
        raise LogError(f"{path}: too large to read into memory") from None
    except (OSError, UnicodeDecodeError) as e:
        raise LogError(f"{path}: cannot read: {e}", "file") from None
    if "nul" in nul_state:
        notes.append(f"the file ends in NUL bytes after line "
                     f"{header_line + nul_state['nul']} (a preallocated file): read up to there"
                     + (f"; a row cut by them was dropped ({nul_state['cut']!r})"
                        if "cut" in nul_state else ""))
    if M.shape[0] == 0:
        raise LogError(f"{path}: no data rows after the header")
    # columns are views of the one array the reader made (no copies: long logs
    # stay small in memory); run() inputs are stacked from them as needed
    cols = {k: M[:, usecols.index(i)] for k, i in found.items()}
    sources = {k: header[i] for k, i in found.items()}

    def where(k):
        """'path:LINE' of data row k (counted again from the file: errors only)."""
        n = -1
        with open(path, encoding=enc, newline="") as fh:
            for ln, line in enumerate(fh, 1):
                if ln <= header_line or not line.split("#", 1)[0].strip():
                    continue
                n += 1
                if n == k:
                    return f"{path}:{ln}"
        return f"{path}: sample {k}"
    return cols, header, sources, notes, where


def _first(z, *keys):
    for k in keys:
        if k in z:
            return np.asarray(z[k])
    return None


#: the arrays (and rate keys) a log in the BROAD layout may hold
_ARRAY_KEYS = ("gyr", "imu_gyr", "acc", "imu_acc", "mag", "imu_mag", "quat_ref", "opt_quat",
               "q_ref", "movement", "time", "t", "rate", "sampling_rate")


def _read_arrays(path):
    """NPZ or HDF5 in the BROAD layout -> (columns, header, sources, rate)."""
    ext = os.path.splitext(path)[1].lower()
    if ext == ".npz":
        try:
            z = dict(np.load(path, allow_pickle=False))
        except Exception as e:     # a damaged archive raises many kinds of error
            raise LogError(f"{path}: not a readable NPZ archive: {e}") from None
    else:
        try:
            import h5py
        except ImportError:
            raise LogError(f"{path}: HDF5 logs need h5py: pip install 'imufuse[hdf5]'",
                           "file") from None
        try:
            with h5py.File(path, "r") as f:
                # only the datasets a log uses (a file may hold others, of any size), and the
                # file's attributes: BROAD as published states its rate as `sampling_rate`
                z = {}
                for k in _ARRAY_KEYS:
                    try:
                        if k in f and isinstance(f[k], h5py.Dataset):
                            z[k] = np.asarray(f[k])
                    except Exception as e:  # noqa: BLE001 - a link to a missing file, a null
                        # dataspace, a damaged dataset: h5py raises many kinds of error
                        raise LogError(f"{path}: dataset {k!r} cannot be read: "
                                       f"{type(e).__name__}: {e}") from None
                for k in ("rate", "sampling_rate"):
                    if k not in z and k in f.attrs:
                        z[k] = np.asarray(f.attrs[k])
                keys_in_file = sorted(f.keys())
        except LogError:
            raise
        except Exception as e:  # noqa: BLE001 - not HDF5, or damaged
            raise LogError(f"{path}: not a readable HDF5 file: {e}") from None
        if not {"gyr", "imu_gyr"} & set(z) or not {"acc", "imu_acc"} & set(z):
            raise LogError(f"{path}: expected arrays gyr and acc (N, 3) (BROAD layout: imu_gyr, "
                           f"imu_acc, imu_mag, opt_quat, movement, attribute sampling_rate); "
                           f"found {', '.join(keys_in_file) or 'none'}")
    keys = sorted(z)
    parts = {"gyr": _first(z, "gyr", "imu_gyr"), "acc": _first(z, "acc", "imu_acc"),
             "mag": _first(z, "mag", "imu_mag"), "quat": _first(z, "quat_ref", "opt_quat", "q_ref"),
             "movement": _first(z, "movement"), "time": _first(z, "time", "t"),
             "rate": _first(z, "rate", "sampling_rate")}
    if parts["gyr"] is None or parts["acc"] is None:
        raise LogError(f"{path}: expected arrays gyr and acc (N, 3) (BROAD layout: gyr, acc, mag, "
                       f"quat_ref, movement, rate); found {', '.join(keys) or 'none'}")
    for kind, a in parts.items():
        if a is not None and a.dtype.kind not in "biuf":
            raise LogError(f"{path}: array {kind} holds {a.dtype} values; expected numbers")
    if parts["gyr"].ndim != 2:
        raise LogError(f"{path}: array gyr has shape {parts['gyr'].shape}; expected (N, 3)")
    n = len(parts["gyr"])
    cols, sources = {}, {}
    for kind, names, width in (("gyr", GYR, 3), ("acc", ACC, 3), ("mag", MAG, 3),
                               ("quat", QUAT, 4)):
        a = parts[kind]
        if a is None:
            continue
        if a.ndim != 2 or a.shape != (n, width):
            raise LogError(f"{path}: array {kind} has shape {a.shape}; expected ({n}, {width})")
        for j, c in enumerate(names):
            cols[c] = np.ascontiguousarray(a[:, j], dtype=np.float64)
            sources[c] = f"{kind} column {j}"
    for kind in ("movement", "time"):
        a = parts[kind]
        if a is not None:
            if a.shape != (n,):
                raise LogError(f"{path}: array {kind} has shape {a.shape}; expected ({n},)")
            cols[kind] = a.astype(np.float64)
            sources[kind] = kind
    rate = parts["rate"]
    if rate is not None:
        if rate.size != 1:
            raise LogError(f"{path}: rate has {rate.size} values (shape {rate.shape}); expected "
                           "one sample rate in Hz")
        rate = float(rate.reshape(-1)[0])
        if not (math.isfinite(rate) and rate > 0 and math.isfinite(1.0 / rate)):
            raise LogError(f"{path}: rate is {rate!r}; expected a finite sample rate > 0 Hz")
    return cols, keys, sources, rate


def _units(cols, sources, kind, names, given, table, default, warnings):
    """Resolve the unit of `names` (given > header > default); convert in place.
    Returns (unit, where from)."""
    header_units = {split_unit(sources[n])[1] for n in names if n in sources}
    header_units.discard(None)
    known = {u for u in header_units if u in table or (kind == "acc" and u == "m/s^2")}
    if len(known) > 1:
        raise LogError(f"columns {', '.join(names)} have different units in the header: "
                       f"{', '.join(sorted(known))}")
    unknown = header_units - known
    if given is not None:
        unit, why = given, "given"
        if known and given.replace("m/s2", "m/s^2") not in {k.replace("m/s2", "m/s^2")
                                                             for k in known}:
            warnings.append(f"{kind} unit {given} given, the header says {known.pop()}: "
                            f"using {given}")
    elif known:
        unit, why = known.pop(), "header"
    else:
        if unknown and kind in ("gyr", "acc"):
            raise LogError(f"unknown {kind} unit {unknown.pop()!r} in the header; expected one of "
                           f"{', '.join(table)} (or give --{kind}-unit)")
        unit, why = default, "default"
    f = table[unit]
    if f != 1.0:
        for n in names:
            if n in cols:
                cols[n] = cols[n] * f
    return unit, why


def read_log(path, gyr_unit=None, acc_unit=None, rate=None, *, columns=None,
             fixed_rate=False, time_unit=None, need_time=True):
    """Read a log; return a Log with units converted (gyro rad/s, acc g, time s).

    gyr_unit, acc_unit, time_unit: None to take them from the header (else rad/s,
    g, s); rate: Hz, a fixed sample rate (the time column is then not needed);
    columns: {name: header} column map; fixed_rate: run at the median interval
    even when the time column is there; need_time=False: a log without a time column
    or rate is read with dt None (for calibration, which needs no time)."""
    user_rate = rate
    if gyr_unit is not None and gyr_unit not in GYR_UNITS:
        raise ValueError(f"gyr_unit: must be one of {', '.join(GYR_UNITS)}, got {gyr_unit!r}")
    if acc_unit is not None and acc_unit not in ACC_UNITS:
        raise ValueError(f"acc_unit: must be one of g, m/s2, got {acc_unit!r}")
    if time_unit is not None and time_unit not in TIME_UNITS:
        raise ValueError(f"time_unit: must be one of {', '.join(TIME_UNITS)}, got {time_unit!r}")
    if rate is not None and not (isinstance(rate, (int, float)) and math.isfinite(rate)
                                 and 0 < rate <= 1e9 and 1.0 / rate > 0):
        raise ValueError(f"rate: must be a positive number of Hz (at most 1e9), got {rate!r}")
    path = os.fspath(path)
    if not os.path.exists(path):
        raise LogError(f"{path}: no such file", "file")
    if os.path.isdir(path):
        raise LogError(f"{path}: is a directory, not a log file", "file")
    ext = os.path.splitext(path)[1].lower()
    warnings, ref_frame, file_rate = [], None, None
    if ext in (".npz", ".h5", ".hdf5", ".hdf"):
        cols, header, sources, file_rate = _read_arrays(path)
        where = lambda k: f"{path}: sample {k}"  # noqa: E731
        ref_frame = "ENU" if "q_w" in cols else None
        default_acc = "m/s^2"
    else:
        cols, header, sources, notes, where = _read_csv(path, columns, time_unit)
        warnings += notes
        default_acc = "g"
    log = Log(path, cols, list(header), sources=sources, ref_frame=ref_frame)
    if len(log) == 0:
        raise LogError(f"{path}: no samples (every array of the log has 0 rows)")
    try:
        log.units["gyr"] = _units(cols, sources, "gyr", GYR, gyr_unit, GYR_UNITS, "rad/s", warnings)
        log.units["acc"] = _units(cols, sources, "acc", ACC, acc_unit, ACC_UNITS, default_acc,
                                  warnings)
        log.units["time"] = _units(cols, sources, "time", ("time",), time_unit, TIME_UNITS, "s",
                                   warnings)
    except LogError as e:
        raise LogError(f"{path}: {e}") from None
    mu = {split_unit(sources[n])[1] for n in MAG if n in sources} - {None}
    log.units["mag"] = (mu.pop() if len(mu) == 1 else ("uT" if ext == ".npz" else "any"), "header")
    if "movement" in cols:
        m = cols["movement"]
        if not np.all(np.isin(m, (0.0, 1.0))):
            k = int(np.argmax(~np.isin(m, (0.0, 1.0))))
            raise LogError(f"{where(k)}: movement must be 0 or 1, got {m[k]!r}")
    if "time" in cols:
        t = cols["time"]
        if not np.all(np.isfinite(t)):
            k = int(np.argmax(~np.isfinite(t)))
            raise LogError(f"{where(k)}: time is not finite: {float(t[k])!r}")
        with np.errstate(over="ignore", invalid="ignore"):
            d = np.diff(t)
        if np.any(~(d > 0)):
            k = int(np.argmax(~(d > 0))) + 1
            raise LogError(f"{where(k)}: time does not increase "
                           f"({float(t[k - 1])!r} then {float(t[k])!r}); times must increase "
                           "strictly")
        if not np.all(np.isfinite(d)):
            k = int(np.argmax(~np.isfinite(d))) + 1
            raise LogError(f"{where(k)}: the interval from {float(t[k - 1])!r} to "
                           f"{float(t[k])!r} s is not a finite number")
    time_cols = cols.get("time")      # the file's own times, before a rate generates any
    if rate is None and file_rate is not None and "time" not in cols:
        rate = file_rate
    if rate is not None:
        log.dt = 1.0 / rate
        log.fixed_rate = True
        if "time" not in cols:
            cols["time"] = np.arange(len(log)) * log.dt
            log.sources["time"] = f"k / {rate:g} Hz"
    elif "time" in cols:
        if d.size == 0:
            raise LogError(f"{path}: one sample: cannot derive the rate from time; give --rate")
        med = float(np.median(d))
        # decimal time stamps rarely difference to the exact period: the rate
        # is 1/median rounded to 9 significant digits (100 Hz, not 99.99999999999991)
        r = float(f"{1.0 / med:.9g}")
        if not (math.isfinite(r) and r > 0 and math.isfinite(1.0 / r) and 1.0 / r > 0):
            raise LogError(f"{path}: median sample interval {med!r} s gives no usable rate")
        log.dt = 1.0 / r
        log.fixed_rate = bool(fixed_rate)
        if np.max(np.abs(d - med)) > 0.2 * med:
            warnings.append(f"sample intervals vary from {d.min():.6g} to {d.max():.6g} s; "
                            + (f"the filters use the median {log.dt:.6g} s (--fixed-rate)"
                               if fixed_rate else "the filters use each sample's own interval"))
    elif not need_time:
        log.dt = None
    else:
        raise LogError(f"{path}: no time column (found {', '.join(map(repr, header[:12]))}); "
                       "give the sample rate (--rate HZ), or name the time column "
                       '(--columns time="HEADER")')
    # the usual unit and rate mistakes, named with the option that fixes them
    log.suspicions = check_log(log, user_rate, file_rate, time_cols)
    warnings += log.suspicions
    log.warnings = warnings
    return log


def describe(log):
    """One line: what was read from where, with units."""
    parts = []
    for kind, names in (("gyr", GYR), ("acc", ACC), ("mag", MAG), ("q", QUAT)):
        if log.has(*names):
            src = [log.sources.get(n, n) for n in names]
            u = log.units.get(kind)
            unit = f" [{u[0]}, {u[1]}]" if u else ""
            same = all(s == n for s, n in zip(src, names))
            parts.append(f"{kind}{unit}" + ("" if same else f" from {src[0]!r}..."))
    return ", ".join(parts)


def axis_inputs(log, axis="x"):
    """(rate, angle, source) for the single-axis filters (see the module doc)."""
    if log.has("rate", "angle"):
        return log.columns["rate"], log.columns["angle"], "columns rate, angle"
    if axis == "x":
        need = ("gyr_x", "acc_y", "acc_z")
        require(log, need, "(single-axis filters need rate and angle, or gyr_x, acc_y, acc_z)")
        c = log.columns
        return c["gyr_x"], np.arctan2(c["acc_y"], c["acc_z"]), "gyr_x, atan2(acc_y, acc_z)"
    if axis == "y":
        need = ("gyr_y", "acc_x", "acc_z")
        require(log, need, "(single-axis filters need rate and angle, or gyr_y, acc_x, acc_z)")
        c = log.columns
        return c["gyr_y"], np.arctan2(-c["acc_x"], c["acc_z"]), "gyr_y, atan2(-acc_x, acc_z)"
    raise ValueError(f"axis: must be 'x' or 'y', got {axis!r}")


# ---------------------------------------------------------------------------
# the shipped real recording

EXAMPLE = "broad_03_slow_rotation_45s.npz"
EXAMPLE_ATTRIBUTION = ("BROAD trial 03_undisturbed_slow_rotation_C, 45 s excerpt; D. Laidig, "
                       "M. Caruso, A. Cereatti, T. Seel, Data 6(7), 2021, "
                       "doi:10.3390/data6070072; CC BY 4.0")


def example_log():
    """Path of the real recording shipped with imufuse: 45 s of a BROAD trial
    (gyr, acc, mag, optical reference quat_ref in ENU, movement mask, rate;
    CC BY 4.0, see data/BROAD-EXCERPT.md beside it)."""
    return str(_path("imufuse", "data", EXAMPLE))


def npz_to_csv(src, dst):
    """Write an NPZ/HDF5 log (BROAD layout) as an imufuse CSV log with headers
    that carry the units: time (s), gyr_* (rad/s), acc_* (g: the values imufuse
    reads from the NPZ, so both files run the filters identically), mag_* (uT),
    q_w..q_z (the file's reference, unchanged: ENU for BROAD), movement."""
    log = read_log(src)
    cols = {"time (s)": log.t}
    for names, unit in ((GYR, "rad/s"), (ACC, "g"), (MAG, log.units["mag"][0])):
        if log.has(*names):
            for n in names:
                cols[f"{n} ({unit})"] = log.columns[n]
    if log.has(*QUAT):
        for n in QUAT:
            cols[n] = log.columns[n]
    if "movement" in log.columns:
        cols["movement"] = log.columns["movement"]
    write_csv(dst, cols)


# ---------------------------------------------------------------------------
# writing

def write_csv(path, columns, float32=()):
    """Write {name: (N,) array} as CSV with a header; values round-trip
    exactly: each is the text of Python's "%.9g" % x for the names in
    float32, else "%.17g" % x ("nan", "inf", "-inf", "-0" as Python writes
    them). path: a file name (written as UTF-8) or an open text stream.

    The text is made in C (imufuse_c._csvout, without the GIL) in blocks of
    whole rows in one fixed 1 MB buffer: memory stays small for long logs,
    and 10^6 rows of 7 columns take about 0.4 s (docs/csv-output.md)."""
    names = list(columns)
    arrs = [columns[n] for n in names]
    precisions = [9 if n in float32 else 17 for n in names]
    header = ",".join(names) + "\n"
    if not hasattr(path, "write"):
        with replacing(path) as tmp, open(tmp, "wb") as fh:
            fh.write(header.encode("utf-8"))
            for block in _csv_blocks(arrs, precisions):
                fh.write(block)
        return
    path.write(header)
    for block in _csv_blocks(arrs, precisions):
        path.write(block.decode("ascii"))


def write_npz(path, columns):
    """Write {name: (N,) array} as an uncompressed NPZ (fast for long logs)."""
    with replacing(path) as tmp, open(tmp, "wb") as fh:
        np.savez(fh, **{n: np.asarray(v) for n, v in columns.items()})


def write_log(path, t, gyr, acc, mag=None, q=None, extra=None):
    """Write a log in the imufuse format (gyro rad/s, acc g)."""
    cols = {"time": t}
    for names, arr in ((GYR, gyr), (ACC, acc), (MAG, mag), (QUAT, q)):
        if arr is not None:
            for j, n in enumerate(names):
                cols[n] = np.asarray(arr)[:, j]
    cols.update(extra or {})
    write_csv(path, cols)
