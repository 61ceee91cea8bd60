"""Build imufuse_c from csrc/ + imufuse_c/*.pyx, once per precision."""
import glob

import numpy
from Cython.Build import cythonize
from setuptools import Extension, setup

# The numerical contract: C99, -O2, no contraction into FMA, never -ffast-math
# or -march=native (see csrc/imf_config.h).
CFLAGS = ["-std=c99", "-O2", "-ffp-contract=off"]
CSRC = sorted(glob.glob("csrc/*.c") + glob.glob("csrc/fixed/*.c"))


def build(name, macros):
    return Extension(f"imufuse_c.{name}", [f"imufuse_c/{name}.pyx", *CSRC],
                     include_dirs=["csrc", "csrc/fixed", numpy.get_include()],
                     define_macros=[*macros, ("NPY_NO_DEPRECATED_API", "NPY_1_7_API_VERSION")],
                     extra_compile_args=CFLAGS)


setup(ext_modules=cythonize([build("_f32", []), build("_f64", [("IMF_DOUBLE", None)]),
                             build("_fixed", [])],  # csrc/fixed: one build, both profiles
                            compiler_directives={"language_level": 3}))
