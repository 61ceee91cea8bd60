"""What the subcommands share: exit codes, errors, option groups, and the border where the
argparse Namespace becomes typed settings (imufuse.session's options)."""
import argparse
import ast
import concurrent.futures as cf
import contextlib
import math
import sys

from .. import io, plots
from ..reference._fusion import SETTINGS as FUSION_SETTINGS
from ..reference._fusion13 import SETTINGS as FUSION13_SETTINGS
from ..catalogue import canonical_name, param_names
from ..io import LogError, parse_column_map, read_column_map
from ..session import ReadOptions, RunOptions, ScoreOptions, Session, init_value

EXIT_OK, EXIT_FAIL, EXIT_USAGE, EXIT_FILE, EXIT_DATA, EXIT_FIRMWARE, EXIT_INTERNAL = range(7)
EXIT_INTERRUPT = 130


class UsageError(ValueError):
    """A bad command line (exit 2)."""


class OutputError(OSError):
    """An output file that cannot be written (exit 3)."""


def err(msg):
    print(f"imufuse: {msg}", file=sys.stderr)


def value(text):
    """A --param value: a Python literal, true/false/none, else the text."""
    low = text.strip().lower()
    if low in ("true", "false"):
        return low == "true"
    if low in ("none", "null"):
        return None
    try:
        return ast.literal_eval(text.strip())
    except (ValueError, SyntaxError, MemoryError, RecursionError):
        return text.strip()


def pairs(items, what="--param"):
    """NAME=VALUE items of a repeatable option -> {name: value}; a name given twice is a
    UsageError naming the option and the name."""
    out, given = {}, {}
    for it in items or ():
        if "=" not in it:
            raise UsageError(f"{what} {it!r}: expected NAME=VALUE")
        k, v = it.split("=", 1)
        k = k.strip()
        if k in out:
            raise UsageError(f"{what} {k}: given twice ({what} {given[k]}, {what} {it.strip()}); "
                             "give it once")
        out[k], given[k] = value(v), it.strip()
    return out


def once(items, what):
    """The values of a repeatable option, in order; a value given twice is a UsageError naming
    the option and the value."""
    out = []
    for it in items or ():
        if it in out:
            raise UsageError(f"{what} {it}: given twice; give it once")
        out.append(it)
    return out


def names(items, what="--filter"):
    """Filter names of a repeatable option (each NAME[,NAME]) in the catalogue's spelling; a
    filter named twice is a UsageError naming it."""
    return once([canonical_name(n.strip()) for f in items or () for n in f.split(",")
                 if n.strip()], what)


def scoped_params(items, filters):
    """--param NAME=V (every filter that has NAME) or FILTER.NAME=V -> {filter: {name: v}};
    one filter's parameter given twice (also as NAME and FILTER.NAME) is a UsageError."""
    out = {n: {} for n in filters}
    src = {n: {} for n in filters}

    def put(f, p, v, k):
        if p in out[f]:
            raise UsageError(f"--param {k}: {p} of {f} is also given by --param {src[f][p]}; "
                             "give it once")
        out[f][p], src[f][p] = v, k
    for k, v in pairs(items).items():
        if "." in k:
            f, p = k.split(".", 1)
            f = canonical_name(f)
            if f not in out:
                raise UsageError(f"--param {k}: filter {f!r} is not among {', '.join(filters)}")
            put(f, p, v, k)
        else:
            hit = [n for n in filters if k in _param_names(n)]
            if not hit:
                raise UsageError(f"--param {k}: no selected filter has a parameter {k!r}; "
                                 + "; ".join(f"{n}: {', '.join(p for p in _param_names(n) if p != 'dt')}"
                                             for n in filters))
            for n in hit:
                put(n, k, v, k)
    return out


def _param_names(name):
    if name == "FusionAHRS":
        return [*FUSION_SETTINGS, "invsqrt"]
    if name == "FusionAHRS13":
        return [*FUSION13_SETTINGS, "invsqrt"]
    return param_names(name)


