"""A plain C loop over a filter's update, compiled with cffi from csrc/:
the baseline that imufuse_c's run() is measured against. Same flags as the
extension (-std=c99 -O2 -ffp-contract=off); the loop stores the state after
every sample, as run() does."""
import glob
import importlib.util
import os
import tempfile

from cffi import FFI

from imufuse import catalogue
from imufuse.shared import cproto
from imufuse.shared.checks import KINDS
from imufuse.shared.resources import csrc_dir

CSRC = str(csrc_dir())


def _loop_source(ref_cls):
    """C for plain_<c_update>(n, inputs..., out, params): init from params, then
    update + memcpy of the state for every sample."""
    c, u = ref_cls.c_name, ref_cls.c_update
    ins = KINDS[ref_cls.kind]
    decl = ", ".join(f"const imf_real *{x}" for x in ins)
    if ref_cls.kind == "1d":
        call = f"{u}(&s, rate[k], angle[k]);"
    else:
        call = f"{u}(&s, " + ", ".join(f"{x}[3 * k + {j}]" for x in ins for j in range(3)) + ");"
    return (f"void plain_{u}(size_t n, {decl}, imf_real *out, const double *p, size_t np)\n"
            "{\n"
            f"    {c}_t s;\n"
            "    size_t k;\n"
            f"{_init_source(ref_cls)}"
            "    for (k = 0; k < n; ++k) {\n"
            f"        {call}\n"
            "        memcpy(out + k * (sizeof s.x / sizeof(imf_real)), &s.x, sizeof s.x);\n"
            "    }\n"
            "    (void)np;\n"
            "}\n"), f"void plain_{u}(size_t n, {decl}, imf_real *out, const double *p, size_t np);"


def _init_source(ref_cls):
    """The init call from p, the values of the twin's _params in the catalogue's init_args
    order: the arguments themselves, or the members of the settings struct the init takes
    (filled by name, as the generated bindings fill it)."""
    e = catalogue.entry(ref_cls.__name__)
    c = ref_cls.c_name
    with open(os.path.join(CSRC, e.family + ".h")) as f:
        settings, _ = cproto.init_params(f.read(), f"{c}_init")
    if settings is None:
        return f"    {c}_init(&s, " + ", ".join(f"p[{i}]" for i in range(len(e.init_args))) + ");\n"
    fill = "".join(f"    st.{n} = p[{i}];\n" for i, n in enumerate(e.init_args))
    return f"    {{\n    {settings} st;\n{fill}    {c}_init(&s, &st);\n    }}\n"


def build(dtype, ref_classes):
    """Compile plain loops for ref_classes in one precision; return (ffi, lib)."""
    ffi = FFI()
    real = "float" if dtype == "float32" else "double"
    bodies, decls = [], []
    for r in ref_classes:
        body, decl = _loop_source(r)
        bodies.append(body)
        decls.append(decl)
    ffi.cdef(f"typedef {real} imf_real;\n" + "\n".join(decls))
    headers = sorted(os.path.basename(h) for h in glob.glob(os.path.join(CSRC, "*.h")))
    src = ("#include <string.h>\n" + "".join(f'#include "{h}"\n' for h in headers)
           + "\n".join(bodies))
    sources = sorted(glob.glob(os.path.join(CSRC, "*.c")))
    macros_def = [] if dtype == "float32" else [("IMF_DOUBLE", None)]
    name = f"_imf_plain_{dtype}"
    ffi.set_source(name, src, sources=sources, include_dirs=[CSRC], define_macros=macros_def,
                   extra_compile_args=["-std=c99", "-O2", "-ffp-contract=off"])
    tmp = tempfile.mkdtemp(prefix="imf_plain_")
    lib_path = ffi.compile(tmpdir=tmp)
    spec = importlib.util.spec_from_file_location(name, lib_path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.ffi, mod.lib
