"""The user's firmware on the host: compiled with cffi beside the generated harness, loaded
and run on a log, the state read back after every sample.

``Firmware`` is a ``Declaration`` that builds (cached under $IMUFUSE_CACHE or
~/.cache/imufuse/firmware, keyed by the generated source, the flags, the compiler's identity
and the contents of every file the compiler reads, from its -M dependency output; bounded
with the programs of validate --target: imufuse.firmware.cache_bound) and runs;
``csrc_firmware`` declares imufuse's own C filter from a csrc directory. ``prepare`` only
compiles; the firmware is loaded (its C constructors run) by ``load`` or ``run``, which
validate_isolated calls in its child process only.
"""
import glob
import hashlib
import importlib.util
import json
import os
import re
import shlex
import shutil
import subprocess
import sysconfig
import tempfile
from pathlib import Path
from typing import Any, List, Optional, Tuple

import numpy as np

from ..shared.checks import KINDS
from ..catalogue import reference_class
from . import cache_bound as _bound
from .csource import host_source, target_source
from .declaration import Declaration, FirmwareError

__all__ = ["Firmware", "csrc_firmware", "compiler_command", "compiler_identity",
           "compiler_missing", "dependency_files"]

_IDENTITY: dict = {}


def _make_deps(text: str) -> List[str]:
    """The prerequisites of a make rule written by the compiler's -M (one target; lines
    continued with a backslash; spaces in names escaped as '\\ ', '$' as '$$')."""
    parts = text.replace("\\\n", " ").split(":", 1)
    if len(parts) < 2:
        return []                     # no rule: the compiler read no source (not C)
    body = parts[1]
    return [t.replace("\\ ", " ").replace("$$", "$")
            for t in re.findall(r"(?:\\ |[^\s])+", body)]


def compiler_command() -> List[str]:
    """The C compiler cffi builds with ($CC, else Python's own CC), as a command list."""
    return shlex.split(os.environ.get("CC") or sysconfig.get_config_var("CC") or "cc")


def _compiler_absent() -> Optional[str]:
    """None when the C compiler of host builds is on PATH, else which one is not and how to
    get one."""
    cc = compiler_command()
    if cc and shutil.which(cc[0]):
        return None
    name = cc[0] if cc else "cc"
    which = "$CC" if os.environ.get("CC") else "the compiler Python was built with"
    where = "" if os.sep in name else " on PATH"
    return (f"{name!r} ({which}) is not found{where}: install one (Debian/Ubuntu: apt install gcc; "
            "Fedora: dnf install gcc; macOS: xcode-select --install) or name yours in CC "
            "(e.g. CC=clang)")


def compiler_missing() -> Optional[str]:
    """None when the C compiler of host builds (compiler_command) is on PATH, else one line
    naming it and how to get one: a wheel of imufuse installs and runs without a compiler,
    validating firmware on the host needs one."""
    absent = _compiler_absent()
    return None if absent is None else ("validating on the host compiles the firmware with a C "
                                        f"compiler, and there is none: {absent}")


def compiler_identity(cc: Optional[List[str]] = None) -> Tuple[str, ...]:
    """The compiler's command, resolved path, size and time stamp, and version text: part of
    the build key, so a different or upgraded compiler never reuses a build. cc: the command
    (default compiler_command(), the host's); looked up once per process."""
    cc = list(cc) if cc is not None else compiler_command()
    key = tuple(cc)
    if key not in _IDENTITY:
        path = shutil.which(cc[0]) or cc[0]
        try:
            proc = subprocess.run([*cc, "--version"], capture_output=True, text=True, timeout=30)
            version = proc.stdout.strip()
        except (OSError, subprocess.SubprocessError):
            version = "unknown"
        try:
            st = os.stat(path)
            stamp = f"{st.st_size}:{st.st_mtime_ns}"
        except OSError:
            stamp = ""
        _IDENTITY[key] = (*cc, os.path.realpath(path), stamp, version)
    return _IDENTITY[key]


