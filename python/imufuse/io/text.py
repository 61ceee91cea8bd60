"""Reading CSV text: opening a file as text (byte-order marks, encodings, the NUL-filled
tail of a preallocated file), sniffing the delimiter, the header (one row, or the rows
tools export: imufuse.io.headers), and parsing the numbers (numpy's C
parser block by block, a failed row located again line by line so that errors name the
line); also `read_csv_rows`, the plain rows of a small CSV file."""
import codecs
import csv
import locale
import os
import re

import numpy as np

import imufuse_c._csvin as _csvin

from .columns import _apply_map, duplicate_columns, recognise
from .headers import header_rows
from .log import LogError


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



_BOMS = ((codecs.BOM_UTF8, "utf-8-sig"), (codecs.BOM_UTF16_LE, "utf-16"),
         (codecs.BOM_UTF16_BE, "utf-16"))
_DELIMS = (",", ";", "\t", "|")
#: the binary files a log is often mistaken for, said by their first bytes
_MAGIC = ((b"\x1f\x8b", "a gzip-compressed file; decompress it first (gunzip)"),
          (b"PK\x03\x04", "a ZIP archive; an NPZ log needs the .npz extension, else unzip it"),
          (b"\x93NUMPY", "a NumPy .npy array; save the log as NPZ (numpy.savez(path, gyr=..., "
                         "acc=..., rate=...))"),
          (b"\x89HDF\r\n\x1a\n", "an HDF5 file; an HDF5 log needs the .h5 or .hdf5 extension"))
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
        what = next((w for magic, w in _MAGIC if head.startswith(magic)), None)
        raise LogError(f"{path}: not a text (CSV) log: " + (what or "it contains NUL bytes "
                                                            "(expected a header row of column "
                                                            "names)"))
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

def _cut_short(path, ln):
    """True when line ``ln`` (1-based) is the file's last and has no line end: the file was
    cut while a row was written (the error path only: it reads the file again)."""
    with open(path, "rb") as fh:
        data = fh.read()
    data = data.rstrip(b"\0")                 # a preallocated file's NUL tail
    if not data or data.endswith((b"\n", b"\r")):
        return False
    return len(_LINE_END.findall(data)) + 1 == ln


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
                                   f"{max(idx.values()) + 1 if ncol is None else ncol} columns"
                                   + (" (the last line, without a line end: a file cut short, "
                                      "as by an interrupted recording? delete that line)"
                                      if _cut_short(path, ln) else ""))
                for i, name in names.items():
                    s = r[i].strip()
                    if decimal_comma:
                        s = s.replace(",", ".")
                    try:
                        if "_" in s:          # float() takes 1_0; no reader of numbers does
                            raise ValueError(s)
                        float(s)
                    except ValueError:
                        if len(s) > 60:
                            s = s[:60] + "..."
                        raise LogError(f"{path}:{ln}: column {name}: not a number: {s!r}") from None
        except csv.Error as e:
            raise LogError(f"{path}:{ln + 1}: unreadable CSV: {e}") from None
    raise LogError(f"{path}: cannot read the values: {loader_error}")


_BLOCK = 100_000
#: the encodings whose bytes the C parser reads (numbers are ASCII in both)
_FAST_ENCODINGS = ("utf-8", "utf-8-sig")
_LINE_END = re.compile(rb"\r\n|\n|\r")
#: the bytes the C parser reads at a time (the longest line it takes)
_C_BLOCK = _csvin.BLOCK_BYTES


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


def _numbers_numpy(path, enc, delim, header_line, header, found, usecols, decimal_comma, data,
                   nul_state):
    """The used columns through numpy.loadtxt (text decoded by Python: any encoding, any
    locale): the reader for the encodings the C parser does not take."""
    try:
        with open(path, encoding=enc, newline="") as fh:
            for _ in range(header_line):
                fh.readline()
            if decimal_comma:
                return np.loadtxt((ln.replace(",", ".") for ln in fh), delimiter=delim,
                                  usecols=usecols, ndmin=2, dtype=np.float64, quotechar='"',
                                  comments="#")
            width = len(data[0]) + 1 if data else 64     # bytes per row, first row
            # sized from the text, not from a NUL-filled tail of a preallocated file
            rows = int(_nul_tail_start(path) / max(width, 8) * 1.05)
            lines_in = _lines_until_nul(fh, nul_state)
            if delim:
                lines_in = _no_extra_values(lines_in, delim, len(header), header_line + 1)
            return _loadtxt_blocks(lines_in, delim, usecols, rows)
    except LogError as e:
        raise LogError(f"{path}: {e}") from None
    except (ValueError, IndexError) as e:
        _numbers_slow(path, enc, delim, header_line, found, decimal_comma, e)
    except MemoryError:
        raise LogError(f"{path}: too large to read into memory") from None
    except (OSError, UnicodeDecodeError) as e:
        raise LogError(f"{path}: cannot read: {e}", "file") from None
    raise AssertionError("unreachable")


