"""Validate firmware filter code against imufuse, bit for bit (`imufuse validate`).

Compile your C sources with cffi, bind the filter through a short
declaration, run it on the same inputs as an imufuse filter and compare every
state variable after every sample.

    from imufuse.firmware import Firmware, validate
    fw = Firmware(sources=["fw/attitude.c"], include_dirs=["fw"], headers=["attitude.h"],
                  init="void att_init(att_t *self, float dt, float k0)",
                  update="void att_update(att_t *self, float rate, float angle)",
                  state={"theta": "x.theta"})
    report = validate(fw, "Kalman1D", dict(dt=0.005, k0=0.01), inputs)
    print(report.text())

The declaration:
  init, update  C prototypes (or only the function names: the prototypes are
                then looked up in `headers`). If the first parameter of init
                (or, without init, of update) is a pointer to a non-float type,
                it is the filter object: the harness allocates one (zeroed) and
                passes its address. Without it, the filter lives in globals.
  init's other parameters receive the imufuse filter's C init arguments
                (imufuse.reference.X._params(...), the order of csrc's
                <c_name>_init) when the counts match; otherwise they are matched
                by name to the filter's parameters (dt included) or to
                `init_args` {name: value}.
  update's other parameters receive the inputs in the imufuse order: 1d: rate,
                angle; imu: gyr x, y, z, acc x, y, z; ahrs: + mag x, y, z.
                A scalar parameter takes one value, an array or pointer
                parameter (`const float g[3]`, `float *g`) one 3-vector; a
                scalar parameter named dt / deltat / delta_t gets the sample
                period.
  state         {imufuse state name: C expression}: a member path relative to
                the filter object (`x.theta`, `q[0]`) or any C expression
                using `self` or globals, marked by a leading `=`
                (`=self->x.theta`, `=q0`). Default: `x.<name>` for every
                state name (csrc's convention).
  set_state     True: after init, write the imufuse filter's initial state into
                the state expressions (they must then be lvalues); default:
                only when there is no init function.
The precision of the firmware is read from sizeof of the state expressions.

Compilation: `cflags` default DEFAULT_CFLAGS (the numerical contract of
docs/internals.md); give a list to replace them. `defines` {NAME: value or None}.
Builds are cached under $IMUFUSE_CACHE or ~/.cache/imufuse/firmware, keyed by
the generated source, the flags, the compiler's identity and the contents of
every file the compiler reads (its -M dependency output: headers in any
directory, included files of any extension). The programs built for an emulated
MCU (--target) are cached in targets/ there, keyed the same way with the cross
compiler (imufuse.firmware.target_build).

The modules, by subject:
  declaration   the user's declaration: prototypes (imufuse.shared.cproto), the filter object,
                settings structs, state expressions, which value goes where
  csource       the C generated around the firmware (host harness, MCU driver)
  host          Firmware: built with cffi and run in this process; csrc_firmware
  targets       the emulated MCUs: names, descriptions, default flags
  elf           reading ELF images and linker maps
  target_build  the firmware cross-built and linked with the harness (Program)
  target_cache  the built programs kept, keyed by everything that can change them
  target_run    the program run on the emulator chunk by chunk (TargetRun)
  causes        why a run differs (fused multiply-add, double, fast-math) and by how much
  results       Validation and Cost
  validate      validate(): the firmware and imufuse on the same inputs, compared
  isolate       validate_isolated(): the same in a child process with a timeout
  declared      DeclaredFirmware: any API (a C++ class, structs by value, settings, units)
                declared in a file instead of prototypes; the harness generated around it
  declfile      load_declaration(): that file (TOML) read and checked
  ctemplate     a declaration's templates checked as C; the heap and system calls a
                declared firmware gets on bare metal
  diagnostics   the source's causes: compiler warnings on the code run up to the divergence
                (gcov), the data model (long, int, double widths), a changed constant
  sanitize      the firmware built for the host under UBSan and ASan: the first report
  report        rounding or formula, the --within verdict, the JSON and JUnit reports
  versus        compare_firmware(): firmware against firmware, no imufuse reference
"""
from ..shared.bits import Comparison, c_double_literal as hexfloat, compare_states, ulps
from .causes import Cause, angle_divergence_deg, double_promotions, find_causes
from .declaration import DEFAULT_CFLAGS, Declaration, FirmwareError, parse_prototype
from .host import Firmware, csrc_firmware
from .isolate import DEFAULT_TIMEOUT, validate_isolated
from .declared import DeclaredFirmware
from .declfile import Declared, load_declaration
from .versus import compare_firmware
from .results import Cost, Validation
from .target_build import MAX_CHUNK, Program, StateType, build_program
from .target_run import TargetRun, run_program
from .targets import (DEFAULT_TARGET_CFLAGS, DESCRIPTION, TARGETS, TargetError, harness_target,
                      speed_note, target_names)
from .validate import counts_for, mag_counts_scale, validate
from .hil import DEFAULT_BAUD, BoardCost, BoardRun, Link
from .hil_board import Board, build_board

__all__ = ["Firmware", "FirmwareError", "Validation", "validate", "csrc_firmware",
           "parse_prototype", "Comparison", "compare_states", "ulps", "DEFAULT_CFLAGS",
           "DEFAULT_TIMEOUT", "validate_isolated", "DeclaredFirmware", "Declared",
           "load_declaration", "compare_firmware", "counts_for", "mag_counts_scale", "Cost", "Declaration",
           # the emulated-MCU targets
           "TARGETS", "DESCRIPTION", "DEFAULT_TARGET_CFLAGS", "TargetError", "target_names",
           "harness_target", "speed_note", "MAX_CHUNK", "StateType", "Program", "build_program",
           "TargetRun", "run_program", "Cause", "find_causes", "double_promotions",
           "angle_divergence_deg", "hexfloat",
           # hardware in the loop (validate(..., port=...)) and its emulated boards
           "Link", "BoardRun", "BoardCost", "DEFAULT_BAUD", "Board", "build_board"]