def dependency_files(commands: List[List[str]], cwd: Optional[str] = None) -> Optional[List[str]]:
    """Every file the compiler reads for these compilations: each command is a compile
    command without its output (``cc FLAGS... -M -MT x FILE`` is run), side by side; the
    union of their -M outputs as real paths, sorted; None when any of them fails (the
    compilation proper says why)."""
    procs = []
    try:
        for cmd in commands:
            try:
                procs.append(subprocess.Popen([*cmd[:-1], "-M", "-MT", "x", cmd[-1]], cwd=cwd,
                                              stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                                              stdin=subprocess.DEVNULL, text=True))
            except OSError:
                return None
        deps: set = set()
        ok = True
        for proc in procs:
            try:
                out, _ = proc.communicate(timeout=120)
            except subprocess.TimeoutExpired:
                proc.kill()
                out, _ = proc.communicate()
                ok = False
            if proc.returncode != 0:
                ok = False
            elif ok:
                deps.update(os.path.realpath(os.path.join(cwd or "", d))
                            for d in _make_deps(out))
        return sorted(deps) if ok else None
    finally:
        for proc in procs:
            if proc.poll() is None:
                proc.kill()
                proc.wait()


class Firmware(Declaration):
    """User C sources plus a declaration (see imufuse.firmware's doc), built and run on the
    host; ``target_source`` gives the driver of an emulated-MCU build."""

    _lib: Any = None     # ((kind, number of init values), the loaded cffi module)

    def source(self, kind, n_init):
        """The C of the host harness (imufuse.firmware.csource.host_source)."""
        return host_source(self, kind, n_init)

    def target_source(self, kind, init_values, dt, state0=None, c89=False):
        """The driver of an emulated-MCU build (imufuse.firmware.csource.target_source)."""
        return target_source(self, kind, init_values, dt, state0, c89)

    def _harness_extension(self):
        """.cpp when the firmware is C++ (the harness is then C++ too, built and linked by
        the C++ compiler), else .c."""
        return ".cpp" if getattr(self, "language", "c") == "c++" else ".c"

    def _deps(self, src):
        """Every file the compiler reads for this build (its -M dependency output over the
        harness and each source, system headers included), sorted; FirmwareError naming the
        compiler's message when the sources cannot even be preprocessed."""
        cc = compiler_command()
        flags = [f for f in self.cflags if not f.startswith(("-M", "-o"))]
        defs = [f"-D{k}" if v is None else f"-D{k}={v}" for k, v in self.defines.items()]
        incs = [f"-I{d}" for d in self.include_dirs]
        with tempfile.TemporaryDirectory(prefix="imufuse-deps-") as tmp:
            harness = os.path.join(tmp, "harness" + self._harness_extension())
            with open(harness, "w") as fh:
                fh.write(src)
            deps = dependency_files([[*cc, *flags, *defs, *incs, f]
                                     for f in [harness, *self.sources]])
            if deps is None:
                return None             # the compilation proper reports it with its output
            return [p for p in deps if p != os.path.realpath(harness)]

    def _key(self, src):
        """The build's name: a hash of the generated harness, the declaration's build
        settings, the compiler's identity and the contents of every file the compiler reads
        (sources, headers in any directory, included files of any extension)."""
        h = hashlib.sha256()
        h.update(src.encode())
        h.update(json.dumps([self.cflags, sorted(self.defines.items()), self.include_dirs,
                             self.sources, compiler_identity()]).encode())
        deps = self._deps(src)
        files = list(self.sources) if deps is None else deps
        for f in files:
            h.update(f.encode())
            try:
                with open(f, "rb") as fh:
                    h.update(hashlib.sha256(fh.read()).digest())
            except OSError:
                h.update(b"\0missing")
        if deps is None:
            # not preprocessable: never a cached build (the compiler will say why)
            h.update(os.urandom(16))
        return "_imufuse_fw_" + h.hexdigest()[:24]

    def _compiled(self, kind, n_init):
        """The path of the compiled harness and firmware (built now unless a build of the
        same key is cached). No firmware code runs here."""
        # the build key runs the compiler (-M): a missing cffi or compiler is named first, in
        # one line (exit 5 from the command line), never as a failed subprocess
        try:
            from cffi import FFI
        except ImportError:
            absent = _compiler_absent()
            if absent:
                raise FirmwareError("validating on the host compiles the firmware with cffi and "
                                    "a C compiler, and neither is here: pip install "
                                    f"'imufuse[firmware]' for cffi; {absent}") from None
            raise FirmwareError("validating on the host compiles the firmware with cffi, "
                                "which is not installed: pip install 'imufuse[firmware]' "
                                "(or validate on an emulated MCU with --target)") from None
        no_cc = compiler_missing()
        if no_cc:
            raise FirmwareError(no_cc)
        src = self.source(kind, n_init)
        name = self._key(src)
        outdir = os.path.join(self.cache_dir, name)
        built = glob.glob(os.path.join(outdir, name + ".*so")) + \
            glob.glob(os.path.join(outdir, name + ".*pyd"))
        if built:
            _bound.touch(outdir)        # used now: the last to go (cache_bound.prune)
            return name, built[0]
        _bound.cache_limit()            # a bad $IMUFUSE_CACHE_MAX_MB is said before the build
        ffi = FFI()
        ffi.cdef("void imufuse_fw_run(const double *p, const double *s0, int set_state, "
                 "size_t n, const double *in, double dt, double *out, int *isint);\n"
                 "void imufuse_fw_sizes(int *sizes);")
        defs = [(k, None if v is None else str(v)) for k, v in self.defines.items()]
        ffi.set_source(name, src, source_extension=self._harness_extension(),
                       sources=self.sources, include_dirs=self.include_dirs,
                       define_macros=defs, extra_compile_args=self.cflags)
        # built in a directory of its own and renamed into place when complete: a build
        # interrupted half way leaves nothing that looks built, and two processes building
        # the same key at once never load each other's half-written module
        os.makedirs(self.cache_dir, exist_ok=True)
        tmp = tempfile.mkdtemp(prefix=f"{name}.part-", dir=self.cache_dir)
        try:
            try:
                path = ffi.compile(tmpdir=tmp, verbose=False)
            except Exception as e:  # cffi.VerificationError, distutils CompileError
                raise FirmwareError(f"compilation failed (compiler output above): {e}") from None
            for _ in range(2):
                try:
                    os.rename(tmp, outdir)
                    _bound.prune(Path(self.cache_dir), Path(outdir))
                    break
                except OSError:
                    # another process finished the same build first: use the one in place;
                    # a directory without the module (an interrupted build of an earlier
                    # version) is replaced
                    built = glob.glob(os.path.join(outdir, os.path.basename(path)))
                    if built:
                        return name, built[0]
                    shutil.rmtree(outdir, ignore_errors=True)
            else:
                raise FirmwareError(f"cannot store the build in {outdir}")
            return name, os.path.join(outdir, os.path.relpath(path, tmp))
        finally:
            if os.path.isdir(tmp):
                shutil.rmtree(tmp, ignore_errors=True)

    @staticmethod
    def _load(name, path):
        """Load a compiled build into this process: its C constructors run here, so
        validate_isolated loads it only in the child."""
        spec = importlib.util.spec_from_file_location(name, path)
        try:
            mod = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(mod)
        except (ImportError, OSError) as e:
            m = re.search(r"undefined symbol: (\S+)", str(e))
            if m:
                raise FirmwareError(f"symbol not found: {m.group(1)} (declared or called, but "
                                    "defined in none of the sources)") from None
            raise FirmwareError(f"the compiled firmware cannot be loaded: {e}") from None
        return mod

    def _build(self, kind, n_init):
        return self._load(*self._compiled(kind, n_init))

    def prepare(self, kind, c_args=(), params=None):
        """Compile the firmware for a `kind` filter, without loading it: no firmware code
        (not even a C constructor) runs in this process."""
        n_init = len(self._init_values(c_args, params or {})) if self.init else 0
        self._compiled(kind, n_init)

    def load(self, kind, c_args=(), params=None):
        """Compile and load the firmware (its C constructors run in this process)."""
        n_init = len(self._init_values(c_args, params or {})) if self.init else 0
        key = (kind, n_init)
        if self._lib is None or self._lib[0] != key:
            self._lib = (key, self._build(kind, n_init))

    def run(self, kind, inputs, dt, c_args=(), params=None, state0=None):
        """Run the firmware on inputs (the run() arrays of a `kind` filter);
        return the (N, n_state) trajectory in the firmware's precision."""
        n_init = len(self._init_values(c_args, params or {})) if self.init else 0
        key = (kind, n_init)
        if self._lib is None or self._lib[0] != key:
            self._lib = (key, self._build(kind, n_init))
        mod = self._lib[1]
        ffi, lib = mod.ffi, mod.lib
        ns = len(self.state)
        sizes = ffi.new("int[]", max(ns, 1))
        lib.imufuse_fw_sizes(sizes)
        sz = set(sizes[j] for j in range(ns))
        cols = [np.asarray(a, dtype=np.float64) for a in inputs]
        x = np.ascontiguousarray(np.column_stack([c if c.ndim == 2 else c[:, None] for c in cols]))
        n = x.shape[0]
        out = np.empty((n, ns), dtype=np.float64)
        p = np.ascontiguousarray(self._init_values(c_args, params or {}) if self.init else [0.0],
                                 dtype=np.float64)
        s0 = np.zeros(max(ns, 1)) if state0 is None else np.ascontiguousarray(state0, dtype=np.float64)
        isint = ffi.new("int[]", max(ns, 1))
        lib.imufuse_fw_run(ffi.cast("double *", p.ctypes.data), ffi.cast("double *", s0.ctypes.data),
                           int(self.set_state), n, ffi.cast("double *", x.ctypes.data),
                           float(dt), ffi.cast("double *", out.ctypes.data), isint)
        ints = {bool(isint[j]) for j in range(ns)}
        if len(ints) > 1:
            raise FirmwareError("state expressions mix integer and floating-point types: "
                                + ", ".join(f"{nm} {'integer' if isint[j] else 'floating'}"
                                            for j, nm in enumerate(self.state)))
        if ints == {True}:
            if sz - {1, 2, 4, 8} or len(sz) != 1:
                raise FirmwareError(f"integer state expressions of different sizes {sorted(sz)}")
            # integers are stored through double: exact up to 2^53
            return out.astype({1: np.int8, 2: np.int16, 4: np.int32, 8: np.int64}[sz.pop()])
        if sz - {4, 8} or len(sz) != 1:
            raise FirmwareError(f"state expressions must all be float or all double; sizes {sorted(sz)}")
        dtype = np.float32 if sz == {4} else np.float64
        return out.astype(dtype)

    def dtype(self, kind="1d", c_args=(), params=None):
        S = self.run(kind, [np.zeros((0, 1 if kind == "1d" else 3))] * len(KINDS[kind]),
                     1.0, c_args, params)
        return S.dtype.name


