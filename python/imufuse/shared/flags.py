"""The command line's options in a log's notes and errors, said as well in the Python API's
terms for a user of imufuse.session.Session (the notes are written once, for both).

  as_python(message)   the message with "[Python: ...]" added after it when it names
                       command-line options, e.g. "give --gyr-unit deg/s" ->
                       "... [Python: ReadOptions(gyr_unit='deg/s')]"

Every option named maps to the field of the same name (dashes as underscores) of
ReadOptions or ScoreOptions, or to run()'s params (``-p NAME=VALUE``); ``imufuse calibrate
SENSOR`` to imufuse.calibration.log.run_log. A value the message does not give is written
as the placeholder the command line's help uses (FILE, HZ, ...).
"""
import re
from typing import Dict, List, Tuple

#: option -> (record, field, the pattern of its value in a message, placeholder); a value
#: None: a switch (True)
_OPTIONS: Dict[str, Tuple[str, str, str, str]] = {
    "gyr-unit": ("ReadOptions", "gyr_unit", r"rad/s|deg/s", "UNIT"),
    "acc-unit": ("ReadOptions", "acc_unit", r"m/s2|g\b", "UNIT"),
    "time-unit": ("ReadOptions", "time_unit", r"(?:s|ms|us)\b", "UNIT"),
    "rate": ("ReadOptions", "rate", r"[0-9][0-9.e+]*|HZ", "HZ"),
    "columns": ("ReadOptions", "columns", r'\w+="[^"]*"', 'NAME="HEADER"'),
    "calibration": ("ReadOptions", "calibration", r"(?!)", "FILE"),
    "align": ("ReadOptions", "align", r"[+-][XYZxyz][+-][XYZxyz][+-][XYZxyz]", "ALIGNMENT"),
    "fixed-rate": ("ReadOptions", "fixed_rate", "", ""),
    "offset": ("ReadOptions", "offset", "", ""),
    "strict": ("ReadOptions", "strict", "", ""),
    "ref-frame": ("ScoreOptions", "ref_frame", r"NWU|ENU|NED", "FRAME"),
    "ref-direction": ("ScoreOptions", "ref_direction", r"sensor-to-earth|earth-to-sensor",
                      "DIRECTION"),
    "skip": ("ScoreOptions", "skip", r"[0-9][0-9.e+]*", "SECONDS"),
}
_OPTION = re.compile(r"(?<![\w-])--(" + "|".join(sorted(_OPTIONS, key=len, reverse=True))
                     + r")(?![\w-])(?:(?=[ =]+(\S+)))?")
_PARAM = re.compile(r"(?<![\w-])-p (\w+)=(\S+?)[,;)]?(?:\s|$)")
_CALIBRATE = re.compile(r"imufuse calibrate (gyro|acc|mag)\b")


def _value(field: str, pattern: str, placeholder: str, text: str) -> str:
    if not pattern:
        return "True"
    m = re.match(pattern, text or "")
    if m is None:
        return placeholder
    v = m.group(0)
    if v == placeholder:
        return v
    if field == "columns":
        k, h = v.split("=", 1)
        return "{" + repr(k) + ": " + repr(h.strip('"')) + "}"
    if field in ("rate", "skip") and v[0].isdigit():
        return v.rstrip(".")
    return repr(v)


def as_python(message: str) -> str:
    """``message`` with the Python API's terms for the command-line options it names."""
    records: Dict[str, List[str]] = {}
    for m in _OPTION.finditer(message):
        record, field, pattern, placeholder = _OPTIONS[m.group(1)]
        items = records.setdefault(record, [])
        if not any(i.startswith(field + "=") for i in items):   # the first value given
            items.append(f"{field}={_value(field, pattern, placeholder, m.group(2))}")
    said = [f"{r}({', '.join(items)})" for r, items in records.items()]
    said += [f"run(name, params={{{k!r}: {v}}})" for k, v in _PARAM.findall(message)]
    said += [f"imufuse.calibration.log.run_log({s!r}, ...)" for s in
             dict.fromkeys(_CALIBRATE.findall(message))]
    return f"{message} [Python: {'; '.join(said)}]" if said else message
