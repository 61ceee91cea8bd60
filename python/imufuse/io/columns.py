"""Column headers: recognition of imufuse's names and common spellings (`recognise`),
units in headers ("Gyroscope X (deg/s)": `split_unit`, and the unit each quantity is read
in, `_units`), column maps ({name: header}: `parse_column_map`, `read_column_map`), and the
errors that name a missing column with its close matches (`require`). A column named twice
in a map is refused by name (LogError of kind "usage")."""
import csv
import difflib
import re

from .._jsonfile import FileContentError, parse_object, read_text
from .log import KNOWN, TIME_UNITS, LogError

#: how unit spellings in headers are read
_UNIT_SPELLINGS = {
    "rad/s": "rad/s", "rads": "rad/s", "rad/sec": "rad/s", "radians/s": "rad/s",
    "deg/s": "deg/s", "dps": "deg/s", "°/s": "deg/s", "degrees/s": "deg/s", "deg/sec": "deg/s",
    "g": "g", "gee": "g",
    "m/s^2": "m/s^2", "m/s2": "m/s^2", "m/s²": "m/s^2", "m/s/s": "m/s^2", "ms^-2": "m/s^2",
    "ut": "uT", "µt": "uT", "μt": "uT", "microtesla": "uT", "gauss": "gauss", "mg": "mgauss",
    "nt": "nT", "au": "a.u.", "a.u.": "a.u.",
    "s": "s", "sec": "s", "seconds": "s", "ms": "ms", "us": "us", "µs": "us", "μs": "us",
    "ns": "ns",
}

# recognised header names (normalised: lower case, unit removed, runs of
# space/-/./: turned into "_")
_ALIASES = {"time": ["time", "t", "timestamp", "time_s", "times", "seconds", "sec"],
            "movement": ["movement", "moving", "mask"],
            "rate": ["rate"], "angle": ["angle"]}
for _ax in "xyz":
    _ALIASES[f"gyr_{_ax}"] = [f"gyr_{_ax}", f"gyro_{_ax}", f"gyroscope_{_ax}", f"g{_ax}",
                              f"gyr{_ax}", f"gyro{_ax}", f"w{_ax}", f"omega_{_ax}",
                              f"angular_velocity_{_ax}", f"rot_{_ax}", f"gyroscope{_ax}"]
    _ALIASES[f"acc_{_ax}"] = [f"acc_{_ax}", f"accel_{_ax}", f"accelerometer_{_ax}",
                              f"acceleration_{_ax}", f"a{_ax}", f"acc{_ax}", f"accel{_ax}",
                              f"accelerometer{_ax}"]
    _ALIASES[f"mag_{_ax}"] = [f"mag_{_ax}", f"magn_{_ax}", f"magnetometer_{_ax}",
                              f"magnetic_field_{_ax}", f"m{_ax}", f"mag{_ax}",
                              f"magnetometer{_ax}"]
for _c in "wxyz":
    _ALIASES[f"q_{_c}"] = [f"q_{_c}", f"q{_c}", f"quat_{_c}", f"quaternion_{_c}",
                           f"quat{_c}", f"ref_q_{_c}", f"q_ref_{_c}", f"quat_ref_{_c}"]
_RECOGNISE = {a: canon for canon, names in _ALIASES.items() for a in names}


_UNIT_RE = re.compile(r"^(.*?)\s*[\(\[]\s*([^\)\]]*?)\s*[\)\]]\s*$")


def split_unit(header):
    """'Gyroscope X (deg/s)' -> ('Gyroscope X', 'deg/s'); no unit -> (header, None).
    The unit is given in its canonical spelling when known, else as written."""
    m = _UNIT_RE.match(header.strip())
    if not m:
        return header.strip(), None
    name, unit = m.group(1), m.group(2)
    return name, _UNIT_SPELLINGS.get(unit.lower().replace(" ", ""), unit)


def _norm(name):
    return re.sub(r"[\s\-\.:/]+", "_", name.strip().lower()).strip("_")


def recognise(header):
    """{known name: header index} for the headers imufuse recognises. When
    several headers could be one column, the closer spelling wins (`time`
    before `t`); a header whose unit belongs to another quantity ("T (degC)")
    is not taken for time."""
    best = {}
    for i, h in enumerate(header):
        name, unit = split_unit(h)
        canon = _RECOGNISE.get(_norm(name))
        if canon is None:
            continue
        if canon == "time" and unit is not None and unit not in TIME_UNITS:
            continue
        rank = _ALIASES[canon].index(_norm(name))
        if canon not in best or rank < best[canon][0]:
            best[canon] = (rank, i)
    return {k: i for k, (r, i) in best.items()}


def duplicate_columns(header):
    """{known name: [header indices]} for names that two or more headers spell equally
    closely (e.g. 'gyr_x' twice): recognise() cannot choose between them."""
    seen = {}
    for i, h in enumerate(header):
        name, unit = split_unit(h)
        canon = _RECOGNISE.get(_norm(name))
        if canon is None or (canon == "time" and unit is not None and unit not in TIME_UNITS):
            continue
        seen.setdefault((canon, _ALIASES[canon].index(_norm(name))), []).append(i)
    best = recognise(header)
    return {c: idx for (c, r), idx in seen.items() if len(idx) > 1 and best.get(c) in idx}


