"""The C reader of CSV logs (imufuse_c._csvin, csvparse.h) against numpy.loadtxt, the reader
it replaced: the same values to the bit and the same errors, on generated logs in every
layout the reader takes (delimiters, line ends, quotes, comments, blank lines, decimal
commas, NUL-filled tails, numbers written every way a logger writes them), and the few
places where it reads more than numpy did, each on purpose.
"""
import math
import os
import re
import struct
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from imufuse import io
from imufuse_c import _csvin
from imufuse.io import text as T
from imufuse.io.log import LogError

COLS = ["time", "gyr_x", "gyr_y", "gyr_z", "acc_x", "acc_y", "acc_z"]


def _read(path, engine, block=None):
    """(values, notes) or the LogError's text, through one engine (the C parser reading
    ``block`` bytes at a time)."""
    enc, lines = T._open_text(str(path))
    header_line = next(i for i, ln in enumerate(lines) if ln.strip()) + 1
    delim, header = T._sniff(lines)
    header = [h.strip() for h in header]
    found = T.recognise(header)
    usecols = sorted(set(found.values()))
    decimal_comma = delim not in (",", None) and any(
        T._DEC_COMMA.match(c) for c in lines[header_line].split(delim))
    nul: dict = {}
    try:
        if engine == "c":
            if block is not None:
                saved, T._C_BLOCK = T._C_BLOCK, block
            try:
                M = T._numbers_c(str(path), enc, delim, header_line, header, found, usecols,
                                 decimal_comma, nul, lines)
            finally:
                if block is not None:
                    T._C_BLOCK = saved
        else:
            data = [ln for ln in lines[header_line:header_line + 50] if ln.strip()]
            M = T._numbers_numpy(str(path), enc, delim, header_line, header, found, usecols,
                                 decimal_comma, data, nul)
    except LogError as e:
        return str(e)
    return M, nul


def _same(path, block=None):
    a, b = _read(path, "c", block), _read(path, "numpy")
    if isinstance(b, str) or isinstance(a, str):
        assert a == b
        return a
    (Ma, na), (Mb, nb) = a, b
    assert Ma.shape == Mb.shape
    assert np.array_equal(Ma.view(np.uint64), Mb.view(np.uint64)), (Ma, Mb)
    assert na == nb
    return Ma


def _fmt(x, how):
    """x as a logger writes it."""
    if how == "r":
        return repr(x)
    if how == "g7":
        return "%.7g" % x
    if how == "e":
        return "%.12e" % x
    if how == "f":
        return "%.6f" % x
    if how == "long":                       # more than 19 significant digits
        return "%.30f" % x
    if how == "plus":
        return ("+" if math.copysign(1.0, x) > 0 else "") + "%.9g" % x
    if how == "int":
        return str(int(x))
    return " %.5g " % x                      # blanks around the number


floats = st.one_of(st.floats(allow_nan=False, allow_infinity=False, width=64),
                   st.floats(-1e3, 1e3), st.integers(-10**6, 10**6).map(float),
                   st.sampled_from([0.0, -0.0, 5e-324, 2.2250738585072014e-308, 1.7976931348623157e308,
                                    0.1, 9007199254740993.0, 1e22, 1e23]))
formats = st.sampled_from(["r", "g7", "e", "f", "long", "plus", "int", "blank"])


@st.composite
def logs(draw):
    delim = draw(st.sampled_from([",", ";", "\t", "|", " "]))
    end = draw(st.sampled_from(["\n", "\r\n", "\r"]))
    extra = draw(st.integers(0, 2))                        # unused columns
    header = COLS + [f"note{i}" for i in range(extra)]
    order = draw(st.permutations(range(len(header))))
    header = [header[i] for i in order]
    rows = []
    for _ in range(draw(st.integers(1, 12))):
        kind = draw(st.sampled_from(["row"] * 8 + ["blank", "comment"]))
        if kind == "blank" and delim != " ":
            rows.append("")
            continue
        if kind == "comment":
            rows.append("# a comment" + (delim * 2 if delim != " " else ""))
            continue
        cells = []
        for _ in header:
            x = draw(floats)
            how = draw(formats)
            if how == "int" and abs(x) > 1e15:
                how = "r"
            c = _fmt(x, how)
            if delim == " ":
                c = c.strip()
            elif draw(st.integers(0, 9)) == 0:
                c = f'"{c}"'
            cells.append(c)
        line = delim.join(cells)
        if delim != " " and draw(st.integers(0, 5)) == 0:
            line += delim                                    # a trailing delimiter
        if draw(st.integers(0, 7)) == 0:
            line += " # trailing comment"
        rows.append(line)
    if not any(r and not r.startswith("#") for r in rows):
        rows.append(delim.join("1" for _ in header))
    text = delim.join(header) + end + end.join(rows) + draw(st.sampled_from(["", end]))
    tail = b"\0" * draw(st.sampled_from([0, 0, 7, 5000]))
    return text.encode() + tail


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(logs(), st.sampled_from([None, 1024, 257, 64]))
def test_the_c_reader_reads_what_numpy_read(tmp_path, blob, block):
    """In blocks of 64 bytes too, so that rows, numbers, a CR LF and the NUL tail straddle
    the blocks (a row longer than a block is refused: such logs are left to the big block)."""
    p = tmp_path / "log.csv"
    p.write_bytes(blob)
    if block is not None and max(map(len, re.split(rb"\r\n|\n|\r", blob))) + 2 >= block:
        block = None
    _same(p, block)


