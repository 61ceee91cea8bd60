"""The imufuse command line: demo, run, compare, tune, latency, bench, validate, export,
vario, calibrate.

Exit codes (every failure is one line on stderr, "imufuse: error: ..."):
  0  success
  1  a bit-exact check or a validation failed (the firmware differs)
  2  bad command line (unknown filter or parameter, bad option value, an
     option's name or value given twice, an output that would overwrite the
     input)
  3  a file not found, unreadable, or an output that cannot be written
  4  bad file contents: a log's (columns, values, time), a calibration file's or
     a column map's (not UTF-8, over 1 MiB, not JSON, nested too deep, not the
     format); a plausibility warning under --strict, or nothing could be
     computed or evaluated
  5  firmware that cannot be compiled, bound or run (a crash, exit(), a
     hang past --timeout, a missing symbol)
  6  an unexpected internal error (a bug; IMUFUSE_DEBUG=1 shows the traceback)
  7  validate --within: the firmware is not bit-exact, and its orientation is
     within the --within tolerance (bit-exact is 0, beyond the tolerance 1)
130  interrupted (Ctrl-C)
"""
import argparse
import os
import sys

from .. import __version__
from ..calibration import CalibrationError
from ..catalogue import FilterError
from ..firmware import FirmwareError
from ..io import LogError
from ..session import NothingComputed
from . import firmware, logs, tools, tune, vario
from .common import (EXIT_DATA, EXIT_FILE, EXIT_FIRMWARE, EXIT_INTERNAL, EXIT_INTERRUPT,
                     EXIT_OK, EXIT_USAGE, OutputError, UsageError, err)

__all__ = ["main", "build_parser", "EXIT_OK", "EXIT_DATA", "EXIT_USAGE"]

#: each module's add_parsers(sub), in the order of `imufuse --help`
SUBCOMMANDS = [tools.add_demo, logs.add_parsers, tune.add_parsers, tools.add_latency,
               tools.add_bench, firmware.add_parsers, vario.add_parsers]


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        self.print_usage(sys.stderr)
        self.exit(EXIT_USAGE, f"imufuse: error: {message}\n")


def build_parser():
    p = _Parser(prog="imufuse", description=__doc__,
                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--version", action="version", version=f"imufuse {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for add in SUBCOMMANDS:
        add(sub)
    return p


def _join_flag_values(argv):
    """`--cflags -O2` as `--cflags=-O2`, `--align -Y+X+Z` as `--align=-Y+X+Z`: argparse would
    take a value starting with '-' for an option; compiler flags always start with one, and
    half of the alignments (a minus before an axis: no option of imufuse is -x, -y or -z)."""
    out, i = [], 0
    while i < len(argv):
        a, nxt = argv[i], argv[i + 1] if i + 1 < len(argv) else None
        if nxt is not None and (a in ("--cflags", "--against-cflags") or (
                a == "--align" and nxt[:2].upper() in ("-X", "-Y", "-Z"))):
            out.append(f"{a}={nxt}")
            i += 2
        else:
            out.append(a)
            i += 1
    return out


def main(argv=None):
    p = build_parser()
    try:
        args = p.parse_args(_join_flag_values(sys.argv[1:] if argv is None else list(argv)))
    except SystemExit as e:
        return e.code if isinstance(e.code, int) else EXIT_USAGE
    if not getattr(args, "func", None):
        p.print_help()
        return EXIT_USAGE
    try:
        return args.func(args)
    except LogError as e:
        err(f"error: {e}")
        return {"file": EXIT_FILE, "usage": EXIT_USAGE}.get(e.kind, EXIT_DATA)
    except CalibrationError as e:
        err(f"error: {e}")
        return EXIT_FILE if e.kind == "file" else EXIT_DATA
    except NothingComputed as e:
        err(f"error: {e}")
        return EXIT_DATA
    except FirmwareError as e:
        err(f"error: {e}")
        return EXIT_FIRMWARE
    except (UsageError, FilterError) as e:
        err(f"error: {e}")
        return EXIT_USAGE
    except BrokenPipeError:
        # the reader went away (| head): not an error; silence the final flush
        try:
            fd = os.open(os.devnull, os.O_WRONLY)
            os.dup2(fd, sys.stdout.fileno())
        except (OSError, ValueError):
            pass
        return EXIT_OK
    except OutputError as e:
        err(f"error: {e}")
        return EXIT_FILE
    except OSError as e:
        err(f"error: {e.filename + ': ' if e.filename else ''}{e.strerror or e}")
        return EXIT_FILE
    except KeyboardInterrupt:
        err("interrupted")
        return EXIT_INTERRUPT
    except MemoryError:
        err("error: out of memory")
        return EXIT_DATA
    except ValueError as e:
        err(f"error: {e}")
        return EXIT_USAGE
    except Exception as e:  # noqa: BLE001 - the documented last resort, exit 6
        if os.environ.get("IMUFUSE_DEBUG"):
            raise
        msg = " ".join(str(e).split())
        err(f"internal error: {type(e).__name__}: {msg[:300]} (IMUFUSE_DEBUG=1 shows the "
            "traceback; please report it)")
        return EXIT_INTERNAL