# ---------------------------------------------------------------------------
# the border: arguments -> typed settings

def column_map(args):
    """{name: header} from --column-map and --columns; a column named twice (in one of them
    or in both) is a UsageError naming the option and the column."""
    cmap, where = {}, {}
    if getattr(args, "column_map", None):
        try:
            cmap = read_column_map(args.column_map)
        except LogError as e:
            if e.kind == "usage":
                raise UsageError(f"--column-map {e}") from None
            raise
        where = dict.fromkeys(cmap, f"--column-map {args.column_map}")
    for item in getattr(args, "columns", None) or ():
        try:
            m = parse_column_map(item, "--columns")
        except LogError as e:
            raise UsageError(str(e)) from None
        for k, h in m.items():
            if k in cmap:
                raise UsageError(f"--columns {k}={h!r}: {k!r} is also named by {where[k]}; "
                                 "name each column once")
            cmap[k], where[k] = h, f"--columns {k}={h!r}"
    return cmap


def read_options(args, **over):
    return ReadOptions(
        gyr_unit=getattr(args, "gyr_unit", None), acc_unit=getattr(args, "acc_unit", None),
        time_unit=getattr(args, "time_unit", None), columns=column_map(args),
        rate=getattr(args, "rate", None), fixed_rate=getattr(args, "fixed_rate", False),
        calibration=getattr(args, "calibration", None), align=getattr(args, "align", None),
        offset=getattr(args, "offset", False), strict=getattr(args, "strict", False),
        backend=getattr(args, "backend", "c"), command_line=True, **over)


def run_options(args):
    try:
        init = init_value(getattr(args, "init", None))
    except ValueError:
        raise UsageError(f"--init {args.init!r}: expected first, identity or a quaternion "
                         "w,x,y,z") from None
    return RunOptions(backend=getattr(args, "backend", "c"),
                      dtype=getattr(args, "dtype", "float64"), init=init,
                      init_window=getattr(args, "init_window", None),
                      axis=getattr(args, "axis", "x"), preset=getattr(args, "preset", None))


def score_options(args):
    return ScoreOptions(ref_frame=getattr(args, "ref_frame", None),
                        ref_direction=getattr(args, "ref_direction", "sensor-to-earth"),
                        skip=getattr(args, "skip", None),
                        heading_offset=getattr(args, "heading_offset", False),
                        frame=getattr(args, "frame", "NWU"))


def open_session(args, path=None, **over):
    """The session of a log command, its notes printed."""
    s = Session(path or args.log, read_options(args, **over))
    for note in s.notes:
        err(f"note: {note}")
    return s


#: the last tenth of each run's progress printed (plain lines, stderr not a terminal)
_PROGRESS: dict = {}


def progress(label, done, n):
    """A long run's progress on stderr: on a terminal one line rewritten in place; else (a
    file, a pipe) a plain line at each tenth of the run, never a carriage return."""
    pct = f"imufuse: {label}: {100 * done // n}% ({done}/{n} samples)"
    if sys.stderr.isatty():
        print(f"\r{pct}", end="\n" if done >= n else "", file=sys.stderr, flush=True)
        return
    last_done, last_tenth = _PROGRESS.get(label, (0, 0))
    if done <= last_done:                        # a new run of the same filter
        last_tenth = 0
    tenth = 10 * done // n
    _PROGRESS[label] = (done, max(tenth, last_tenth))
    if tenth > last_tenth:
        print(pct, file=sys.stderr, flush=True)


def plot_available(path):
    """OutputError (exit 3) for a --plot that cannot be written: matplotlib is missing."""
    if path and not plots.available():
        raise OutputError(f"--plot {path}: cannot write: matplotlib is not installed (pip "
                          "install 'imufuse[plot]')")


def input_files(args):
    """Every file a log command reads: the log, a column map, a calibration."""
    return [getattr(args, "log", None), getattr(args, "column_map", None),
            getattr(args, "calibration", None)]


