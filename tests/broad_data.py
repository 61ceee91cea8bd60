"""Where the BROAD development trials are (BROAD, Laidig et al. 2021, CC BY 4.0;
seven .npz files kept outside the repository): $IMUFUSE_BROAD, else
shared/data/broad beside the checkout (../shared or ../../shared), else
/work/shared/data/broad. BROAD is None when none of them exists; the tests that
need the trials skip with SKIP_REASON."""
import os

_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
_CANDIDATES = [os.environ.get("IMUFUSE_BROAD", ""),
               os.path.join(_ROOT, "..", "shared", "data", "broad"),
               os.path.join(_ROOT, "..", "..", "shared", "data", "broad"),
               "/work/shared/data/broad"]

BROAD = next((os.path.abspath(d) for d in _CANDIDATES
              if d and os.path.isfile(os.path.join(d, "03_undisturbed_slow_rotation_C.npz"))), None)
SKIP_REASON = ("BROAD development trials not found (set IMUFUSE_BROAD to the directory of the "
               "seven .npz files)")
