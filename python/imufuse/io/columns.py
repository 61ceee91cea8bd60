"""Column headers: recognition of imufuse's names and common spellings (`recognise`; also
a sensor's word after other words, "IMU Gyroscope X", "Vicon Orientation W", as tools export
them), units in headers ("Gyroscope X (deg/s)", "AccX_g": `split_unit`, and the unit each
quantity is read in, `_units`), column maps ({name: header}: `parse_column_map`,
`read_column_map`), and the errors that name a missing column with its close matches of the
same axis (`require`). A column named twice in a map is refused by name (LogError of kind
"usage")."""
import csv
import difflib
import re

from ..shared.jsonfile import FileContentError, parse_object, read_text
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

#: a sensor's words in a longer header, after any other words and before the axis ("IMU
#: Gyroscope X", "Vicon Orientation W", "AccelX"): recognised after every spelling above
_SENSOR_WORDS = {
    "gyr": ("gyroscope", "angular_velocity", "angular_rate", "rate_of_turn", "gyro", "gyr"),
    "acc": ("accelerometer", "acceleration", "accel", "acc"),
    "mag": ("magnetometer", "magnetic_field", "magnetic", "magn", "mag"),
    "q": ("orientation", "quaternion", "quat", "attitude"),
}
_SENSOR_RE = {k: re.compile(r"^(?:(.*?)_)?(?:" + "|".join(w) + r")_?([xyzw])$")
              for k, w in _SENSOR_WORDS.items()}
#: words before a sensor's word that make it something else than the sensor's reading
#: (x-io's "Earth Acceleration X", a "Linear Acceleration", an estimated bias)
_NOT_THE_SENSOR = {"free", "freeacc", "linear", "lin", "earth", "global", "world", "gravity",
                   "delta", "bias", "offset", "error", "std", "var", "variance", "sigma", "cov",
                   "noise"}
#: the rank of a header recognised by its sensor's word (after every alias)
_WORD_RANK = 100

#: units written after the name with an underscore ("AccX_g", "gyro_x_dps", "t_ms"), as
#: normalised names end
_SUFFIX_UNITS = {"g": "g", "dps": "deg/s", "degs": "deg/s", "deg_s": "deg/s",
                 "rads": "rad/s", "rad_s": "rad/s", "mps2": "m/s^2", "ms2": "m/s^2",
                 "m_s2": "m/s^2", "m_s^2": "m/s^2", "ut": "uT", "s": "s", "sec": "s",
                 "ms": "ms", "us": "us", "ns": "ns"}


_UNIT_RE = re.compile(r"^(.*?)\s*[\(\[]\s*([^\)\]]*?)\s*[\)\]]\s*$")


def _by_word(n):
    """(known name, prefix) of a normalised name by its sensor's word, or None; a quaternion
    component is only one with its three others (checked by `_matches`)."""
    for kind, rx in _SENSOR_RE.items():
        m = rx.match(n)
        if not m:
            continue
        pre, axis = m.group(1) or "", m.group(2)
        if set(pre.split("_")) & _NOT_THE_SENSOR or (kind != "q" and axis == "w"):
            return None
        return f"{kind}_{axis}", (pre, n[len(pre):].lstrip("_")[:-1].rstrip("_"))
    return None


def _known(n):
    return n in _RECOGNISE or _by_word(n) is not None


def split_unit(header):
    """'Gyroscope X (deg/s)' -> ('Gyroscope X', 'deg/s'); 'AccX_g' -> ('AccX', 'g') (a unit
    after an underscore, when the rest is a name imufuse recognises); no unit -> (header,
    None). The unit is given in its canonical spelling when known, else as written."""
    m = _UNIT_RE.match(header.strip())
    if not m:
        name = header.strip()
        n = _norm(name)
        if n and not _known(n):
            for suf in sorted(_SUFFIX_UNITS, key=len, reverse=True):
                if n.endswith("_" + suf) and _known(n[:-len(suf) - 1]):
                    pat = r"[\s\-\.:/_]+".join(re.escape(p) for p in suf.split("_"))
                    cut = re.match(r"^(.*?)[\s\-\.:/_]+" + pat + r"$", name, re.I)
                    if cut:
                        return cut.group(1), _SUFFIX_UNITS[suf]
        return name, None
    name, unit = m.group(1), m.group(2)
    return name, _UNIT_SPELLINGS.get(unit.lower().replace(" ", ""), unit)


