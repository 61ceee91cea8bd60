"""The dependency direction of the Python package: cli -> catalogue ->
{imufuse_c, reference} -> shared helpers, floor by floor (FLOORS, docs/architecture.md),
without cycles, and no import of a project module inside a function body (the usual way to
hide a cycle). And the tree's rules: no source file over 500 lines without a reason, nothing
loaded by path, every folder of the package in the wheel."""
import ast
import re
from pathlib import Path

import pytest

import imufuse

PKG = Path(imufuse.__file__).resolve().parent
# the Cython sources of the compiled module (a checkout, or the sdist the tests install)
CSRC_PYX = Path(__file__).resolve().parents[1] / "imufuse_c"


def _modules():
    for p in sorted(PKG.rglob("*.py")):
        rel = p.relative_to(PKG.parent).with_suffix("")
        parts = list(rel.parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        yield ".".join(parts), p, p.name == "__init__.py"


def _target(mod, is_pkg, node):
    """Absolute name of a project module an import statement refers to, or None."""
    if isinstance(node, ast.Import):
        names = [a.name for a in node.names]
    else:
        base = mod.split(".") if is_pkg else mod.split(".")[:-1]
        if node.level:
            base = base[:len(base) - node.level + 1]
            head = ".".join(base + ([node.module] if node.module else []))
        else:
            head = node.module or ""
        names = [head] + [f"{head}.{a.name}" for a in node.names]
    return [n for n in names if n.split(".")[0] in ("imufuse", "imufuse_c")]


def _graph():
    mods = {m: (p, pkg) for m, p, pkg in _modules()}
    edges, inner = {}, []
    for m, (p, pkg) in mods.items():
        tree = ast.parse(p.read_text())
        deps = set()
        for node in ast.walk(tree):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                for t in _target(m, pkg, node):
                    # `from . import x` names a submodule or an attribute: keep what exists
                    while t and t not in mods and t != "imufuse_c":
                        t = t.rpartition(".")[0]
                    if t and t != m:
                        deps.add(t)
        for fn in ast.walk(tree):
            if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                for node in ast.walk(fn):
                    if isinstance(node, (ast.Import, ast.ImportFrom)) and _target(m, pkg, node):
                        inner.append(f"{m}.{fn.name}: line {node.lineno}")
        edges[m] = deps
    edges["imufuse_c"] = _compiled_imports(set(mods))
    return edges, inner


def _compiled_imports(mods):
    """The project modules the compiled module imports (its .pyx and .pxi files), as one
    node: imufuse_c -> imufuse.x is an edge of the graph like any other."""
    deps = set()
    for p in sorted(CSRC_PYX.glob("*.p[yx][xi]")) + [CSRC_PYX / "__init__.py"]:
        for line in p.read_text().splitlines():
            m = re.match(r"\s*(?:from\s+(\S+)\s+import\s+(\w+)|import\s+(\S+))", line)
            if not m:
                continue
            names = [m.group(3)] if m.group(3) else [m.group(1), f"{m.group(1)}.{m.group(2)}"]
            for t in names:
                if t.split(".")[0] != "imufuse":
                    continue
                while t and t not in mods:
                    t = t.rpartition(".")[0]
                if t:
                    deps.add(t)
    return deps


def test_the_compiled_module_is_in_the_graph():
    """imufuse_c's own imports are read, so that a cycle through it (imufuse.x imports
    imufuse_c, which imports imufuse.x) fails test_no_import_cycles."""
    deps = _graph()[0]["imufuse_c"]
    assert {"imufuse.shared.checks", "imufuse.reference"} <= deps, deps
    assert not {d for d in deps if d.startswith(("imufuse.catalogue", "imufuse.session", "imufuse.cli"))}


def test_no_project_imports_in_function_bodies():
    _, inner = _graph()
    assert not inner, inner


def test_no_import_cycles():
    edges, _ = _graph()
    # a package's __init__ re-exporting its submodules is not a cycle of the design
    def deps(m):
        return {d for d in edges.get(m, ()) if not (m.startswith(d + ".") and edges.get(d))}
    state, stack = {}, []

    def visit(m):
        state[m] = "open"
        stack.append(m)
        for d in sorted(deps(m)):
            if state.get(d) == "open":
                raise AssertionError("import cycle: " + " -> ".join(stack[stack.index(d):] + [d]))
            if d not in state:
                visit(d)
        stack.pop()
        state[m] = "done"
    for m in sorted(edges):
        if m not in state:
            visit(m)


def test_direction():
    """The layers: nothing below the catalogue imports it or the command line."""
    edges, _ = _graph()
    low = [m for m in edges if m.startswith(("imufuse.reference", "imufuse.shared")) or m == "imufuse.rotations"]
    assert {"imufuse.shared.checks", "imufuse.shared.bits", "imufuse.shared.cproto",
            "imufuse.shared.estimate"} <= set(low), low
    for m in low:
        bad = {d for d in edges[m] if d in ("imufuse.catalogue", "imufuse.cli")
               or d.startswith(("imufuse.firmware", "imufuse.mcu", "imufuse.tools"))}
        assert not bad, f"{m} imports {bad}"


#: The floors of docs/architecture.md, top down: a module by its name or the package it is in
#: (the longest name that matches). Every import goes to the module's own floor or below. A
#: folder is on one floor (imufuse.shared the lowest, imufuse.tools the sessions'); the modules
#: named one by one are the public ones a user imports by their documented path (README.md,
#: docs/), which stay at the top of the package, and the two modules of a folder on another
#: floor than its package (imufuse.vario.log, imufuse.calibration.fit).
FLOORS = [
    ("command line", {"imufuse.cli", "imufuse.__main__"}),
    ("sessions and tools", {"imufuse.session", "imufuse.tune", "imufuse.comparison", "imufuse.testing",
                            "imufuse.tools", "imufuse.vario.log", "imufuse.calibration", "imufuse.firmware",
                            "imufuse.mcu"}),
    ("data and filters", {"imufuse.io", "imufuse.preprocess", "imufuse.plots", "imufuse.catalogue",
                          "imufuse.registry", "imufuse.sim", "imufuse.vario", "imufuse.vario.pipeline"}),
    ("compiled and twins", {"imufuse_c", "imufuse.reference"}),
    ("helpers", {"imufuse", "imufuse.shared", "imufuse.rotations", "imufuse.evaluation",
                 "imufuse.latency", "imufuse.plausible", "imufuse.calibration.fit"}),
]


def test_the_top_level_modules_are_the_public_ones():
    """The folders say the floor: a module left at the top of the package is one a user imports
    by its documented path (FLOORS names it), every other module sits in a folder."""
    top = {p.stem for p in PKG.glob("*.py")} - {"__init__", "__main__"}
    named = {n.split(".")[1] for _, ns in FLOORS for n in ns if n.count(".") == 1}
    folders = {p.name for p in PKG.iterdir() if (p / "__init__.py").is_file()}
    assert top <= named, sorted(top - named)
    assert not top & folders


def _floor(module):
    """The floor's index (0 = the top) of a module: its own entry, else its package's."""
    names = {n: k for k, (_, ns) in enumerate(FLOORS) for n in ns}
    m = module
    while m and m not in names:
        m = m.rpartition(".")[0]
    assert m, f"{module} is on no floor of FLOORS (docs/architecture.md)"
    return names[m]


def test_every_import_goes_down_the_floors():
    """The floors as the tree has them: no module imports a module of a higher floor (the
    calibration models sit with the preprocessing that applies them, imufuse.calibration's log
    fitting above; the metrics below the compiled module that scores with them)."""
    edges, _ = _graph()
    up = [f"{m} ({FLOORS[_floor(m)][0]}) imports {d} ({FLOORS[_floor(d)][0]})"
          for m in sorted(edges) for d in sorted(edges[m])
          if _floor(d) < _floor(m) and not d.startswith(m + ".")]
    assert not up, up


def test_the_namespace_stops_at_the_cli_border():
    """argparse lives in imufuse.cli only: below it, options are typed settings
    (imufuse.session's dataclasses), so no module outside the command line imports argparse,
    builds parser arguments, or reads attributes off an argparse Namespace."""
    bad = []
    for m, p, _ in _modules():
        if m == "imufuse.cli" or m.startswith("imufuse.cli."):
            continue
        tree = ast.parse(p.read_text())
        for node in ast.walk(tree):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                names = [a.name for a in node.names] + [getattr(node, "module", None) or ""]
                if any(n.split(".")[0] == "argparse" for n in names):
                    bad.append(f"{m}: imports argparse (line {node.lineno})")
            if isinstance(node, ast.Attribute) and node.attr in ("add_argument",
                                                                 "add_argument_group"):
                bad.append(f"{m}: builds command-line options (line {node.lineno})")
            if isinstance(node, ast.Name) and node.id == "Namespace":
                bad.append(f"{m}: uses a Namespace (line {node.lineno})")
    assert not bad, bad


def test_the_commands_run_through_the_session():
    """Every log command reads its log through imufuse.session (one way of reading, units,
    preprocessing and scoring): no module of the command line calls the log reader, the
    preprocessing or the evaluation itself."""
    edges, _ = _graph()
    for m, p, _ in _modules():
        if m == "imufuse.cli" or m.startswith("imufuse.cli."):
            assert "read_log(" not in p.read_text(), f"{m} reads logs itself"
            assert not any(d == "imufuse.preprocess" or d.startswith("imufuse.preprocess.")
                           for d in edges[m]), f"{m} preprocesses itself"
            assert not {"evaluate", "mean_over_trials"} & {
                a.name for node in ast.walk(ast.parse(p.read_text()))
                if isinstance(node, ast.ImportFrom) for a in node.names}, f"{m} scores itself"
    assert "imufuse.session" in edges["imufuse.cli.common"]
    for m in ("imufuse.session", "imufuse.tune"):
        assert not any(d == "imufuse.cli" or d.startswith("imufuse.cli.") for d in edges[m]), m


ROOT = Path(__file__).resolve().parents[1]
REASON = "Longer than 500 lines because:"


def _sources():
    """Every source file the size rule covers: the Python package, the bindings, the C library,
    the tests, the benchmarks, the research scripts and the tools."""
    def tree(top, *patterns):
        return [p for pat in patterns for p in sorted((ROOT / top).rglob(pat))] if (ROOT / top).is_dir() else []
    return [*PKG.rglob("*.py"), *(ROOT / "imufuse_c").glob("*.p[yx][xi]"),
            *tree("csrc", "*.c", "*.h"),
            *(p for top in ("tests", "bench", "research", "tools") for p in tree(top, "*.py", "*.c", "*.h"))]


def test_no_module_over_500_lines_without_a_reason():
    """A source file over 500 lines says why in its first lines ("Longer than 500 lines because:"):
    the Python package, the bindings, csrc/, tests/, bench/, research/ and tools/."""
    files = _sources()
    assert any(p.suffix == ".c" for p in files) and any(p.parent.name == "tests" for p in files)
    long = [p for p in files if len(p.read_text().splitlines()) > 500
            and REASON not in "".join(p.read_text().splitlines(True)[:40])]
    assert not long, [f"{p}: {len(p.read_text().splitlines())} lines" for p in long]


# Loading a module from its file (importlib's loaders from a file location, running a file as
# a module, a path put on the import path in code or in a child's script) instead of importing
# it by name; each pattern is written so that this file does not match it itself.
BY_PATH = re.compile(r"spec_from_file_locatio[n]|SourceFileLoade[r]|\bload_sourc[e]\b|\brunp[y]\b"
                     r"|\bsys\.pat[h]\s*(?:\.(?:insert|append|extend)\s*\(|\[[^\]]*\]\s*=|\+?=(?!=))")
#: the files that must load by path, and why
BY_PATH_ALLOWED = {
    "setup.py": "tools/bindgen.py, before anything is built or installed (tools/ is no package)",
    "tools/bindgen.py": "imufuse.shared.cproto, which is not importable while the package is being built",
    "python/imufuse/firmware/host.py": "the user's firmware, compiled by cffi at run time into a "
                                       "cache directory",
    "tests/fusion_oracle.py": "the published Fusion C and imufusion, compiled from the sdist in "
                              "the test session, beside any installed imufusion",
    "bench/plain_loop.py": "the plain C loop, compiled by cffi at run time",
}


def test_nothing_loads_a_file_by_path():
    """Modules are imported by name (the package, and the helpers on the suite's pythonpath in
    pyproject.toml), never loaded from their file: the filter matrix is imufuse.registry, the
    MCU measurement's cases are bench/mcu/mcu_cases.py. A child process gets its paths through
    PYTHONPATH. Only the files above compile what they load or run before the build."""
    files = [ROOT / "setup.py", *(p for top in ("python", "tests", "bench", "research", "tools")
                                  for p in sorted((ROOT / top).rglob("*.py")))]
    found = {p.relative_to(ROOT).as_posix(): BY_PATH.findall(p.read_text()) for p in files if p.is_file()}
    bad = {f: m for f, m in found.items() if m and f not in BY_PATH_ALLOWED}
    assert not bad, bad
    stale = [f for f in BY_PATH_ALLOWED if (ROOT / f).is_file() and not found.get(f)]
    assert not stale, f"allowed to load by path but no longer does: {stale}"


def test_the_package_does_not_import_the_test_matrix():
    """imufuse.registry (the configurations the suites run) sits above the catalogue: no module
    of the package imports it."""
    edges, _ = _graph()
    users = [m for m, deps in edges.items() if "imufuse.registry" in deps]
    assert not users, users


def test_every_subpackage_is_in_the_wheel():
    """pyproject.toml names its packages one by one: a folder of the package moved or added
    (imufuse.preprocess, say) is listed there, or the wheel would go without it."""
    tomllib = pytest.importorskip("tomllib")
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    folders = {".".join(p.parent.relative_to(PKG.parent).parts) for p in PKG.rglob("__init__.py")}
    assert folders <= listed, sorted(folders - listed)
