"""Files the installed package carries: the C library (csrc/) and the MCU
harness data, found through importlib.resources so that a wheel in
site-packages and a source checkout (editable install) behave alike.

In the source tree, python/imufuse/csrc is a link to the top-level csrc/ and
python/imufuse/mcu/data/install-toolchains.sh one to tools/; the wheel and the
sdist carry copies.
"""
from importlib.resources import files
from pathlib import Path


def _path(package: str, *parts: str) -> Path:
    p = files(package).joinpath(*parts)
    # the package is installed as plain files (wheel or editable), never zipped
    return Path(str(p))


def csrc_dir() -> Path:
    """The C library's directory: <family>.h/.c and fixed/."""
    return _path("imufuse", "csrc")


def mcu_data_dir() -> Path:
    """Port files, linker script and driver of the MCU harness."""
    return _path("imufuse.mcu", "data")


def install_toolchains_script() -> Path:
    """tools/install-toolchains.sh (the Debian toolchains of the MCU tests)."""
    return mcu_data_dir() / "install-toolchains.sh"