def _norm(name):
    return re.sub(r"[\s\-\.:/]+", "_", name.strip().lower()).strip("_")


def _matches(header):
    """[(known name, rank, header index)] of every header imufuse recognises: by a spelling
    of _ALIASES (its rank: its place in the list), else by its sensor's word (a quaternion
    only with all four of w, x, y, z under the same words); a header whose unit belongs to
    another quantity ("T (degC)") is not taken for time."""
    out, quats = [], {}
    for i, h in enumerate(header):
        name, unit = split_unit(h)
        n = _norm(name)
        canon = _RECOGNISE.get(n)
        if canon is not None:
            if canon == "time" and unit is not None and unit not in TIME_UNITS:
                continue
            out.append((canon, _ALIASES[canon].index(n), i))
            continue
        word = _by_word(n)
        if word is None:
            continue
        if word[0].startswith("q_"):
            quats.setdefault(word[1], {})[word[0]] = i
        else:
            out.append((word[0], _WORD_RANK, i))
    for parts in quats.values():
        if len(parts) == 4:
            out += [(c, _WORD_RANK, i) for c, i in parts.items()]
    return out


def recognise(header):
    """{known name: header index} for the headers imufuse recognises. When
    several headers could be one column, the closer spelling wins (`time`
    before `t`, `acc_x` before 'IMU Acceleration X'); a header whose unit belongs to another
    quantity ("T (degC)") is not taken for time."""
    best = {}
    for canon, rank, i in _matches(header):
        if canon not in best or rank < best[canon][0]:
            best[canon] = (rank, i)
    return {k: i for k, (r, i) in best.items()}


def duplicate_columns(header):
    """{known name: [header indices]} for names that two or more headers spell equally
    closely (e.g. 'gyr_x' twice, or 'IMU1 Gyroscope X' and 'IMU2 Gyroscope X'): recognise()
    cannot choose between them."""
    seen = {}
    for canon, rank, i in _matches(header):
        seen.setdefault((canon, rank), []).append(i)
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
    ('#' starts a comment). Read by imufuse.shared.jsonfile (UTF-8, at most 1 MiB; a JSON map
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


def _guess(header):
    """(sensor, axis) a header seems to hold ('AccX_raw' -> ('acc', 'x'), 'Gyr-X raw' ->
    ('gyr', 'x')); either None when not seen."""
    n = _norm(split_unit(header)[0])
    for kind, words in _SENSOR_WORDS.items():
        m = re.search(r"(?:^|_)(?:" + "|".join(words) + r")(?:_?([xyzw]))?(?=_|$)", n)
        if m:
            return kind, m.group(1)
    m = re.search(r"(?:^|_)([xyzw])(?=_|$)", n)
    return None, m.group(1) if m else None


def _missing(names, header, used=()):
    msgs = []
    unknown = [h for h in header if h not in used]
    for n in names:
        kind, _, axis = n.partition("_")
        if not axis:
            kind = axis = ""
        lower = [h for h in unknown if h.strip().lower() == n]
        same = [h for h in unknown if kind and _guess(h) == (kind, axis)]
        close = lower or same or _close(n, unknown) or _close(
            n, [_norm(split_unit(h)[0]) for h in unknown])
        if close and close[0] not in header:          # matched on a normalised name
            close = [h for h in unknown if _norm(split_unit(h)[0]) in close]
        if axis and not lower:                        # never a column of another axis
            close = [h for h in close if _guess(h)[1] in (None, axis)]
        close = close[:2]
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
