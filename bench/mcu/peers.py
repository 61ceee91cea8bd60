"""The peers' published sources for the cross-library table (bench/mcu/cross_library.py) and its
test (tests/test_cross_library.py): sdists from PyPI, fetched by URL, SHA-256 checked, cached,
extracted; never committed.

    python bench/mcu/peers.py              # fetch every one, print where it is

Cache: IMUFUSE_ORACLE_CACHE (default ~/.cache/imufuse/oracle), shared with tests/fusion_oracle.py.
Each peer: the sdist, the directory of its C or C++ inside it, the declaration that builds it
(examples/declarations/).
"""
from __future__ import annotations

import dataclasses
import hashlib
import os
import shutil
import sys
import tarfile
import tempfile
import urllib.request
from pathlib import Path
from typing import Dict

ROOT = Path(__file__).resolve().parents[2]
CACHE = Path(os.environ.get("IMUFUSE_ORACLE_CACHE", Path.home() / ".cache" / "imufuse" / "oracle"))
_FILES = "https://files.pythonhosted.org/packages"


@dataclasses.dataclass(frozen=True)
class Peer:
    name: str           # the table's name
    sdist: str          # file name
    url: str
    sha256: str
    subdir: str         # the sources inside the extracted sdist
    declaration: str    # examples/declarations/...

    @property
    def declaration_path(self) -> Path:
        return ROOT / "examples" / "declarations" / self.declaration


PEERS: Dict[str, Peer] = {p.name: p for p in (
    Peer("Fusion 1.2.3", "imufusion-1.2.3.tar.gz",
         f"{_FILES}/fb/43/11cdcad3bed146bd17d35794a4243b8dd33c14026fc8c36d02e6b1fcb8c4/"
         "imufusion-1.2.3.tar.gz",
         "e403e66abd77b5206be8511ecbd54d62fa452f681444bfe9ea17e1d31af6c493",
         "imufusion-1.2.3/Fusion", "fusion-1.2.3.toml"),
    Peer("Fusion 1.3.3", "imufusion-1.3.3.tar.gz",
         f"{_FILES}/aa/5e/c2bd75da78da778816dc576dcfac5a6dff2aeca3d7658cb19082d1e65465/"
         "imufusion-1.3.3.tar.gz",
         "b2175e5ed1e1cca95ef8673432d1f089037f957cde4325a510738c9e7ad3b87d",
         "imufusion-1.3.3/Fusion", "fusion-1.3.3.toml"),
    Peer("VQF 2.1.2 (float32)", "vqf-2.1.2.tar.gz",
         f"{_FILES}/0b/1f/9b24f7bf45532b2922c127a66b02116662ba0bb9ca8965140d207d0883fe/"
         "vqf-2.1.2.tar.gz",
         "2bf7134ffb181d518ac8c0855a239881c5a3e06e927605c351e72bbce1623233",
         "vqf-2.1.2/vqf/cpp", "vqf-2.1.2.toml"),
)}


class Unavailable(RuntimeError):
    """The sdist cannot be fetched (no network)."""


def _sha256(p: Path) -> str:
    return hashlib.sha256(p.read_bytes()).hexdigest()


def fetch(name: str) -> Path:
    """The directory of the peer's sources, extracted from its checked sdist."""
    peer = PEERS[name]
    CACHE.mkdir(parents=True, exist_ok=True)
    sdist = CACHE / peer.sdist
    if not (sdist.exists() and _sha256(sdist) == peer.sha256):
        with tempfile.TemporaryDirectory(dir=CACHE) as tmp:
            got = Path(tmp) / peer.sdist
            try:
                with urllib.request.urlopen(peer.url, timeout=60) as r, open(got, "wb") as f:
                    shutil.copyfileobj(r, f)
            except OSError as e:
                raise Unavailable(f"cannot fetch {peer.url}: {e}") from None
            if _sha256(got) != peer.sha256:
                raise RuntimeError(f"{peer.sdist}: SHA-256 {_sha256(got)}, expected {peer.sha256}")
            shutil.move(str(got), sdist)
    out = CACHE / f"src-{peer.sha256[:12]}"
    if not (out / peer.subdir).is_dir():
        with tempfile.TemporaryDirectory(dir=CACHE) as tmp:
            with tarfile.open(sdist) as tf:
                tf.extractall(tmp, filter="data")
            shutil.rmtree(out, ignore_errors=True)
            shutil.move(tmp, out)
            os.makedirs(tmp, exist_ok=True)   # for the context manager's cleanup
    return out / peer.subdir


if __name__ == "__main__":
    for n in PEERS:
        print(f"{n}: {fetch(n)}")
    sys.exit(0)