def test_numbers_every_way_to_the_bit(tmp_path):
    """Significands of up to 40 digits, exponents from subnormal to overflow, the exact fast
    path's edges (2^53, 10^22) and the strtod path beyond them: bit for bit with Python's
    correctly rounded float()."""
    vals = ["0.1", "9007199254740992", "9007199254740993", "9007199254740993.0000000000001",
            "1e22", "1e23", "1.0000000000000000000000001", "123456789012345678901234567890e-30",
            "2.2250738585072011e-308", "4.9e-324", "2e-324", "1e-400", "1.7976931348623157e308",
            "1.7976931348623159e308", "1e400", "-0", "-0.0e5", "+.5", "5.", "00000000000000000000000123.5",
            "0.000000000000000000000000000000000001", "NaN", "-inf", "Infinity", "+INF"]
    p = tmp_path / "numbers.csv"
    p.write_text("time,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z\n"
                 + "".join(f"{i},{v},{v},0,0,0,1\n" for i, v in enumerate(vals)))
    M = _same(p)
    for v, got in zip(vals, M[:, 1]):
        want = float(v)
        if math.isnan(want):
            assert math.isnan(got)
        else:
            assert struct.pack("<d", got) == struct.pack("<d", want), v


@pytest.mark.parametrize("bad, where", [
    ("1,2,3,x,5,6,7", "column gyr_z: not a number: 'x'"),
    ("1,2,3,0x10,5,6,7", "not a number: '0x10'"),
    ("1,2,3,1_0,5,6,7", "column gyr_z: not a number: '1_0'"),
    ("1,2,3,4,5,6", "6 values, the header has 7 columns"),
    ("1,2,3,4,5,6,7,8,9", "9 values under a header of 7 columns"),
    ("1,2,3,,5,6,7", "column gyr_z: not a number: ''"),
])
def test_errors_name_the_line_as_before(tmp_path, bad, where):
    p = tmp_path / "bad.csv"
    p.write_text("time,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z\n0,0,0,0,0,0,1\n\n" + bad + "\n")
    msg = _same(p)
    assert isinstance(msg, str) and where in msg, msg
    assert ":4:" in msg or "line 4" in msg, msg


def test_a_line_of_blanks_is_a_blank_line(tmp_path):
    """Where the C reader reads more than numpy did: a line of blanks under a delimited
    header is a blank line (numpy failed on it)."""
    p = tmp_path / "log.csv"
    p.write_bytes(b"time,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z,note\n0,1,2,3,0,0,1,ok\n   \n"
                  b"1,1,2,3,0,0,1,fine\n")
    log = io.read_log(p)
    assert len(log) == 2 and list(log.gyr[1]) == [1, 2, 3]
    assert isinstance(_read(p, "numpy"), str)


def test_a_line_longer_than_a_block_is_no_csv(tmp_path):
    p = tmp_path / "long.csv"
    p.write_bytes(b"time,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z\n0,0,0,0,0,0,1\n"
                  + b"1" * (3 << 20) + b"\n")
    with pytest.raises(LogError, match="a line longer than"):
        io.read_log(p)


_PEAK = """
import re, sys
from imufuse.io import text as T
def rss(k):
    return int(re.search(k + r":\\s+(\\d+)", open("/proc/self/status").read()).group(1)) * 1024
T._read_csv(sys.argv[1], None, None)             # warm: imports, first allocations
open("/proc/self/clear_refs", "w").write("5")    # the peak from here
base = rss("VmRSS")
cols = T._read_csv(sys.argv[1], None, None)[0]
print(rss("VmHWM") - base, sum(c.nbytes for c in cols.values()))
"""


@pytest.mark.skipif(not os.access("/proc/self/clear_refs", os.W_OK),
                    reason="the peak resident memory is reset through /proc/self/clear_refs "
                    "(Linux), not writable here")
def test_memory_is_the_arrays_and_a_block(tmp_path):
    """2·10^5 rows: the peak resident memory while the reader reads is the arrays it yields
    (7 float64 columns, 11 MB) plus its buffer of two blocks, not the text (17 MB here): the
    array is sized for rows of half the first rows' length, and only what is written costs
    memory."""
    n = 200_000
    t = np.arange(n) / 100.0
    data = np.column_stack([t] + [np.sin(t * k) for k in range(1, 7)])
    p = tmp_path / "big.csv"
    with open(p, "w") as fh:
        fh.write(",".join(COLS) + "\n")
        np.savetxt(fh, data, delimiter=",", fmt="%.9g")
    out = subprocess.run([sys.executable, "-c", _PEAK, str(p)], capture_output=True, text=True,
                         check=True)
    peak, arrays = map(int, out.stdout.split())
    assert arrays == n * 7 * 8
    assert peak < arrays + 2 * _csvin.BLOCK_BYTES + (2 << 20), (peak, arrays, os.path.getsize(p))
