"""The firmware cache is bounded: every build of an edited firmware is a new entry, and nothing
removed them (a development machine's cache held 1 856 programs, 929 MB, and 192 host builds,
after some weeks of test runs). After a store the least recently used entries, the programs of
`validate --target` (targets/) and the host builds (_imufuse_fw_*) together, go until they take
at most $IMUFUSE_CACHE_MAX_MB; a hit counts as a use; a host build used in the last ten minutes
stays (a process may be loading it by its path); the pieces a killed build left go after an
hour. Entries here are made by hand in the cache's layout (the builds themselves:
tests/test_target_cache.py, and the host build below)."""
import hashlib
import json
import os
import time

from pathlib import Path

import pytest

from imufuse.firmware import FirmwareError
from imufuse.firmware import cache_bound
from imufuse.firmware import target_cache as tc

CSRC = Path(__file__).resolve().parents[1] / "csrc"


def _entry(cache, name, size, used):
    """A whole program entry of ``size`` bytes of image in the cache's targets/, last used
    ``used`` s ago."""
    e = cache / "targets" / name
    e.mkdir(parents=True)
    data = os.urandom(size)
    (e / "imf.elf").write_bytes(data)
    meta = {"format": tc._CACHE_FORMAT, "link_inputs": [],
            "files": {"imf.elf": [len(data), hashlib.sha256(data).hexdigest()]}}
    (e / tc._CACHE_META).write_text(json.dumps(meta))
    t = time.time() - used
    os.utime(e, (t, t))
    return e


