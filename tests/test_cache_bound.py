"""The program cache of `validate --target` is bounded: every build of an edited firmware is a
new entry, and nothing removed them (a development machine's cache held 1 856 programs, 929 MB,
after some weeks of test runs). After a store the least recently used entries go until the
programs take at most $IMUFUSE_CACHE_MAX_MB; a hit counts as a use; the pieces a killed build
left go after an hour. Entries here are made by hand in the cache's layout (the build itself:
tests/test_target_cache.py)."""
import hashlib
import json
import os
import time

import pytest

from imufuse.firmware import FirmwareError
from imufuse.firmware import target_cache as tc


def _entry(root, name, size, used):
    """A whole entry of ``size`` bytes of image, last used ``used`` s ago."""
    e = root / name
    e.mkdir(parents=True)
    data = os.urandom(size)
    (e / "imf.elf").write_bytes(data)
    meta = {"format": tc._CACHE_FORMAT, "link_inputs": [],
            "files": {"imf.elf": [len(data), hashlib.sha256(data).hexdigest()]}}
    (e / tc._CACHE_META).write_text(json.dumps(meta))
    t = time.time() - used
    os.utime(e, (t, t))
    return e


def test_the_least_recently_used_go_first(tmp_path, monkeypatch):
    monkeypatch.setenv("IMUFUSE_CACHE_MAX_MB", "1")
    for name, used in (("old", 300), ("mid", 200), ("new", 100), ("stored", 0)):
        _entry(tmp_path, name, 300_000, used)
    tc._prune(tmp_path, "stored")
    assert sorted(os.listdir(tmp_path)) == ["mid", "new", "stored"]   # 1.2 MB -> 0.9 MB


def test_a_hit_is_a_use(tmp_path, monkeypatch):
    monkeypatch.setenv("IMUFUSE_CACHE_MAX_MB", "0.7")
    old = _entry(tmp_path, "old", 300_000, 300)
    _entry(tmp_path, "mid", 300_000, 200)
    _entry(tmp_path, "stored", 300_000, 0)
    assert tc._read_entry(old) is not None          # read now: the most recent
    tc._prune(tmp_path, "stored")
    assert sorted(os.listdir(tmp_path)) == ["old", "stored"]


def test_the_entry_just_stored_stays(tmp_path, monkeypatch):
    monkeypatch.setenv("IMUFUSE_CACHE_MAX_MB", "0")
    _entry(tmp_path, "a", 1000, 10)
    _entry(tmp_path, "stored", 1000, 0)
    tc._prune(tmp_path, "stored")
    assert os.listdir(tmp_path) == ["stored"]


def test_within_the_bound_nothing_goes(tmp_path, monkeypatch):
    monkeypatch.delenv("IMUFUSE_CACHE_MAX_MB", raising=False)
    for k in range(5):
        _entry(tmp_path, f"e{k}", 100_000, 100 * k)
    tc._prune(tmp_path, "e0")
    assert len(os.listdir(tmp_path)) == 5 and tc.cache_limit() == int(tc.CACHE_MAX_MB * 1e6)


def test_a_killed_builds_pieces_go_after_an_hour(tmp_path, monkeypatch):
    monkeypatch.delenv("IMUFUSE_CACHE_MAX_MB", raising=False)
    _entry(tmp_path, "stored", 1000, 0)
    for name, age in (("m4f-k1.part-old", 2 * 3600), ("m4f-k2.part-new", 60)):
        (tmp_path / name).mkdir()
        (tmp_path / name / "imf.elf").write_bytes(b"x" * 100)
        t = time.time() - age
        os.utime(tmp_path / name, (t, t))
    tc._prune(tmp_path, "stored")
    assert sorted(os.listdir(tmp_path)) == ["m4f-k2.part-new", "stored"]


@pytest.mark.parametrize("value", ["abc", "-1", "nan", "inf", "1e999"])
def test_a_bad_bound_is_refused(monkeypatch, value):
    monkeypatch.setenv("IMUFUSE_CACHE_MAX_MB", value)
    with pytest.raises(FirmwareError, match="IMUFUSE_CACHE_MAX_MB=.*a number >= 0"):
        tc.cache_limit()
