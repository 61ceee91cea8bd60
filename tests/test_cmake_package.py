"""The C library as a package: `cmake --install` of csrc/ gives imufuseConfig.cmake, a version
file and imufuse.pc; clean consumer projects find it (find_package for the host and, through a
toolchain file, for the Cortex-M4F; pkg-config with a plain compiler) and their programs print
the Python reference's states bit for bit. The C version macros equal the package's version.
imufuse.pc is relocatable: installed with `cmake --install build --prefix P` (another prefix than
the configured one), or moved, it names the headers and library where they are.

The consumer program is examples/firmware/main.c (Mahony1DBias on recorded samples, the state
after every sample as bit patterns); the expected lines come from imufuse.reference
(test_cross_build._reference_lines).
"""
import re
import shutil
import subprocess
from pathlib import Path

import pytest

import imufuse
import imufuse.mcu as mcu
from imufuse.shared.resources import csrc_dir
from test_cross_build import EXAMPLE, _reference_lines, _run

ROOT = Path(__file__).resolve().parents[1]
CSRC = ROOT / "csrc"
ARM_TOOLCHAIN = EXAMPLE / "cmake" / "arm-none-eabi.cmake"


@pytest.fixture(scope="module")
def cmake():
    exe = shutil.which("cmake")
    assert exe, "cmake is in the test extra (pip install 'imufuse[test]')"
    return exe


@pytest.fixture(scope="module")
def host_prefix(cmake, tmp_path_factory):
    """csrc/ configured with its defaults, built and installed for the host once: the tests
    that only read the installed package (find_package, the version file, pkg-config) share
    it."""
    return _install(cmake, tmp_path_factory.mktemp("host"), "host")


def _install(cmake, tmp_path, name, extra=()):
    prefix = tmp_path / f"prefix-{name}"
    build = tmp_path / f"build-{name}"
    _run([cmake, "-S", CSRC, "-B", build, f"-DCMAKE_INSTALL_PREFIX={prefix}", *extra])
    _run([cmake, "--build", build])
    _run([cmake, "--install", build])
    return prefix


def _consumer(tmp_path, name, sources, link_options=""):
    d = tmp_path / f"consumer-{name}"
    d.mkdir()
    for s in sources:
        shutil.copy(s, d / Path(s).name)
    (d / "CMakeLists.txt").write_text(
        "cmake_minimum_required(VERSION 3.13)\n"
        "project(consumer LANGUAGES C)\n"
        f"find_package(imufuse {imufuse.__version__} CONFIG REQUIRED)\n"
        f"add_executable(consumer {' '.join(Path(s).name for s in sources)})\n"
        "set_target_properties(consumer PROPERTIES C_STANDARD 99 C_EXTENSIONS OFF)\n"
        "target_include_directories(consumer PRIVATE ${CMAKE_CURRENT_SOURCE_DIR})\n"
        "target_link_libraries(consumer PRIVATE imufuse::imufuse)\n" + link_options)
    return d


def test_version_macros_equal_the_package_version():
    for d in (CSRC, csrc_dir()):
        text = (Path(d) / "imf_version.h").read_text()
        m = {k: v for k, v in re.findall(r"#define IMF_VERSION_(\w+) (\S+)", text)}
        assert m["STRING"] == f'"{imufuse.__version__}"'
        assert ".".join((m["MAJOR"], m["MINOR"], m["PATCH"])) == imufuse.__version__


def test_host_find_package(cmake, host_prefix, tmp_path):
    prefix = host_prefix
    for f in ("imufuseConfig.cmake", "imufuseConfigVersion.cmake", "imufuseTargets.cmake"):
        assert (prefix / "lib" / "cmake" / "imufuse" / f).is_file()
    assert (prefix / "include" / "imufuse" / "imf_version.h").is_file()
    src = _consumer(tmp_path, "host", [EXAMPLE / "main.c", EXAMPLE / "board_host.c",
                                       EXAMPLE / "board.h", EXAMPLE / "recorded_samples.h"])
    build = tmp_path / "cb-host"
    _run([cmake, "-S", src, "-B", build, f"-DCMAKE_PREFIX_PATH={prefix}"])
    _run([cmake, "--build", build])
    assert _run([build / "consumer"]).stdout.splitlines() == _reference_lines()


