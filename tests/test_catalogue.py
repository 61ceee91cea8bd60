"""The catalogue is complete and true: every exported filter has an entry,
every entry reaches every harness (registry, demo/CLI, firmware harness, MCU
runner, fixed-point driver, stubs), and what an entry derives agrees with the C
headers."""
import inspect
from pathlib import Path

import pytest

import imufuse.reference as reference
import imufuse_c
from imufuse import catalogue, cproto
from imufuse._checks import KINDS
from imufuse._resources import csrc_dir
from imufuse._stubs import stubs
from imufuse.estimate import ADAPTERS
from imufuse.mcu import filters as mcu_filters
from registry import FIXED_CASES, FLOAT_CASES

HEADERS = "\n".join(p.read_text() for p in sorted(csrc_dir().rglob("*.h")))
ENTRIES = [pytest.param(e, id=e.name) for e in (*catalogue.FLOAT, *catalogue.FIXED)]


def test_every_exported_filter_has_one_entry():
    assert sorted(catalogue.FILTERS) == sorted(reference.FILTERS)
    assert sorted(catalogue.FILTERS_FIXED) == sorted(reference.FILTERS_FIXED)
    assert sorted(catalogue.FILTERS) == sorted(imufuse_c.FILTERS)
    assert sorted(catalogue.FILTERS_FIXED) == sorted(imufuse_c.FILTERS_FIXED)
    assert len(catalogue.ENTRIES) == len(catalogue.FLOAT) + len(catalogue.FIXED)
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
    init = cproto.find_prototype(HEADERS, e.c_name + "_init")
    update = cproto.find_prototype(HEADERS, e.c_name + "_update")
    assert init is not None and update is not None, f"{e.c_name}_init/_update not in csrc/"
    assert f"}} {e.c_name}_t;" in HEADERS
    c_args = tuple(p.name for p in init.params[1:])
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
    assert n_c == n_in, f"{e.c_name}_update takes {n_c} values, kind {e.kind} gives {n_in}"


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
    assert any(c.name == e.name for c in cases), "missing from tests/registry.py"
    # MCU runner and firmware harness: the prototypes they read
    cf = mcu_filters.c_library(e.c_name)
    assert len(cf.init) == len(cproto.find_prototype(HEADERS, e.c_name + "_init").params) - 1
    if not e.fixed:
        assert e.name in catalogue.filter_names()       # demo and CLI
        assert catalogue.resolve_params(e.name, 0.01)["dt"] == 0.01


def test_unknown_names_are_reported():
    with pytest.raises(catalogue.FilterError, match="did you mean MadgwickIMU"):
        catalogue.entry("MadgwickIMUU")
    with pytest.raises(catalogue.FilterError, match="fixed-point"):
        catalogue.reference_class("KKQ")


def test_stubs_are_generated_from_the_catalogue():
    """imufuse_c/__init__.pyi (shipped with the package) is what the catalogue
    generates: regenerate with `python -m imufuse._stubs > imufuse_c/__init__.pyi`."""
    shipped = Path(imufuse_c.__file__).with_name("__init__.pyi")
    assert shipped.is_file(), "imufuse_c/__init__.pyi is not installed"
    assert shipped.read_text() == stubs(), "stale stubs: python -m imufuse._stubs > imufuse_c/__init__.pyi"
    assert Path(imufuse_c.__file__).with_name("py.typed").is_file()
    for name in (*catalogue.FILTERS, *catalogue.FILTERS_FIXED):
        assert f"\nclass {name}(" in shipped.read_text()


@pytest.mark.parametrize("e", ENTRIES)
def test_stub_methods_exist(e):
    """What the stubs promise, the compiled class has."""
    import re
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
