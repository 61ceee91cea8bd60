"""CSV output (imufuse.io.write_csv, formatted in C by imufuse_c._csvout).

The text must be Python's "%.17g" % x (float64 columns) or "%.9g" % x
(float32 columns) for every value, and must read back to the same bits as
the arrays that were written.
"""
import errno
import io as _io
import os
import struct

import numpy as np
import pytest

from imufuse import cli, io
from imufuse_c import _csvout


def _hostile_values():
    """Random bit patterns (every exponent, subnormals, NaN payloads), values
    around the %g style switch and the 128-bit fast path's limits, exact
    rounding ties for 9 and 17 digits, and the special values."""
    rng = np.random.default_rng(20261201)
    bits = rng.integers(0, 2**64, size=60000, dtype=np.uint64).view(np.float64)
    scaled = rng.normal(size=60000) * 10.0 ** rng.integers(-40, 45, size=60000)
    f32 = rng.normal(size=20000).astype(np.float32).astype(np.float64)
    edges = [10.0 ** k * s for k in range(-330, 309) for s in (1.0, -1.0)]
    edges += [np.nextafter(10.0 ** k, d) for k in range(-20, 40) for d in (0.0, np.inf)]
    edges += [1e-4, 9.9999999999999995e-5, 1e-5, 1e16, 1e17, 9.999999999999999e16,
              99999999.5, 999999999.5, 1e9, 2.0 ** 127, 2.0 ** 128, 2.0 ** -74, 2.0 ** -75,
              5e-324, -5e-324, 2.2250738585072014e-308, 1.7976931348623157e308,
              0.0, -0.0, np.inf, -np.inf, np.nan, -np.nan,
              struct.unpack("<d", struct.pack("<Q", 0x7FF0000000000001))[0],
              struct.unpack("<d", struct.pack("<Q", 0xFFF8000000000123))[0]]
    # exact ties: 18 significant digits ending in 5 (for 17), 10 ending in 5 (for 9)
    ties17 = [float(k) + 0.25 for k in range(1234567890123400, 1234567890123500)]
    ties17 += [float(k) + 0.625 for k in range(123456789012300, 123456789012400)]
    ties9 = [k + 0.5 for k in range(123456700, 123456800)]
    ties9 += [float((10 * k + 5) * 10 ** e) for k in range(123456700, 123456800)
              for e in (0, 3, 6)]
    return np.concatenate([bits, scaled, f32, edges, ties17, ties9])


VALUES = _hostile_values()


def _python_text(values, precision):
    fmt = f"%.{precision}g"
    return [fmt % v for v in values.tolist()]


@pytest.mark.parametrize("precision", [9, 17])
def test_text_is_pythons_g_format(precision):
    got = b"".join(_csvout.iter_blocks([VALUES], [precision])).decode("ascii").split("\n")
    assert got[-1] == ""
    want = _python_text(VALUES, precision)
    bad = [(v, g, w) for v, g, w in zip(VALUES.tolist(), got[:-1], want) if g != w]
    assert len(got) - 1 == len(want) and not bad, bad[:10]


@pytest.mark.parametrize("precision", [9, 17])
def test_format_value_matches_blocks(precision):
    some = VALUES[::97]
    want = _python_text(some, precision)
    assert [_csvout.format_value(v, precision) for v in some.tolist()] == want


def _bits(a, dtype):
    return np.asarray(a, dtype=dtype).view(np.uint32 if dtype == np.float32 else np.uint64)


def test_round_trip_bits():
    """float64 at 17 digits and float32 at 9 read back to the same bits
    (NaN as NaN)."""
    f64 = VALUES[np.isfinite(VALUES)]
    f32 = f64[np.abs(f64) < 3e38].astype(np.float32)
    f32 = f32[np.isfinite(f32)]
    for vals, prec, dt in ((f64, 17, np.float64), (f32, 9, np.float32)):
        text = b"".join(_csvout.iter_blocks([vals], [prec])).decode("ascii").split()
        back = np.array([float(s) for s in text]).astype(dt)
        np.testing.assert_array_equal(_bits(back, dt), _bits(vals, dt))