def parse_column_map(text, what="column map"):
    """'gyr_x="Gyroscope X (deg/s)",gyr_y=...' -> {name: header}; a name given twice is a
    LogError ("usage") naming it (`what`: the option, in the messages)."""
    out = {}
    for item in next(csv.reader([text], skipinitialspace=True)) if text.strip() else ():
        if not item.strip():
            continue
        if "=" not in item:
            raise LogError(f"{what} {item!r}: expected NAME=HEADER (e.g. "
                           'gyr_x="Gyroscope X (deg/s)")', "usage")
        k, v = item.split("=", 1)
        k = k.strip()
        if k in out:
            raise LogError(f"{what} {text!r}: {k!r} named twice; name each column once", "usage")
        out[k] = v.strip().strip('"').strip("'")
    return out


def read_column_map(path):
    """A mapping file: a JSON object {name: header}, or lines NAME = HEADER
    ('#' starts a comment). Read by imufuse._jsonfile (UTF-8, at most 1 MiB; a JSON map
    nested too deep or not an object is a data error); a name given twice is a LogError
    ("usage") naming it and its lines."""
    try:
        text = read_text(path, "column map")
        if text.lstrip().startswith("{"):
            m = parse_object(text, path, "column map", repeated="usage")
        else:
            m = None
    except FileContentError as e:
        raise LogError(str(e), e.kind) from None
    if m is not None:
        if not all(isinstance(v, str) for v in m.values()):
            raise LogError(f"{path}: the JSON column map must be an object of name: header strings")
        return dict(m)
    out, lines = {}, {}
    for ln, line in enumerate(text.splitlines(), 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        if "=" not in line:
            raise LogError(f"{path}:{ln}: expected NAME = HEADER, got {line!r}")
        k, v = line.split("=", 1)
        k = k.strip()
        if k in out:
            raise LogError(f"{path}:{ln}: {k!r} named twice (also on line {lines[k]}); name each "
                           "column once", "usage")
        out[k], lines[k] = v.strip().strip('"').strip("'"), ln
    return out


def _close(name, candidates):
    return difflib.get_close_matches(name, candidates, n=2, cutoff=0.6)


def _apply_map(path, header, found, column_map):
    for k, h in column_map.items():
        if k not in KNOWN:
            c = _close(k, KNOWN)
            raise LogError(f"column map: {k!r} is not a log column"
                           + (f" (did you mean {' or '.join(map(repr, c))}?)" if c else "")
                           + f"; expected one of {', '.join(KNOWN)}", "usage")
        if h not in header:
            stripped = [x for x in header if x.strip().lower() == h.strip().lower()]
            if len(stripped) == 1:
                h = stripped[0]
            else:
                c = _close(h, header)
                raise LogError(f"{path}: column map {k}={h!r}: no such column in the header"
                               + (f" (did you mean {' or '.join(map(repr, c))}?)" if c else "")
                               + f"; columns found: {', '.join(map(repr, header))}")
        found[k] = header.index(h)
    return found


def _missing(names, header, used=()):
    msgs = []
    unknown = [h for h in header if h not in used]
    for n in names:
        lower = [h for h in unknown if h.strip().lower() == n]
        close = lower or _close(n, unknown) or _close(n, [_norm(split_unit(h)[0]) for h in unknown])
        if close and close[0] not in header:          # matched on a normalised name
            close = [h for h in unknown if _norm(split_unit(h)[0]) in close]
        msgs.append(f"{n}" + (f" (did you mean {' or '.join(repr(c) for c in close)}?)"
                              if close else ""))
    return msgs


def require(log, names, why=""):
    """LogError naming every missing column of `names`, with close matches."""
    miss = [n for n in names if n not in log.columns]
    if miss:
        raise LogError(f"{log.path}: missing column{'s' if len(miss) > 1 else ''} "
                       f"{', '.join(_missing(miss, log.header, set(log.sources.values())))}"
                       f"{' ' + why if why else ''}; columns found: "
                       f"{', '.join(map(repr, log.header))} (name columns with --columns "
                       f'NAME="HEADER", e.g. gyr_x="Gyro X")')


def _units(cols, sources, kind, names, given, table, default, warnings):
    """Resolve the unit of `names` (given > header > default); convert in place.
    Returns (unit, where from)."""
    header_units = {split_unit(sources[n])[1] for n in names if n in sources}
    header_units.discard(None)
    known = {u for u in header_units if u in table or (kind == "acc" and u == "m/s^2")}
    if len(known) > 1:
        raise LogError(f"columns {', '.join(names)} have different units in the header: "
                       f"{', '.join(sorted(known))}")
    unknown = header_units - known
    if given is not None:
        unit, why = given, "given"
        if known and given.replace("m/s2", "m/s^2") not in {k.replace("m/s2", "m/s^2")
                                                             for k in known}:
            warnings.append(f"{kind} unit {given} given, the header says {known.pop()}: "
                            f"using {given}")
    elif known:
        unit, why = known.pop(), "header"
    else:
        if unknown and kind in ("gyr", "acc"):
            raise LogError(f"unknown {kind} unit {unknown.pop()!r} in the header; expected one of "
                           f"{', '.join(table)} (or give --{kind}-unit)")
        unit, why = default, "default"
    f = table[unit]
    if f != 1.0:
        for n in names:
            if n in cols:
                cols[n] = cols[n] * f
    return unit, why
