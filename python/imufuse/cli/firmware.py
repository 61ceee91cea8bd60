"""`imufuse validate` (firmware against imufuse, bit for bit) and `imufuse export`."""
import argparse
import copy
import os

import numpy as np
import time

from .. import __version__, plots, sim
from ..tools.arduino import export_arduino
from ..shared.atomic import check_outputs
from ..shared.resources import csrc_dir
from ..catalogue import canonical_name, inputs_for, reference_class, resolve_params
from ..catalogue import entry as _entry
from ..firmware import (DEFAULT_TIMEOUT, Firmware, FirmwareError, counts_for, csrc_firmware,
                        mag_counts_scale, target_names, validate, validate_isolated)
from ..firmware.report import build_info, error_dict, report_dict, tolerance, write_reports
from ..firmware.declfile import load_declaration
from ..firmware.versus import compare_firmware
from ..firmware.validate import _filter_entry
from ..session import FUSION, FUSIONS
from ..io import LogError
from .common import (EXIT_FAIL, EXIT_OK, OutputError, UsageError, err, once, open_session,
                     pairs, plot_available, positive, strict_option, unit_options)

#: imufuse validate --within: not bit-exact, within the tolerance (imufuse.cli's exit codes)
EXIT_WITHIN = 7


def _headers(args):
    out = []
    for h in args.header or ():
        for d in ["", *(args.include or ())]:
            p = os.path.join(d, h) if d else h
            if os.path.isfile(p):
                out.append(p)
    return out


def _side_inputs(name, kind, overrides, dt, raw, src):
    """(params, inputs, description) of the imufuse filter `name` on the raw inputs (rad/s,
    g): FusionAHRS in its units (the gyroscope in deg/s, dt with every update), a
    fixed-point filter on int16 counts."""
    if name in FUSIONS:
        return ({**overrides, "dt": dt},
                [np.degrees(np.asarray(raw[0], dtype=np.float64)), *raw[1:]],
                src + "; gyroscope in deg/s (Fusion's unit)")
    params = resolve_params(name, dt, overrides)
    if _entry(name).fixed:
        mag = f", mag {mag_counts_scale(raw[2]):g} per unit" if kind == "ahrs" else ""
        return (params, counts_for(kind, params, raw),
                src + f"; int16 counts (gyr_scale {params['gyr_scale']:g} rad/s, acc 4096 per "
                      f"g{mag})")
    return params, raw, src


def _against(args, b, fw_b, kind, dt, raw, src):
    """--against / --against-target / --against-cflags: firmware B (the one given) against
    firmware A (--against FILE, else the same firmware) on the same samples, A built for
    --against-target (default: B's target) with --against-cflags (default: A's flags)."""
    if args.against:
        d = load_declaration(args.against)      # its paths: relative to its own file
        fw_a, name_a, over_a = d.firmware, d.filter, dict(d.params)
    else:
        fw_a, name_a = copy.copy(fw_b), args.filter
        over_a = {**(fw_b_declared_params(args)), **pairs(args.param)}
    kind_a = _filter_entry(name_a).kind if name_a in FUSIONS else _entry(name_a).kind
    if kind_a != kind:
        raise UsageError(f"--against: firmware A compares with {name_a} ({kind_a}), firmware B "
                         f"with {args.filter} ({kind}): give two filters of one kind")
    if args.against_cflags is not None:
        fw_a.cflags = args.against_cflags.split()
        fw_a.cflags_given = list(fw_a.cflags)
        fw_a._lib = None
    params_a, inputs_a, _ = _side_inputs(name_a, kind, over_a, dt, raw, src)
    a = validate_isolated(fw_a, name_a, params_a, inputs_a, backend=args.backend,
                          dtype=args.dtype if name_a == args.filter else None,
                          timeout=args.timeout, target=args.against_target or args.target,
                          explain=False)
    a.params = dict(params_a)
    return compare_firmware(a, b, "A", "B")


def fw_b_declared_params(args):
    """The declaration's parameters of the firmware given (none without --declaration)."""
    return load_declaration(args.declaration, source_dir=args.source_dir).params \
        if args.declaration else {}


def _fusion_kind(name=FUSION):
    """What validate needs of a Fusion AHRS class: its kind (AHRS) and state."""
    return _filter_entry(name)