@pytest.mark.parametrize("block", [1, 100, 1 << 20])
def test_write_csv_columns_and_blocks(tmp_path, monkeypatch, block):
    """Strided, float32, integer, boolean and reversed columns; blocks
    smaller than a row, of a few rows and the default; file and text stream
    give the same text, the one of Python's % formatting."""
    monkeypatch.setattr(_csvout, "BLOCK_BYTES", block)
    rng = np.random.default_rng(1)
    S = rng.normal(size=(2503, 3)) * 10.0 ** rng.integers(-8, 20, size=(2503, 3))
    cols = {"time": np.arange(2503) / 200.0, "a": S[:, 0], "b": S[:, 1].astype(np.float32),
            "c": S[::-1, 2], "k": np.arange(2503) - 1000, "m": np.arange(2503) % 2 == 0}
    want = "time,a,b,c,k,m\n" + "".join(
        "%.17g,%.17g,%.9g,%.17g,%.17g,%.17g\n" % row
        for row in zip(*(np.asarray(c, dtype=np.float64).tolist() for c in cols.values())))
    p = tmp_path / "o.csv"
    io.write_csv(p, cols, float32={"b"})
    assert p.read_bytes() == want.encode("ascii")
    s = _io.StringIO()
    io.write_csv(s, cols, float32={"b"})
    assert s.getvalue() == want


def test_write_csv_empty_and_bad_columns(tmp_path):
    p = tmp_path / "o.csv"
    io.write_csv(p, {"time": np.zeros(0), "x": np.zeros(0)})
    assert p.read_text() == "time,x\n"
    with pytest.raises(ValueError, match="column 1"):
        io.write_csv(p, {"time": np.zeros(3), "x": np.zeros(4)})
    with pytest.raises(ValueError, match="column 0"):
        io.write_csv(p, {"x": np.zeros((3, 2))})
    with pytest.raises(ValueError, match="precisions"):
        list(_csvout.iter_blocks([np.zeros(3)], [8]))


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full on this system")
def test_write_csv_full_device():
    with pytest.raises(OSError) as e:
        io.write_csv("/dev/full", {"x": np.arange(100000.0)})
    assert e.value.errno == errno.ENOSPC


@pytest.mark.parametrize("dtype", ["float32", "float64"])
@pytest.mark.parametrize("backend", ["c", "ref"])
def test_run_csv_reads_back_to_the_computed_bits(tmp_path, dtype, backend):
    """`imufuse run -o out.csv` against `-o out.npz` (the arrays as computed,
    written by numpy): every column, every value, the same bits (float32
    state columns compared as float32)."""
    log = io.example_log()
    outs = {}
    for ext in ("csv", "npz"):
        outs[ext] = tmp_path / f"out.{ext}"
        argv = ["run", log, "-f", "MadgwickIMU", "--dtype", dtype, "--backend", backend,
                "-o", str(outs[ext])]
        if backend == "ref":
            argv[1] = str(_short_log(tmp_path))
        assert cli.main(argv) == 0
    arrays = np.load(outs["npz"])
    with open(outs["csv"]) as fh:
        header = fh.readline().strip().split(",")
        rows = [line.rstrip("\n").split(",") for line in fh]
    assert header == list(arrays.files)
    assert len(rows) == len(arrays["time"]) > 0
    for j, name in enumerate(header):
        a = arrays[name]
        dt = np.float32 if a.dtype == np.float32 else np.float64
        if dtype == "float32" and name in ("q0", "q1", "q2", "q3"):
            assert dt == np.float32, name
        back = np.array([float(r[j]) for r in rows]).astype(dt)
        np.testing.assert_array_equal(_bits(back, dt), _bits(a, dt), err_msg=name)


def _short_log(tmp_path):
    """The first 2000 samples of the example log (the reference backend is slow)."""
    p = tmp_path / "short.csv"
    if not p.exists():
        full = io.read_log(io.example_log())
        cols = {"time": full.t[:2000]}
        for n in (*io.GYR, *io.ACC):
            cols[n] = full.columns[n][:2000]
        io.write_csv(p, cols)
    return p