def write_output(path, cols, f32=()):
    """CSV to stdout ("-") or a file, or NPZ for OUT.npz; OutputError when it cannot be
    written."""
    try:
        if path == "-":
            io.write_csv(sys.stdout, cols, float32=f32)
        elif path.lower().endswith(".npz"):
            io.write_npz(path, cols)
        else:
            io.write_csv(path, cols, float32=f32)
    except OSError as e:
        if isinstance(e, BrokenPipeError):
            raise
        raise OutputError(f"-o {path}: cannot write: {e.strerror or e}") from None


# ---------------------------------------------------------------------------
# option types and groups

def positive(typ, hi, lo=0):
    def conv(text):
        try:
            v = typ(text)
        except (ValueError, OverflowError):
            # it read "expected a int"
            raise argparse.ArgumentTypeError(
                f"expected {'an integer' if typ is int else 'a number'}, got {text!r}") from None
        if not (v > 0 and lo <= v <= hi) or (typ is float and not math.isfinite(v)):
            # it read "must be in [0, 1e+06] and > 0"
            raise argparse.ArgumentTypeError(
                (f"must be > 0 and at most {hi:g}" if lo <= 0 else f"must be in [{lo:g}, {hi:g}]")
                + f", got {text}")
        return v
    conv.__name__ = typ.__name__
    return conv


def nonneg_int(text):
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if not 0 <= v <= 100:
        raise argparse.ArgumentTypeError(f"must be 0..100, got {v}")
    return v


def column_options(g):
    g.add_argument("--columns", "-c", action="append", metavar='NAME="HEADER",...',
                   help='name the log\'s columns, e.g. gyr_x="Gyro X",acc_x="Acc X" (repeatable)')
    g.add_argument("--column-map", metavar="FILE",
                   help="a file of NAME = HEADER lines (or a JSON object) naming the columns")


def strict_option(g):
    g.add_argument("--strict", action="store_true",
                   help="a plausibility warning (gyro in deg/s read as rad/s, acc in m/s^2 read "
                        "as g, time in ms read as s, a --rate the time column contradicts, a "
                        "reference frame mistake) is an error (exit 4)")


def unit_options(g, when="", time=True):
    """--gyr-unit, --acc-unit[, --time-unit], --columns, --column-map: how every command reads
    a log's columns (``when``: a condition said first in the help, e.g. "with --log: ")."""
    g.add_argument("--gyr-unit", choices=("rad/s", "deg/s"),
                   help=f"{when}unit of gyr_x..z (default: from the header, else rad/s)")
    g.add_argument("--acc-unit", choices=("g", "m/s2", "m/s^2"),
                   help=f"{when}unit of acc_x..z (default: from the header, else g)")
    if time:
        g.add_argument("--time-unit", choices=("s", "ms", "us", "ns"),
                       help=f"{when}unit of the time column (default: from the header, else s)")
    column_options(g)


def log_options(p):
    g = p.add_argument_group("log")
    unit_options(g)
    g.add_argument("--rate", type=positive(float, 1e9, 1e-3), metavar="HZ",
                   help="fixed sample rate, Hz (default: the time column's intervals)")
    g.add_argument("--fixed-rate", action="store_true",
                   help="run at the median interval of the time column instead of each "
                        "sample's own interval")
    g.add_argument("--axis", choices=("x", "y"), default="x",
                   help="single-axis filters without rate/angle columns: x = roll from gyr_x and "
                        "atan2(acc_y, acc_z); y = pitch from gyr_y and atan2(-acc_x, acc_z)")
    strict_option(g)


