"""Writing logs and filter outputs (CSV formatted in C, exactly round-tripping; NPZ;
the imufuse log format), and the real recording shipped with imufuse (`example_log`,
`npz_to_csv`)."""
import numpy as np
from imufuse_c._csvout import iter_blocks as _csv_blocks

from ..shared.atomic import replacing
from ..shared.resources import _path
from .log import ACC, GYR, MAG, QUAT
from .read import read_log


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


class CsvBlocks:
    """write_csv for a table made block by block: ``add(columns)`` appends a block of rows
    (the header from the first block; every block the same names), and the file is written
    whole or not at all (the atomic writer) when the ``with`` block ends without an error.
    path: a file name or an open text stream. Memory is one block's."""

    def __init__(self, path, float32=()):
        self.path, self.float32, self.names = path, set(float32), None
        self._cm = None
        self._fh = None

    def __enter__(self):
        if hasattr(self.path, "write"):
            self._fh = self.path
        else:
            self._cm = replacing(self.path)
            tmp = self._cm.__enter__()
            self._fh = open(tmp, "wb")
        return self

    def add(self, columns):
        names = list(columns)
        if self.names is None:
            self.names = names
            self._put(",".join(names).encode("utf-8") + b"\n")
        elif names != self.names:
            raise ValueError(f"CsvBlocks: columns {names} after {self.names}")
        precisions = [9 if n in self.float32 else 17 for n in names]
        for block in _csv_blocks([columns[n] for n in names], precisions):
            self._put(block)

    def _put(self, data):
        if self._cm is None:
            self._fh.write(data.decode("utf-8"))
        else:
            self._fh.write(data)

    def __exit__(self, *exc):
        if self._cm is None:
            return False
        try:
            self._fh.close()
        finally:
            self._cm.__exit__(*exc)
        return False


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
