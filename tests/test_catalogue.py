"""The catalogue is complete and true: every exported filter has an entry,
every entry reaches every harness (registry, demo/CLI, firmware harness, MCU
runner, fixed-point driver, stubs), and what an entry derives agrees with the C
headers."""
import inspect
import re
from pathlib import Path

import pytest

import imufuse.reference as reference
import imufuse_c
from imufuse import catalogue
from imufuse.shared import cproto, recovery
from imufuse.shared.checks import KINDS
from imufuse.shared.resources import csrc_dir
from imufuse.tools.stubs import stubs
from imufuse.shared.estimate import ADAPTERS
from imufuse.mcu import filters as mcu_filters
import bindgen
from imufuse.registry import CASES_VARIO, FIXED_CASES, FLOAT_CASES, FUSION_CASES

HEADERS = "\n".join(p.read_text() for p in sorted(csrc_dir().rglob("*.h")))
ENTRIES = [pytest.param(e, id=e.name) for e in (*catalogue.FLOAT, *catalogue.FIXED)]
#: the sections with an API of their own: the Fusion suite and the variometer
OWN = [pytest.param(e, id=e.name) for e in (*catalogue.FUSION, *catalogue.VARIO)]
EVERY = [*ENTRIES, *OWN]
ROOT = Path(__file__).resolve().parents[1]      # the source tree (a checkout or the sdist)


def test_every_exported_filter_has_one_entry():
    assert sorted(catalogue.FILTERS) == sorted(reference.FILTERS)
    assert sorted(catalogue.FILTERS_FIXED) == sorted(reference.FILTERS_FIXED)
    assert sorted(catalogue.FILTERS) == sorted(imufuse_c.FILTERS)
    assert sorted(catalogue.FILTERS_FIXED) == sorted(imufuse_c.FILTERS_FIXED)
    assert sorted(catalogue.FILTERS_FUSION) == sorted(reference.FILTERS_FUSION) == sorted(imufuse_c.FILTERS_FUSION)
    assert sorted(catalogue.FILTERS_VARIO) == sorted(reference.FILTERS_VARIO) == sorted(imufuse_c.FILTERS_VARIO)
    assert len(catalogue.ENTRIES) == len(catalogue.FLOAT) + len(catalogue.FIXED)
    assert len(catalogue.ALL_ENTRIES) == len(EVERY)
    assert all(e.fixed for e in catalogue.FIXED) and not any(e.fixed for e in catalogue.FLOAT)


@pytest.mark.parametrize("e", ENTRIES)
def test_entry_matches_both_backends(e):
    ref, comp = e.reference, e.compiled
    assert ref.__name__ == e.name
    assert e.kind in KINDS
    kw = dict(dtype="float64") if not e.fixed else {}
    c = e.make("c", dt=0.01, **e.defaults, **kw)
    r = e.make("ref", dt=0.01, **e.defaults, **kw)
    assert tuple(c.state_names) == tuple(r.state_names) == e.state_names
    assert c.kind == r.kind == e.kind
    assert len(c.state) == len(e.state_names)
    if not e.fixed:
        # imufuse_c's constructor shows the reference signature, dtype and how
        # the filter starts (state=; init=, init_window=, q0= for the 3-D filters)
        start = ["state"] if e.kind == "1d" else ["init", "init_window", "q0", "state"]
        params = list(inspect.signature(comp).parameters)
        assert params == [*e.params, "dtype", *start]


@pytest.mark.parametrize("e", ENTRIES)
def test_entry_c_prototypes_match_by_name(e):
    """The C init takes the reference's _init arguments, by name and in order
    (the Cython binding passes them by name); update takes the kind's inputs."""
    init = cproto.init_params(HEADERS, e.c_name + "_init")
    update = cproto.find_prototype(HEADERS, e.c_update)
    assert init is not None and update is not None, f"{e.c_name}_init/{e.c_update} not in csrc/"
    assert f"}} {e.c_name}_t;" in HEADERS
    c_args = tuple(p.name for p in init[1])
    want = e.init_args
    if e.fixed and "profile" not in c_args:   # profile selects the update, not an init value
        want = tuple(a for a in want if a != "profile")
    assert c_args == want, f"{e.c_name}_init{c_args} vs reference _init{e.init_args}"
    if not e.fixed:   # per-sample dt and, for 3-D filters, the start attitude
        hooks = ["_set_dt"] + ([] if e.kind == "1d" else ["_set_attitude"])
        for h in hooks:
            assert cproto.find_prototype(HEADERS, e.c_name + h) is not None, e.c_name + h
            assert callable(getattr(e.reference, h, None)), f"{e.name}.{h}"
    n_in = sum(1 if e.kind == "1d" else 3 for _ in e.inputs)
    n_c = sum(3 if p.vector else 1 for p in update.params[1:])
    assert n_c == n_in, f"{e.c_update} takes {n_c} values, kind {e.kind} gives {n_in}"