def test_version_file_refuses_another_major(cmake, host_prefix, tmp_path):
    prefix = host_prefix
    d = tmp_path / "consumer-ver"
    d.mkdir()
    (d / "CMakeLists.txt").write_text("cmake_minimum_required(VERSION 3.13)\nproject(c C)\n"
                                      "find_package(imufuse 99.0 CONFIG REQUIRED)\n")
    p = subprocess.run([cmake, "-S", str(d), "-B", str(tmp_path / "b"),
                        f"-DCMAKE_PREFIX_PATH={prefix}"], capture_output=True, text=True)
    assert p.returncode != 0 and "version found is not compatible" in p.stderr, p.stderr


def test_cortex_m4f_find_package_runs_bit_exact(cmake, tmp_path):
    missing = mcu.ensure_toolchains(("m4f",))
    assert not missing, missing
    arm = [f"-DCMAKE_TOOLCHAIN_FILE={ARM_TOOLCHAIN}", "-DIMUFUSE_ARM_CORE=m4f"]
    prefix = _install(cmake, tmp_path, "m4f", arm)
    # the emulator's board: the harness's start-up and linker script (qemu mps2-an386)
    tgt = mcu.TARGETS["m4f"]
    ld = tmp_path / "mps2.ld"
    ld.write_text((mcu.DATA_DIR / "arm.ld.in").read_text().replace("@FLASH_LEN@", str(tgt.flash))
                  .replace("@RAM_LEN@", str(tgt.ram)))
    src = _consumer(tmp_path, "m4f", [EXAMPLE / "main.c", EXAMPLE / "board_semihost.c",
                                      EXAMPLE / "board.h", EXAMPLE / "recorded_samples.h",
                                      mcu.DATA_DIR / "arm_startup.c", mcu.DATA_DIR / "imf_port.h"],
                    f"target_link_options(consumer PRIVATE -nostartfiles -T{ld})\n"
                    "set_target_properties(consumer PROPERTIES SUFFIX .elf)\n")
    build = tmp_path / "cb-m4f"
    _run([cmake, "-S", src, "-B", build, f"-DCMAKE_PREFIX_PATH={prefix}", *arm,
          f"-DCMAKE_FIND_ROOT_PATH={prefix}"])
    _run([cmake, "--build", build])
    elf = build / "consumer.elf"
    # the library's own flags reached the consumer: no fused multiply-add in the image
    dis = _run(["arm-none-eabi-objdump", "-d", elf]).stdout
    assert "vfma" not in dis and "vmul.f32" in dis
    out = _run(["qemu-system-arm", "-M", "mps2-an386", "-nographic", "-monitor", "none",
                "-serial", "null", "-semihosting-config", "enable=on,target=native",
                "-kernel", elf], timeout=120)
    lines = [ln for ln in (out.stdout + out.stderr).splitlines()
             if re.fullmatch(r"[0-9a-f]{8} [0-9a-f]{8}|skipped \w+|end", ln)]
    assert lines == _reference_lines()


def test_pkg_config(host_prefix, tmp_path):
    pkg = shutil.which("pkg-config")
    assert pkg, "pkg-config is installed by tools/install-toolchains.sh"
    prefix = host_prefix
    env = {"PKG_CONFIG_PATH": str(prefix / "lib" / "pkgconfig"), "PATH": "/usr/bin:/bin"}
    ver = subprocess.run([pkg, "--modversion", "imufuse"], capture_output=True, text=True,
                         env=env).stdout.strip()
    assert ver == imufuse.__version__
    cflags = subprocess.run([pkg, "--cflags", "imufuse"], capture_output=True, text=True,
                            env=env).stdout.split()
    libs = subprocess.run([pkg, "--libs", "imufuse"], capture_output=True, text=True,
                          env=env).stdout.split()
    assert "-ffp-contract=off" in cflags
    exe = tmp_path / "pc-consumer"
    _run(["cc", "-std=c99", "-O2", *cflags, f"-I{EXAMPLE}", EXAMPLE / "main.c",
          EXAMPLE / "board_host.c", "-o", exe, *libs])
    assert _run([exe]).stdout.splitlines() == _reference_lines()