def _header_bytes(path, enc, header_line):
    """The byte offset of the line after the first header_line lines (line ends as Python's
    readline with newline="" sees them: LF, CR LF, a lone CR), byte-order mark included. The
    header lines lie in the first block _open_text read."""
    with open(path, "rb") as fh:
        head = fh.read((1 << 16) + 2)
    pos = len(codecs.BOM_UTF8) if enc == "utf-8-sig" else 0
    for _ in range(header_line):
        m = _LINE_END.search(head, pos)
        if m is None:
            return len(head)
        pos = m.end()
    return pos


def _numbers_c(path, enc, delim, header_line, header, found, usecols, decimal_comma,
               nul_state, lines):
    """The used columns through the C parser (imufuse_c._csvin: UTF-8 bytes, numbers as
    numpy.loadtxt reads them, to the bit, in one pass without the GIL); the first row it
    cannot read is found again line by line (_numbers_slow) for the message."""
    try:
        # to the first byte of a NUL-filled tail (which ends the text with a note)
        stop = min(os.path.getsize(path), _nul_tail_start(path) + 1)
        rows = [ln for ln in lines[header_line:header_line + 50] if ln.strip()]
        M, info = _csvin.read_numbers(path, _header_bytes(path, enc, header_line), stop,
                                      delim, len(header), usecols, decimal_comma,
                                      min((len(r.encode()) + 1 for r in rows), default=0),
                                      _C_BLOCK)
    except MemoryError:
        raise LogError(f"{path}: too large to read into memory") from None
    except OSError as e:
        raise LogError(f"{path}: cannot read: {e.strerror or e}", "file") from None
    status, line = info["status"], header_line + info["line"]
    if status == "many":
        raise LogError(f"{path}: line {line}: {info['column']} values under a header of "
                       f"{len(header)} columns")
    if status == "long":
        raise LogError(f"{path}: a line longer than {_C_BLOCK} characters after "
                       f"data line {info['line'] - 1}: not a CSV log")
    if status is not None:
        what = "a value that is not a number" if status == "number" else "too few values"
        _numbers_slow(path, enc, delim, header_line, found, decimal_comma,
                      f"line {line}: {what}")
    if info["nul"]:
        nul_state["nul"] = info["lines"]
        if info["cut"]:
            nul_state["cut"] = info["cut"].decode("utf-8", "replace")[:40]
    return M


def _read_csv(path, column_map, time_unit):
    enc, lines = _open_text(path)
    if not lines or not any(ln.strip() for ln in lines):
        raise LogError(f"{path}: empty file (expected a header row of column names, "
                       "e.g. time,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z)")
    header_line = next(i for i, ln in enumerate(lines) if ln.strip()) + 1
    delim, header = _sniff(lines)
    # a header over two or three rows (a group row, an axis or unit row), as tools export it
    header, more = header_rows(header, lines[header_line:], delim)
    header_line += more
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
        if delim != "," and not dc:
            # a first row of integers ("0;0;0;1") says nothing: the first rows that do
            for row in data[1:]:
                dc = [c for c in (next(csv.reader([row], delimiter=delim)) if delim
                                  else row.split()) if _DEC_COMMA.match(c)]
                if dc:
                    break
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
    if enc in _FAST_ENCODINGS and locale.localeconv()["decimal_point"] == ".":
        M = _numbers_c(path, enc, delim, header_line, header, found, usecols, decimal_comma,
                       nul_state, lines)
    else:
        M = _numbers_numpy(path, enc, delim, header_line, header, found, usecols,
                           decimal_comma, data, nul_state)
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
