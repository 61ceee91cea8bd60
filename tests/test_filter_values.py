"""Filters are values: copy.copy, copy.deepcopy and pickle of every filter of the catalogue,
compiled and reference, give an independent filter that continues bit for bit (the state and
the skipped count after every later sample), also mid-way through an init="first" window and
after rejected samples."""
import copy
import pickle

import numpy as np
import pytest

from imufuse import catalogue, sim
from imufuse.registry import each

HOW = {"copy": copy.copy, "deepcopy": copy.deepcopy,
       "pickle": lambda f: pickle.loads(pickle.dumps(f))}
D = sim.imu("fast", rate=100.0, duration=1.2, seed=9)


def _inputs(e, n0, n1):
    sl = slice(n0, n1)
    if e.kind == "1d":
        ins = [D.gyr[sl, 0].copy(), np.arctan2(D.acc[sl, 1], D.acc[sl, 2])]
    else:
        ins = [D.gyr[sl].copy(), D.acc[sl].copy()] + ([D.mag[sl].copy()] if e.kind == "ahrs"
                                                      else [])
    if e.fixed:
        scale = [e.defaults.get("gyr_scale", 1e-3)] + \
            [e.defaults.get("angle_scale", 1 / 4096.0)] * 2
        ins = [np.clip(np.rint(a / s), -32768, 32767).astype(np.int16) for a, s in zip(ins, scale)]
    if n0 == 0:
        ins[0][3] = np.nan if not e.fixed else ins[0][3]     # a rejected sample before the copy
    return tuple(ins)


def _generic(name, backend):
    e = catalogue.entry(name)
    params = catalogue.resolve_params(name, 0.01)
    kw = {} if e.fixed else {"dtype": "float32"}
    if not e.fixed and e.kind != "1d":
        kw["init"] = "first"
        kw["init_window"] = 40           # the copy is taken inside the window (after 30)
    return e, e.make(backend, **params, **kw)


GENERIC = [n for n in catalogue.ENTRIES]


@pytest.mark.parametrize("name", GENERIC)
@each("how", list(HOW))
@each("backend", ["c", "ref"])
def test_generic_filters_are_values(name, backend, how):
    e, f = _generic(name, backend)
    f.run(*_inputs(e, 0, 30))
    g = HOW[how](f)
    assert g is not f and type(g) is type(f)
    rest = _inputs(e, 30, 120)
    a, b = f.run(*rest), g.run(*rest)
    assert np.array_equal(np.asarray(a).view(np.uint8), np.asarray(b).view(np.uint8))
    if hasattr(f, "skipped"):
        assert f.skipped == g.skipped and (e.fixed or f.skipped >= 1)
    # independent: running one more sample on the copy leaves the original
    before = np.asarray(f.state).copy()
    g.run(*_inputs(e, 0, 5))
    assert np.array_equal(np.asarray(f.state), before)


@pytest.mark.parametrize("how", list(HOW))
@pytest.mark.parametrize("backend", ["c", "ref"])
def test_fusion_and_vario_are_values(backend, how):
    e = catalogue.ALL_ENTRIES
    fa = e["FusionAHRS"].make(backend, dtype="float32")
    fo = e["FusionOffset"].make(backend, sample_rate=100, dtype="float32") if backend == "ref" \
        else e["FusionOffset"].make(backend, sample_rate=100)
    vk = e["VarioKF"].make(backend, dtype="float32")
    gd, ag = np.degrees(D.gyr), D.acc
    for k in range(30):
        fa.update(gd[k], ag[k], D.mag[k], 0.01)
        fo.update(gd[k])
        vk.update(ag[k, 2] * 10.0, 100.0 + k, 0.01)
    if hasattr(fa, "set_settings"):
        fa.set_settings(gain=0.7)           # settings changed after construction travel too
    copies = [HOW[how](x) for x in (fa, fo, vk)]
    for k in range(30, 120):
        for x in (fa, copies[0]):
            x.update(gd[k], ag[k], D.mag[k], 0.01)
        for x in (fo, copies[1]):
            x.update(gd[k])
        for x in (vk, copies[2]):
            x.update(ag[k, 2] * 10.0, 100.0 + k, 0.01)
        for x, y in zip((fa, fo, vk), copies):
            assert np.array_equal(np.asarray(x.state).view(np.uint8),
                                  np.asarray(y.state).view(np.uint8))