@pytest.mark.parametrize("e", ENTRIES)
def test_entry_defaults_construct_and_estimate(e):
    """The defaults are complete (every required parameter but dt) and valid;
    the adapter reads the state."""
    required = {k for k, v in e.params.items() if v is inspect.Parameter.empty} - {"dt"}
    assert required <= set(e.defaults), f"no default for {sorted(required - set(e.defaults))}"
    assert set(e.defaults) <= set(e.params)
    for alt in e.alternatives:
        assert alt <= set(e.params), alt
    kw = dict(dtype="float64") if not e.fixed else {}
    f = e.make("ref", dt=0.01, **e.defaults, **kw)
    e.make("c", dt=0.01, **e.defaults, **kw)
    assert e.estimate is None or e.estimate in ADAPTERS
    if e.estimate and not e.fixed:
        est = catalogue.estimate(e.reference, f.state[None, :])
        assert est is not None and (est.angle is not None or est.q is not None)


@pytest.mark.parametrize("e", ENTRIES)
def test_entry_reaches_every_harness(e):
    cases = FIXED_CASES if e.fixed else FLOAT_CASES
    assert any(c.name == e.name for c in cases), "missing from imufuse.registry"
    # MCU runner and firmware harness: the prototypes they read
    cf = mcu_filters.c_library(e.c_name)
    assert cf.init == cproto.init_params(HEADERS, e.c_name + "_init")[1]
    if not e.fixed:
        assert e.name in catalogue.filter_names()       # demo and CLI
        assert catalogue.resolve_params(e.name, 0.01)["dt"] == 0.01


def test_unknown_names_are_reported():
    with pytest.raises(catalogue.FilterError, match="did you mean MadgwickIMU"):
        catalogue.entry("MadgwickIMUU")
    with pytest.raises(catalogue.FilterError, match="fixed-point"):
        catalogue.reference_class("KKQ")
    for name in (*catalogue.FILTERS_FUSION, *catalogue.FILTERS_VARIO):
        with pytest.raises(catalogue.FilterError, match=f"^{name}: has an API of its own"):
            catalogue.entry(name)


def test_stubs_are_generated_from_the_catalogue():
    """imufuse_c/__init__.pyi (shipped with the package) is what the catalogue
    generates: regenerate with `python -m imufuse.tools.stubs > imufuse_c/__init__.pyi`."""
    shipped = Path(imufuse_c.__file__).with_name("__init__.pyi")
    assert shipped.is_file(), "imufuse_c/__init__.pyi is not installed"
    assert shipped.read_text() == stubs(), "stale stubs: python -m imufuse.tools.stubs > imufuse_c/__init__.pyi"
    assert Path(imufuse_c.__file__).with_name("py.typed").is_file()
    for name in (*catalogue.FILTERS, *catalogue.FILTERS_FIXED):
        assert f"\nclass {name}(" in shipped.read_text()


@pytest.mark.parametrize("e", ENTRIES)
def test_stub_methods_exist(e):
    """What the stubs promise, the compiled class has."""
    text = stubs()
    body = text.split(f"\nclass {e.name}(")[1].split("\nclass ")[0]
    kw = dict(dtype="float64") if not e.fixed else {}
    f = e.make("c", dt=0.01, **e.defaults, **kw)
    for name in re.findall(r"    def (\w+)\(", body):
        assert name == "__init__" or callable(getattr(f, name)), name
    ctor = inspect.signature(e.compiled) if not e.fixed else None
    if ctor is not None:
        for p in ctor.parameters:
            assert f" {p}: " in body.split("def __init__(")[1].split(") -> None")[0], p