def _declared(args):
    """--declaration FILE: the firmware, its imufuse filter and parameters from the file;
    the command line's --param and --cflags apply on top."""
    if args.sources or args.csrc or args.init or args.update or args.state or args.header:
        raise UsageError("--declaration: the firmware's sources, init, update, state and "
                         "headers come from the file; give no SOURCE, --csrc, --init, "
                         "--update, --state or --header with it")
    d = load_declaration(args.declaration, source_dir=args.source_dir)
    if args.filter and args.filter != d.filter:
        raise UsageError(f"--filter {args.filter}: the declaration compares with {d.filter}")
    args.filter = d.filter
    if args.cflags is not None:
        d.firmware.cflags = args.cflags.split()
        d.firmware.cflags_given = list(d.firmware.cflags)
    return d


def _validate(args):
    declared = None
    if args.declaration:
        declared = _declared(args)
    elif args.source_dir:
        raise UsageError("--source-dir: with --declaration only")
    elif not args.filter:
        raise UsageError("validate: give --filter (the imufuse filter to compare with), or "
                         "--declaration FILE")
    fusion = args.filter in FUSIONS
    if fusion and declared is None:
        raise UsageError(f"validate: {args.filter} has an API of its own: declare it in a file "
                         "(--declaration; examples/declarations/fusion-1.3.3.toml, "
                         "fusion-1.2.3.toml)")
    cls = _fusion_kind(args.filter) if fusion else reference_class(args.filter) \
        if not _entry(args.filter).fixed else _entry(args.filter).reference
    overrides = {**(declared.params if declared else {}), **pairs(args.param)}
    once(args.header, "--header")
    once(args.include, "-I")
    check_outputs([args.log, *(args.sources or ()), *_headers(args),
                   *(declared.firmware.sources if declared else ()), args.declaration],
                  [("--plot", args.plot), ("--json", args.json), ("--junit", args.junit)])
    plot_available(args.plot)           # exit 3 before any work, not a run without its plot
    if args.within is not None and not fusion and _entry(args.filter).estimate is None:
        raise UsageError(f"--within: {args.filter} has no orientation estimate to compare in "
                         "degrees")
    defines = {}
    for d in args.define or ():
        k, _, v = d.partition("=")
        if k in defines:
            raise UsageError(f"-D {k}: given twice; define it once")
        defines[k] = v if v else None
    cflags = args.cflags.split() if args.cflags is not None else None
    if declared is not None:
        fw = declared.firmware
    elif args.csrc:
        if not os.path.isdir(args.csrc):
            raise LogError(f"--csrc {args.csrc}: no such directory", "file")
        dtype = args.dtype or "float32"
        fw = csrc_firmware(args.filter, args.csrc, dtype, cflags=cflags)
    else:
        if not args.sources:
            raise UsageError("validate: give the firmware's C sources (or --csrc DIR)")
        for s in args.sources:
            if not os.path.isfile(s):
                raise LogError(f"{s}: no such file", "file")
        if not args.update:
            raise UsageError("validate: give --update (the update function's prototype or name)")
        state = pairs(args.state, "--state") or None
        fw = Firmware(args.sources, init=args.init, update=args.update, state=state,
                      state_names=cls.state_names, headers=args.header or (),
                      include_dirs=args.include or (), defines=defines, cflags=cflags,
                      init_args=pairs(args.init_arg, "--init-arg"))
    if args.log:
        s = open_session(args)
        dt = s.log.dt
        inputs, src = s.inputs(args.filter, args.axis)
        t = s.log.t
    else:
        rate = args.rate or 200.0
        data = (sim.axis1d("slow", rate=rate, duration=args.duration, seed=args.seed)
                if cls.kind == "1d" else
                sim.imu("slow", rate=rate, duration=args.duration, seed=args.seed))
        dt, inputs, t = data.dt, inputs_for(cls.kind, data), data.t
        src = f"simulated 'slow' motion, {rate:g} Hz, {args.duration:g} s, seed {args.seed}"
    raw = inputs
    params, inputs, src = _side_inputs(args.filter, cls.kind, overrides, dt, raw, src)
    args.report_context = (fw, params, src)      # for the reports of an error (_reported)
    pair = args.against or args.against_target or args.against_cflags is not None
    if args.port:
        # the board runs the firmware the user built: nothing of it runs in this process
        v = validate(fw, args.filter, params, inputs, backend=args.backend, dtype=args.dtype,
                     timeout=args.timeout, target=args.target, explain=not pair,
                     port=args.port, baud=args.baud)
    else:
        v = validate_isolated(fw, args.filter, params, inputs, backend=args.backend,
                              dtype=args.dtype, timeout=args.timeout, target=args.target,
                              explain=not pair)
    v.params = dict(params)
    if pair:
        v = _against(args, v, fw, cls.kind, dt, raw, src)
    print(f"inputs: {src}; {args.filter} "
          f"{', '.join(f'{k}={val}' for k, val in params.items())}")
    print(v.text())
    tol = tolerance(v, args.within) if args.within is not None else None
    if tol is not None and not v.bit_exact:
        print(tol.text())
    if args.json or args.junit:
        write_reports(report_dict(v, tol, build_info(fw, args.filter, params, args.target, v.cflags),
                                  src, {"total": time.perf_counter() - args.started}, args.within),
                      args.json, args.junit)
    if args.plot:
        try:
            plots.plot_divergence(args.plot, t, v.got, v.want, v.comparison.names,
                                  v.comparison.first_sample,
                                  f"firmware vs imufuse {args.filter} ({v.comparison.dtype})")
        except OSError as e:
            raise OutputError(f"--plot {args.plot}: cannot write: {e.strerror or e}") from None
        err(f"plot: {args.plot}")
    return EXIT_OK if v.bit_exact else (EXIT_WITHIN if tol is not None and tol.passed else
                                        EXIT_FAIL)


