"""The compiled extension is built per precision and checks itself at import.

`setup.py` compiles every csrc source into a per-precision translation unit
(build/imufuse_units/<module>/), so a parallel build (`build_ext -j 2`) cannot
link float32 objects into the float64 module or the other way round; each
float module compares one update of every C family with the reference at
import and raises ImportError if they differ. These tests build a copy of the
tree (the Cython output is copied too, so only the C is compiled).
"""
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

CHECK = r"""
import imufuse_c, imufuse.reference as ref
assert imufuse_c.__file__.startswith({tree!r}), imufuse_c.__file__
for dtype in ("float32", "float64"):
    c = imufuse_c.Kalman1D(dt=.01, k0=.02, dtype=dtype)
    r = ref.Kalman1D(dt=.01, k0=.02, dtype=dtype)
    c.update(1, .5); r.update(1, .5)
    assert c.skipped == 0 and c.state.tobytes() == r.state.tobytes(), (dtype, c.state, r.state)
    assert abs(float(c.state[0]) - 0.0198) < 1e-6
print("ok")
"""


def _copy_tree(dst):
    for name in ("setup.py", "pyproject.toml", "MANIFEST.in"):
        if (ROOT / name).exists():
            shutil.copy2(ROOT / name, dst / name)
    shutil.copytree(ROOT / "csrc", dst / "csrc")
    # keep the generated Cython C (same mtimes): cythonize then has nothing to do
    shutil.copytree(ROOT / "imufuse_c", dst / "imufuse_c",
                    ignore=shutil.ignore_patterns("*.so", "__pycache__"))
    # setup.py lists the Cython bindings from the reference modules' filter classes;
    # the generated list keeps its mtime too (a tree built before: nothing to cythonize)
    shutil.copytree(ROOT / "python" / "imufuse" / "reference", dst / "python" / "imufuse" / "reference",
                    ignore=shutil.ignore_patterns("__pycache__"))
    # the bindings are generated from the headers and the twins (tools/bindgen.py, imufuse.shared.cproto)
    (dst / "tools").mkdir()
    shutil.copy2(ROOT / "tools" / "bindgen.py", dst / "tools")
    (dst / "python" / "imufuse" / "shared").mkdir()
    shutil.copy2(ROOT / "python" / "imufuse" / "shared" / "cproto.py", dst / "python" / "imufuse" / "shared")
    generated = sorted((ROOT / "build" / "imufuse_units").glob("*.pxi"))
    if generated:
        (dst / "build" / "imufuse_units").mkdir(parents=True)
        for g in generated:
            shutil.copy2(g, dst / "build" / "imufuse_units")


def _build(tree, *extra):
    # -O0 after the contract's flags (setup.py's IMUFUSE_EXTRA_CFLAGS): what these tests check
    # is which objects go into which module and the import self-check, not the speed
    env = {**os.environ, "IMUFUSE_EXTRA_CFLAGS": "-O0"}
    proc = subprocess.run([sys.executable, "setup.py", "build_ext", "--inplace", *extra],
                          cwd=tree, capture_output=True, text=True, timeout=900, env=env)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return proc


def _import(tree):
    code = CHECK.format(tree=str(tree))
    # the built tree and this checkout's package ahead of any installed imufuse
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tree), str(ROOT / "python")])}
    return subprocess.run([sys.executable, "-c", code], cwd=tree, capture_output=True,
                          text=True, timeout=120, env=env)


@pytest.fixture(scope="module")
def tree(tmp_path_factory):
    if shutil.which("cc") is None and shutil.which("gcc") is None:
        pytest.skip("no C compiler")
    d = tmp_path_factory.mktemp("tree")
    _copy_tree(d)
    _build(d, "-j", "2")
    return d


def test_parallel_build_gives_each_precision_its_objects(tree):
    objs = {p.relative_to(tree).as_posix() for p in (tree / "build").rglob("*.o")}
    for module in ("_f32", "_f64"):
        for src in sorted((ROOT / "csrc").glob("*.c")):
            want = f"imufuse_units/{module}/{src.stem}.o"
            assert any(o.endswith(want) for o in objs), (want, sorted(objs))
    # no object is compiled from csrc directly (shared between the precisions)
    assert not [o for o in objs if "/csrc/" in o], sorted(objs)
    proc = _import(tree)
    assert proc.returncode == 0 and proc.stdout.strip() == "ok", proc.stderr[-3000:]


def test_module_with_objects_of_the_other_precision_refuses_to_import(tree):
    """Link _f32 with float64 objects (what a racing build did): ImportError at import."""
    setup = (tree / "setup.py").read_text()
    bad = setup.replace('"#ifdef IMF_DOUBLE\\n#error \\"_f32 unit built with IMF_DOUBLE\\"\\n#endif\\n"',
                        '"#define IMF_DOUBLE\\n"')
    assert bad != setup, "setup.py's _f32 guard changed; update this test"
    (tree / "setup.py").write_text(bad)
    try:
        _build(tree)
        proc = _import(tree)
        assert proc.returncode != 0
        assert "ImportError" in proc.stderr and "_f32" in proc.stderr, proc.stderr[-3000:]
        assert "does not compute what the reference computes" in proc.stderr
    finally:
        (tree / "setup.py").write_text(setup)


def test_a_filter_family_without_its_c_pair_stops_the_build(tmp_path):
    """setup.py binds every reference module that declares filter classes (no hand-kept
    include list, no hand-written binding): a family whose header is missing, or does not
    define the filter's struct, stops the build with a message naming the file to fix."""
    if shutil.which("cc") is None and shutil.which("gcc") is None:
        pytest.skip("no C compiler")
    _copy_tree(tmp_path)
    new = tmp_path / "python" / "imufuse" / "reference" / "newfamily.py"
    for twin, header, message in (
            ('class NewFilter:\n    kind = "imu"\n    c_name = "imf_new"\n', None,
             "csrc/newfamily.h does not exist"),
            ('class NewFilter:\n    kind = "imu"\n    c_name = "imf_new"\n', "/* */\n",
             "csrc/newfamily.h: struct imf_new_t is not defined")):
        new.write_text(twin)
        if header:
            (tmp_path / "csrc" / "newfamily.h").write_text(header)
        proc = subprocess.run([sys.executable, "setup.py", "build_ext", "--inplace"], cwd=tmp_path,
                              capture_output=True, text=True, timeout=300)
        assert proc.returncode != 0
        assert message in proc.stdout + proc.stderr, proc.stderr[-3000:]