def _host(cache, key, size, used):
    """A host build as imufuse.firmware.host leaves it (the module, its C, cffi's objects in
    a subdirectory), ``size`` bytes, last used ``used`` s ago."""
    e = cache / f"_imufuse_fw_{key}"
    (e / "tmp").mkdir(parents=True)
    (e / f"_imufuse_fw_{key}.so").write_bytes(os.urandom(size // 2))
    (e / "tmp" / f"_imufuse_fw_{key}.o").write_bytes(os.urandom(size - size // 2))
    t = time.time() - used
    os.utime(e, (t, t))
    return e


def _left(cache):
    return sorted(os.listdir(cache / "targets"))


def test_the_least_recently_used_go_first(tmp_path, monkeypatch):
    monkeypatch.setenv("IMUFUSE_CACHE_MAX_MB", "1")
    for name, used in (("old", 300), ("mid", 200), ("new", 100), ("stored", 0)):
        _entry(tmp_path, name, 300_000, used)
    tc._prune(tmp_path / "targets", "stored")
    assert _left(tmp_path) == ["mid", "new", "stored"]   # 1.2 MB -> 0.9 MB


def test_a_hit_is_a_use(tmp_path, monkeypatch):
    monkeypatch.setenv("IMUFUSE_CACHE_MAX_MB", "0.7")
    old = _entry(tmp_path, "old", 300_000, 300)
    _entry(tmp_path, "mid", 300_000, 200)
    _entry(tmp_path, "stored", 300_000, 0)
    assert tc._read_entry(old) is not None          # read now: the most recent
    tc._prune(tmp_path / "targets", "stored")
    assert _left(tmp_path) == ["old", "stored"]


def test_the_entry_just_stored_stays(tmp_path, monkeypatch):
    monkeypatch.setenv("IMUFUSE_CACHE_MAX_MB", "0")
    _entry(tmp_path, "a", 1000, 10)
    _entry(tmp_path, "stored", 1000, 0)
    tc._prune(tmp_path / "targets", "stored")
    assert _left(tmp_path) == ["stored"]


def test_within_the_bound_nothing_goes(tmp_path, monkeypatch):
    monkeypatch.delenv("IMUFUSE_CACHE_MAX_MB", raising=False)
    for k in range(5):
        _entry(tmp_path, f"e{k}", 100_000, 100 * k)
        _host(tmp_path, f"k{k}", 100_000, 1000 + 100 * k)
    tc._prune(tmp_path / "targets", "e0")
    assert len(_left(tmp_path)) == 5 and tc.cache_limit() == int(tc.CACHE_MAX_MB * 1e6)
    assert len(list(tmp_path.glob("_imufuse_fw_*"))) == 5


def test_a_killed_builds_pieces_go_after_an_hour(tmp_path, monkeypatch):
    monkeypatch.delenv("IMUFUSE_CACHE_MAX_MB", raising=False)
    _entry(tmp_path, "stored", 1000, 0)
    for d, name, age in ((tmp_path / "targets", "m4f-k1.part-old", 2 * 3600),
                         (tmp_path / "targets", "m4f-k2.part-new", 60),
                         (tmp_path, "_imufuse_fw_k3.part-old", 2 * 3600),
                         (tmp_path, "_imufuse_fw_k4.part-new", 60)):
        (d / name).mkdir()
        (d / name / "imf.elf").write_bytes(b"x" * 100)
        t = time.time() - age
        os.utime(d / name, (t, t))
    tc._prune(tmp_path / "targets", "stored")
    assert _left(tmp_path) == ["m4f-k2.part-new", "stored"]
    assert sorted(p.name for p in tmp_path.glob("_imufuse_fw_*")) == ["_imufuse_fw_k4.part-new"]


def test_host_builds_and_programs_share_one_bound(tmp_path, monkeypatch):
    """The oldest go first whichever kind they are; a host build used in the last ten
    minutes stays beyond the bound; what is not the cache's is never touched."""
    monkeypatch.setenv("IMUFUSE_CACHE_MAX_MB", "1")
    _host(tmp_path, "old", 300_000, 4000)
    _entry(tmp_path, "mid", 300_000, 3000)
    _host(tmp_path, "recent", 300_000, 60)          # being loaded, maybe
    _entry(tmp_path, "newer", 300_000, 30)
    (tmp_path / "notes").mkdir()                    # not an entry
    (tmp_path / "notes" / "big").write_bytes(b"x" * 2_000_000)
    stored = _host(tmp_path, "stored", 300_000, 0)
    cache_bound.prune(tmp_path, stored)             # 1.5 MB of entries -> 0.9 MB
    assert sorted(p.name for p in tmp_path.glob("_imufuse_fw_*")) == [
        "_imufuse_fw_recent", "_imufuse_fw_stored"]
    assert _left(tmp_path) == ["newer"] and (tmp_path / "notes" / "big").exists()
    monkeypatch.setenv("IMUFUSE_CACHE_MAX_MB", "0")
    cache_bound.prune(tmp_path, stored)             # the recent host build stays even so
    assert sorted(p.name for p in tmp_path.glob("_imufuse_fw_*")) == [
        "_imufuse_fw_recent", "_imufuse_fw_stored"]
    assert _left(tmp_path) == []


def test_a_host_build_is_bounded_and_a_hit_is_a_use(tmp_path, monkeypatch):
    """The host build itself (cffi and the compiler): storing a build prunes the cache; a hit
    sets the entry's time; a bad bound is refused before anything is compiled."""
    pytest.importorskip("cffi", reason="the host build needs cffi (the firmware extra)")
    from imufuse.firmware import csrc_firmware
    monkeypatch.setenv("IMUFUSE_CACHE_MAX_MB", "0")
    _entry(tmp_path, "old", 300_000, 3000)
    _host(tmp_path, "old", 300_000, 3000)
    fw = csrc_firmware("Mahony1D", CSRC, cache_dir=str(tmp_path))
    fw.prepare("1d", (0.01, 2.0), dict(dt=0.01, kp=2.0))
    built = [p for p in tmp_path.glob("_imufuse_fw_*") if p.name != "_imufuse_fw_old"]
    assert len(built) == 1 and not (tmp_path / "_imufuse_fw_old").exists()
    assert _left(tmp_path) == []
    t = time.time() - 5000
    os.utime(built[0], (t, t))
    fw.prepare("1d", (0.01, 2.0), dict(dt=0.01, kp=2.0))                                # a hit: used now
    assert time.time() - built[0].stat().st_mtime < 60
    monkeypatch.setenv("IMUFUSE_CACHE_MAX_MB", "lots")
    other = tmp_path / "other"
    with pytest.raises(FirmwareError, match="IMUFUSE_CACHE_MAX_MB='lots'"):
        csrc_firmware("Mahony1D", CSRC, cache_dir=str(other)).prepare(
            "1d", (0.01, 2.0), dict(dt=0.01, kp=2.0))
    assert not list(other.glob("_imufuse_fw_*"))


@pytest.mark.parametrize("value", ["abc", "-1", "nan", "inf", "1e999"])
def test_a_bad_bound_is_refused(monkeypatch, value):
    monkeypatch.setenv("IMUFUSE_CACHE_MAX_MB", value)
    with pytest.raises(FirmwareError, match="IMUFUSE_CACHE_MAX_MB=.*a number >= 0"):
        tc.cache_limit()