def _pkg_config(pkg, pcdir, *args):
    p = subprocess.run([pkg, *args, "imufuse"], capture_output=True, text=True,
                       env={"PKG_CONFIG_PATH": str(pcdir), "PATH": "/usr/bin:/bin"})
    assert p.returncode == 0, p.stderr
    return p.stdout.split()


def test_pkg_config_after_install_with_another_prefix(cmake, tmp_path):
    """Configured for one prefix, installed with `cmake --install build --prefix P` as the README
    and csrc/CMakeLists.txt say: `pkg-config --cflags --libs imufuse` names P's headers and
    library (the prefix comes from the .pc file's own place, ${pcfiledir}), a consumer compiles,
    links and prints the reference's states; the installed tree moved elsewhere still works; a
    deeper library directory (Debian's lib/<multiarch>) climbs back to the prefix as well."""
    pkg = shutil.which("pkg-config")
    assert pkg, "pkg-config is installed by tools/install-toolchains.sh"
    configured = tmp_path / "configured-prefix"      # never installed to
    build = tmp_path / "build-reloc"
    _run([cmake, "-S", CSRC, "-B", build, f"-DCMAKE_INSTALL_PREFIX={configured}"])
    _run([cmake, "--build", build])
    prefix = tmp_path / "P"
    _run([cmake, "--install", build, "--prefix", prefix])
    (pc,) = prefix.rglob("imufuse.pc")
    assert pc.parent == prefix / "lib" / "pkgconfig"
    assert str(configured) not in pc.read_text()
    assert not configured.exists()
    moved = tmp_path / "moved"
    for root in (prefix, moved):
        if root == moved:
            prefix.rename(moved)
        pcdir = root / "lib" / "pkgconfig"
        cflags = _pkg_config(pkg, pcdir, "--cflags")
        libs = _pkg_config(pkg, pcdir, "--libs")
        incs = [Path(f[2:]) for f in cflags if f.startswith("-I")]
        assert [i.resolve() for i in incs] == [(root / "include" / "imufuse").resolve()], cflags
        assert (incs[0] / "imf_config.h").is_file()
        (libdir,) = [Path(f[2:]) for f in libs if f.startswith("-L")]
        assert (libdir / "libimufuse.a").is_file(), libs
        exe = tmp_path / f"pc-consumer-{root.name}"
        _run(["cc", "-std=c99", "-O2", *cflags, f"-I{EXAMPLE}", EXAMPLE / "main.c",
              EXAMPLE / "board_host.c", "-o", exe, *libs])
        assert _run([exe]).stdout.splitlines() == _reference_lines()
    # Debian's multiarch library directory: three levels between the .pc file and the prefix
    _run([cmake, "-S", CSRC, "-B", build, "-DCMAKE_INSTALL_LIBDIR=lib/x86_64-linux-gnu"])
    _run([cmake, "--build", build])
    deep = tmp_path / "deep"
    _run([cmake, "--install", build, "--prefix", deep])
    pcdir = deep / "lib" / "x86_64-linux-gnu" / "pkgconfig"
    assert (pcdir / "imufuse.pc").is_file()
    (inc,) = [Path(f[2:]) for f in _pkg_config(pkg, pcdir, "--cflags") if f.startswith("-I")]
    (libdir,) = [Path(f[2:]) for f in _pkg_config(pkg, pcdir, "--libs") if f.startswith("-L")]
    assert (inc / "imf_config.h").is_file() and (libdir / "libimufuse.a").is_file()
    assert libdir.resolve() == (deep / "lib" / "x86_64-linux-gnu").resolve()