def test_fusion_suite_in_the_catalogue():
    """The Fusion suite has its own catalogue section (outside FLOAT, see
    catalogue.FUSION for why), consistent with both backends."""
    assert catalogue.FILTERS_FUSION == reference.FILTERS_FUSION == imufuse_c.FILTERS_FUSION
    for e in catalogue.FUSION:
        c, r = e.compiled, e.reference
        assert tuple(c.state_names) == tuple(r.state_names) == e.state_names
        params = {k for k in e.params if k != "dtype"}
        assert set(e.defaults) <= params, e.name
        f = e.make("c", **e.defaults)
        assert len(f.state) == len(e.state_names)


@pytest.mark.parametrize("e", EVERY)
def test_binding_is_compiled(e):
    """setup.py generates the include list of imufuse_c/_f32.pyx and _f64.pyx from
    the reference modules' filter classes, and each float family's binding
    (tools/bindgen.py) unless it is written by hand: the entry's binding defines the
    class, and the class is in the compiled modules."""
    pxi = ROOT / e.binding
    text = pxi.read_text() if pxi.is_file() else bindgen.fixed_pxi() if e.fixed else \
        bindgen.family_pxi(e.family)
    assert re.search(rf"^cdef class {e.name}\b", text, re.M), f"{e.binding} defines no class {e.name}"
    if e.fixed:
        assert hasattr(imufuse_c._fixed, e.name)
    else:
        for mod in (imufuse_c._f32, imufuse_c._f64):
            assert hasattr(mod, e.name), f"{e.name} not compiled into {mod.__name__}: is {e.binding} included?"


def test_hand_written_bindings_say_why():
    """A float family's binding is generated unless its API is its own: each hand-written
    imufuse_c/<family>.pxi states the reason in its first lines, and no hand-written file
    could have been generated."""
    for pxi in sorted((ROOT / "imufuse_c").glob("*.pxi")):
        family = pxi.stem
        if family not in bindgen.families():
            continue   # shared pieces (_base.pxi, fixed_base.pxi, ...), not a family's binding
        head = "".join(pxi.read_text().splitlines(keepends=True)[:6])
        assert "Hand-written (not tools/bindgen.py):" in head, f"{pxi.name}: say why it is not generated"
        with pytest.raises(SystemExit):
            bindgen.family_pxi(family)


@pytest.mark.parametrize("e", [*catalogue.FLOAT, *catalogue.FUSION], ids=lambda e: e.name)
def test_entry_declares_its_recovery_budget(e):
    """Every float and Fusion entry states how many samples it needs to come back
    after a hostile burst (tests/test_hostile.py runs that many), as a function of
    its parameters whose documentation gives the derivation."""
    assert e.recovery is not None, f"{e.name}: no recovery= in its catalogue entry (imufuse.shared.recovery)"
    assert len(inspect.getdoc(e.recovery) or "") > 80, f"{e.recovery.__name__}: no derivation documented"
    for dtype in ("float32", "float64"):
        n = e.recovery_budget(dict(e.defaults, **({} if e in catalogue.FUSION else dict(dt=0.01))),
                              dtype, dt=0.01)
        assert isinstance(n, int) and recovery.MARGIN < n < 10 ** 8, (e.name, dtype, n)


@pytest.mark.parametrize("e", OWN)
def test_own_api_sections_reach_every_harness(e):
    """The Fusion suite and the variometer: their own catalogue sections, read by
    the registry (whose matrices test_fusion.py, test_fusion_oracle.py,
    test_hostile.py and test_vario.py run), the stubs, the MCU runner's header
    reader and the benchmarks (bench/test_bench_*.py time them by name)."""
    cases = FUSION_CASES if e in catalogue.FUSION else CASES_VARIO
    assert any(c.name == e.name for c in cases), "missing from imufuse.registry"
    c = e.make("c", **e.defaults)
    r = e.make("ref", **e.defaults)
    assert tuple(c.state_names) == tuple(r.state_names) == e.state_names
    assert f"\nclass {e.name}(" in stubs()
    cf = mcu_filters.c_library(e.c_name)
    assert cf.init == cproto.init_params(HEADERS, e.c_name + "_init")[1]
    for name in vars(e.reference):     # the compiled class has the reference's methods
        if not name.startswith("_") and inspect.isfunction(getattr(e.reference, name)):
            assert callable(getattr(c, name, None)), f"{e.name}.{name}"
    bench = "".join(p.read_text() for p in sorted((ROOT / "bench").glob("test_bench_*.py")))
    assert f"{e.name}(" in bench, f"{e.name}: no benchmark in bench/test_bench_*.py"
