"""Logs held as arrays: NPZ and HDF5 files in the layout of the BROAD dataset (gyr, acc,
mag, quat_ref, movement, rate; BROAD's HDF5 names imu_gyr, imu_acc, imu_mag, opt_quat,
sampling_rate), read into the columns of a Log (h5py is needed for HDF5)."""
import math
import os

import numpy as np

from .log import ACC, GYR, MAG, QUAT, LogError


def _first(z, *keys):
    for k in keys:
        if k in z:
            return np.asarray(z[k])
    return None


#: the arrays (and rate keys) a log in the BROAD layout may hold
_ARRAY_KEYS = ("gyr", "imu_gyr", "acc", "imu_acc", "mag", "imu_mag", "quat_ref", "opt_quat",
               "q_ref", "movement", "time", "t", "rate", "sampling_rate")


class _LazyNpz:
    """The members of an open NpzFile as a mapping read on access (a damaged member raises
    LogError naming the archive and the member)."""

    def __init__(self, npz, path):
        self._npz, self._path = npz, path
        self._keys = list(npz.keys())

    def __contains__(self, key):
        return key in self._keys

    def __iter__(self):
        return iter(self._keys)

    def __getitem__(self, key):
        try:
            return self._npz[key]
        except Exception as e:  # noqa: BLE001 - a damaged member raises many kinds of error
            raise LogError(f"{self._path}: not a readable NPZ archive: array {key!r}: "
                           f"{type(e).__name__}: {e}") from None


def _read_arrays(path):
    """NPZ or HDF5 in the BROAD layout -> (columns, header, sources, rate)."""
    ext = os.path.splitext(path)[1].lower()
    if ext == ".npz":
        try:
            # only the arrays a log uses, each read when it is converted (a lazy mapping:
            # the archive's other members, of any size, are never read)
            z = _LazyNpz(np.load(path, allow_pickle=False), path)
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
    # which member holds each part; each is read (and converted) one at a time
    names = {"gyr": ("gyr", "imu_gyr"), "acc": ("acc", "imu_acc"), "mag": ("mag", "imu_mag"),
             "quat": ("quat_ref", "opt_quat", "q_ref"), "movement": ("movement",),
             "time": ("time", "t"), "rate": ("rate", "sampling_rate")}
    member = {kind: next((k for k in ks if k in z), None) for kind, ks in names.items()}
    if member["gyr"] is None or member["acc"] is None:
        raise LogError(f"{path}: expected arrays gyr and acc (N, 3) (BROAD layout: gyr, acc, mag, "
                       f"quat_ref, movement, rate); found {', '.join(keys) or 'none'}")

    def part(kind):
        if member[kind] is None:
            return None
        a = np.asarray(z[member[kind]])
        if a.dtype.kind not in "biuf":
            raise LogError(f"{path}: array {member[kind]} holds {a.dtype} values; expected "
                           "numbers")
        return a
    gyr = part("gyr")
    if gyr.ndim != 2 or gyr.shape[1] != 3:
        # (3, N) read as N = 3 named acc as the wrong one, "expected (3, 3)"
        raise LogError(f"{path}: array {member['gyr']} has shape {gyr.shape}; expected (N, 3)"
                       + (", one row per sample (transposed?)" if gyr.ndim == 2
                          and gyr.shape[0] == 3 else ""))
    n = len(gyr)
    cols, sources = {}, {}
    for kind, cnames, width in (("gyr", GYR, 3), ("acc", ACC, 3), ("mag", MAG, 3),
                                ("quat", QUAT, 4)):
        a = gyr if kind == "gyr" else part(kind)
        if a is None:
            continue
        if a.ndim == 2 and a.shape[1] == width and len(a) != n:
            raise LogError(f"{path}: array {member[kind]} has {len(a)} rows, "
                           f"{member['gyr']} {n}: every array holds one row per sample")
        if a.ndim != 2 or a.shape != (n, width):
            raise LogError(f"{path}: array {member[kind]} has shape {a.shape}; expected "
                           f"({n}, {width})")
        for j, c in enumerate(cnames):
            cols[c] = np.ascontiguousarray(a[:, j], dtype=np.float64)
            sources[c] = f"{kind} column {j}"
        del a
        gyr = None
    for kind in ("movement", "time"):
        a = part(kind)
        if a is not None:
            if a.shape != (n,):
                raise LogError(f"{path}: array {member[kind]} has shape {a.shape}; expected "
                               f"({n},), one value per sample of {member['gyr']}")
            cols[kind] = a.astype(np.float64)
            sources[kind] = kind
    parts = {"rate": part("rate")}
    rate = parts["rate"]
    if rate is not None:
        if rate.size != 1:
            raise LogError(f"{path}: rate has {rate.size} values (shape {rate.shape}); expected "
                           "one sample rate in Hz")
        rate = float(rate.reshape(-1)[0])
        if not (math.isfinite(rate) and rate > 0 and math.isfinite(1.0 / rate)):
            raise LogError(f"{path}: rate is {rate!r}; expected a finite sample rate > 0 Hz")
    return cols, keys, sources, rate