def csrc_firmware(name: str, csrc_dir: "str | os.PathLike[str]", dtype: str = "float32",
                  **kwargs: Any) -> "Firmware":
    """A Firmware for imufuse's own filter `name` from a csrc directory
    (e.g. a copy with changes): prototypes from the headers, state x.<name>."""
    ref = reference_class(name)
    c = ref.c_name
    headers = [os.path.basename(h) for h in sorted(glob.glob(os.path.join(csrc_dir, "*.h")))]
    sources = sorted(glob.glob(os.path.join(csrc_dir, "*.c")))
    # only the family that declares the filter (its header and source), when found
    for h in headers:
        stem = os.path.splitext(h)[0]
        src = os.path.join(csrc_dir, stem + ".c")
        if os.path.isfile(src) and re.search(r"\b" + c + r"_init\s*\(",
                                             open(os.path.join(csrc_dir, h)).read()):
            headers, sources = [h], [src]
            break
    defines = {"IMF_DOUBLE": None} if dtype == "float64" else {}
    # each state word's C expression where the twin declares them (arrays: x.q[0] is q0)
    state = {n: "x." + e for n, e in ref.c_state.items()} if hasattr(ref, "c_state") else None
    return Firmware(sources, headers=headers, include_dirs=[csrc_dir], defines=defines,
                    init=f"{c}_init", update=ref.c_update, state=state,
                    state_names=ref.state_names, **kwargs)