def _reported(args):
    """_validate; with --json/--junit, a firmware that cannot be built, bound or run (exit 5)
    still writes both reports, verdict "error" with the message."""
    args.started = time.perf_counter()
    try:
        return _validate(args)
    except FirmwareError as e:
        if args.json or args.junit:
            fw, params, src = getattr(args, "report_context", (None, None, None))
            build = build_info(fw, args.filter, params, args.target) if fw else None
            write_reports(error_dict(str(e), args.filter, args.target, build, src, params,
                                     args.within, {"total": time.perf_counter() - args.started}),
                          args.json, args.junit)
        raise


def _export(args):
    if os.path.exists(args.dir) and not os.path.isdir(args.dir):
        # it read "DIR/imufuse/src/fixed: Not a directory"
        raise OutputError(f"{args.dir}: is a file, not a directory; give a directory "
                          "for the library")
    lib = export_arduino(args.dir, make_zip=args.zip)
    print(f"Arduino library: {lib}")
    if args.zip:
        print(f"zip for the IDE (Sketch > Include Library > Add .ZIP Library): "
              f"{lib.parent / f'imufuse-{__version__}.zip'}")
    return EXIT_OK


def add_parsers(sub):
    v = sub.add_parser("validate", help="compile firmware C (for the host, or for an emulated "
                       "MCU with your flags) and compare it with an imufuse filter bit for "
                       "bit", formatter_class=argparse.RawDescriptionHelpFormatter,
                       description="Validate firmware filter code against imufuse (see "
                       "imufuse.firmware).\nThe firmware runs in a child process: a crash, exit() "
                       "or hang is reported (exit 5).\nWith --within DEG: exit 7 when not bit-exact "
                       "but within the tolerance.\n\nexample:\n  imufuse validate fw/att.c -I fw "
                       "--header att.h --filter Kalman1D \\\n     --init 'void att_init(att_t *s, "
                       "float dt, float k0)' \\\n     --update 'void att_update(att_t *s, float rate, "
                       "float angle)' \\\n     --state theta=x.theta --param k0=0.01\n"
                       "  imufuse validate --csrc --filter Kalman1D --dtype float32\n"
                       "  imufuse validate fw/cf.c --header cf.h --filter Complementary1D "
                       "--init cf_init \\\n     --update cf_update --state theta=theta "
                       "--target cortex-m4f --cflags '-O2 -ffp-contract=off'\n"
                       "  imufuse validate --declaration madgwick_arduino.toml   # any API, C++")
    v.add_argument("sources", nargs="*", metavar="SOURCE.c")
    v.add_argument("--filter", "-f", help="the imufuse filter to compare with (with "
                   "--declaration: from the file)", type=canonical_name)
    v.add_argument("--declaration", metavar="FILE.toml",
                   help="the firmware's API declared in a file: sources, how to create, "
                        "initialise and update the filter (a C++ class, a C struct, any "
                        "signature and units), how to read its state, which imufuse filter "
                        "to compare with (imufuse.firmware.declared; docs/firmware.md)")
    v.add_argument("--against", metavar="FILE.toml",
                   help="firmware against firmware, no imufuse reference: the firmware given "
                        "(B) against the one declared in FILE (A): old and new versions, a "
                        "float filter and its fixed-point port (compared as orientations)")
    v.add_argument("--against-target", choices=target_names(), metavar="TARGET",
                   help="firmware against firmware: A (--against, else the same firmware) "
                        "built for TARGET (host against target)")
    v.add_argument("--against-cflags", metavar="FLAGS",
                   help="firmware against firmware: A built with FLAGS (-O0 against -O2)")
    v.add_argument("--source-dir", metavar="DIR",
                   help="with --declaration: the directory its relative paths start from "
                        "(default: the file's)")
    v.add_argument("--csrc", metavar="DIR", nargs="?", const=str(csrc_dir()),
                   help="validate imufuse's own sources in DIR (default: the C library "
                        "installed with imufuse)")
    v.add_argument("-I", "--include", action="append", metavar="DIR")
    v.add_argument("-D", "--define", action="append", metavar="NAME[=VALUE]")
    v.add_argument("--header", action="append", metavar="FILE.h", help="header(s) to include")
    v.add_argument("--init", metavar="PROTOTYPE|NAME")
    v.add_argument("--update", metavar="PROTOTYPE|NAME")
    v.add_argument("--state", action="append", metavar="NAME=EXPR",
                   help="imufuse state variable = member path or '=C expression' "
                        "(default x.NAME for every state variable)")
    v.add_argument("--init-arg", action="append", metavar="NAME=VALUE")
    v.add_argument("--target", choices=target_names(), default="host",
                   help="where the firmware runs: host (cffi, this machine) or an emulated MCU "
                        "built with its cross compiler and your --cflags: cortex-m0/m3/m4f/m7/"
                        "m33/m55 (QEMU mps2/mps3 machines, microbit), rv32imac/rv32imafc (QEMU "
                        "riscv32 virt), atmega328p (simavr). The report adds the cause of a "
                        "divergence and the cost per update")
    v.add_argument("--port", metavar="PORT",
                   help="validate on a board: the serial port of a board whose firmware runs "
                        "the HIL runner (csrc/hil/imf_hil.h), e.g. /dev/ttyACM0; the states and "
                        "counts come from the board; with --target CORE the causes of a "
                        "divergence come from your sources built for that emulated core")
    v.add_argument("--baud", type=positive(int, 100_000_000), default=1_000_000, metavar="N",
                   help="with --port: the baud rate (default 1000000)")
    v.add_argument("--cflags", metavar="FLAGS",
                   help="your compiler flags (the target adds only -mcpu/-mfpu/-mfloat-abi or "
                        "-mmcu); default '-std=c99 -O2 -ffp-contract=off' on the host, '-O2' on "
                        "an MCU target (the compiler's default standard, as a firmware build)")
    v.add_argument("--param", "-p", action="append", metavar="NAME=VALUE")
    v.add_argument("--dtype", choices=("float32", "float64"),
                   help="precision (default: the firmware's, from sizeof of its state)")
    v.add_argument("--backend", choices=("c", "ref"), default="c")
    v.add_argument("--timeout", type=positive(float, 1e6), default=DEFAULT_TIMEOUT, metavar="S",
                   help=f"seconds the firmware may run (default {DEFAULT_TIMEOUT:g})")
    v.add_argument("--log", metavar="LOG", help="inputs from a log (default: simulated)")
    unit_options(v, "with --log: ")
    strict_option(v)
    v.add_argument("--axis", choices=("x", "y"), default="x")
    v.add_argument("--rate", type=positive(float, 1e9, 1e-3), metavar="HZ")
    v.add_argument("--duration", type=positive(float, 1e5), default=10.0)
    v.add_argument("--seed", type=int, default=1)
    v.add_argument("--plot", metavar="PNG", help="divergence plot")
    v.add_argument("--within", type=positive(float, 180.0), metavar="DEG",
                   help="a variant not meant to be bit-exact: pass (exit 7) when the orientation "
                        "differs by at most DEG degrees over the run (max and RMS printed)")
    v.add_argument("--json", metavar="FILE", help="write the report as JSON: verdict, first "
                   "divergence (bit patterns), rounding or formula, causes, cost, timing, the "
                   "build (compiler version, flags, sha256 of every file read)")
    v.add_argument("--junit", metavar="FILE", help="write the checks (build, bit-exact or "
                   "within, causes) as JUnit XML for CI")
    v.set_defaults(func=_reported, fixed_rate=True)

    e = sub.add_parser("export", help="write the C library in a form firmware projects take",
                       description="imufuse export arduino DIR: an Arduino library in DIR/imufuse "
                       "(library.properties, src/, keywords.txt, example sketches for an Uno and "
                       "ARM boards); --zip also writes DIR/imufuse-VERSION.zip for the Arduino "
                       "IDE's 'Add .ZIP Library'. See docs/firmware.md.")
    e.add_argument("what", choices=("arduino",))
    e.add_argument("dir", metavar="DIR")
    e.add_argument("--zip", action="store_true", help="also write the .zip the IDE installs")
    e.set_defaults(func=_export)