def filter_options(p):
    g = p.add_argument_group("filter")
    g.add_argument("--param", "-p", action="append", metavar="NAME=VALUE",
                   help="filter parameter (repeatable); dt comes from the log")
    g.add_argument("--preset", metavar="NAME",
                   help="a named parameter set instead of the defaults (--param still applies "
                        "on top): 'published', the settings of the code a filter was ported "
                        "from (Madgwick's and Mahony's C, MultiWii 2.2, x-io Fusion); "
                        "'advanced', x-io's advanced example for FusionAHRS13 (at the log's "
                        "rate)")
    g.add_argument("--init", metavar="first|identity|W,X,Y,Z",
                   help="initial orientation of 3D filters (default first: from the first "
                        "accelerometer [and magnetometer] sample)")
    g.add_argument("--init-window", type=positive(int, 10**6), metavar="N",
                   help="with --init first: average the first N samples (default 1)")
    g.add_argument("--dtype", choices=("float32", "float64"), default="float64")
    g.add_argument("--backend", choices=("c", "ref"), default="c",
                   help="c: imufuse_c (compiled); ref: imufuse.reference (pure Python)")


def eval_options(p):
    g = p.add_argument_group("reference and output frames")
    g.add_argument("--ref-frame", choices=("NWU", "ENU", "NED"),
                   help="earth frame of the log's q_w..q_z (default: NWU; ENU for BROAD files)")
    g.add_argument("--ref-direction", choices=("sensor-to-earth", "earth-to-sensor"),
                   default="sensor-to-earth", help="what the reference quaternion rotates")
    g.add_argument("--skip", type=positive(float, 1e9), metavar="S",
                   help="leave the first S seconds out of the errors (the start-up), on top of "
                        "a movement column")
    g.add_argument("--heading-offset", action="store_true",
                   help="remove the mean heading offset between the reference and the filter "
                        "before the heading and total errors")
    g.add_argument("--frame", choices=("NWU", "ENU", "NED"), default="NWU",
                   help="earth frame of the output quaternion and Euler angles (default NWU); "
                        "the sensor axes stay as logged (a z-up sensor in NED reads roll 180 "
                        "deg when level: align the axes first with --align)")


def preprocess_options(parser):
    g = parser.add_argument_group("preprocessing, in this order (imufuse.preprocess)")
    g.add_argument("--calibration", metavar="FILE.json",
                   help="sensor calibration (M, s, b per inertial sensor; S, h for the "
                        "magnetometer; see imufuse.preprocess.calibration)")
    g.add_argument("--align", metavar="ALIGNMENT",
                   help="axis alignment, a signed permutation such as +X-Z+Y "
                        "(body x = +sensor x, y = -sensor z, z = +sensor y)")
    g.add_argument("--offset", action="store_true",
                   help="gyroscope offset estimator (FusionOffset) at the log's rate")


def executor_spec(text):
    """--executor: processes[:N], dask:ADDRESS or dask-local[:N] (checked here, made by
    `executor`)."""
    kind, _, arg = text.partition(":")
    if kind in ("processes", "dask-local"):
        if arg and not (arg.isdigit() and 0 < int(arg) <= 1024):
            raise argparse.ArgumentTypeError(f"{text!r}: {kind}:N takes a number of workers "
                                             "from 1 to 1024")
        return text
    if kind == "dask" and arg:
        return text
    raise argparse.ArgumentTypeError(f"{text!r}: expected processes[:N], dask:ADDRESS or "
                                     "dask-local[:N]")


@contextlib.contextmanager
def executor(spec):
    """The concurrent.futures.Executor of an --executor SPEC (None: none), shut down after."""
    if not spec:
        yield None
        return
    kind, _, arg = spec.partition(":")
    if kind == "processes":
        with cf.ProcessPoolExecutor(int(arg) if arg else None) as ex:
            yield ex
        return
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise UsageError(f"--executor {spec}: dask.distributed is not installed "
                         "(pip install 'dask[distributed]')") from None
    if kind == "dask-local":
        with LocalCluster(n_workers=int(arg) if arg else None, threads_per_worker=1,
                          processes=True, dashboard_address=None) as cluster, \
                Client(cluster) as client:
            yield client.get_executor()
        return
    try:
        client = Client(arg, timeout=30)
    except OSError as e:
        raise UsageError(f"--executor {spec}: no dask scheduler there ({e})") from None
    with client:
        yield client.get_executor()
