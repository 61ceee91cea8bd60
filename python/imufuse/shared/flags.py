"""The command line's options in a log's notes and errors, said as well in the Python API's
terms for a user of imufuse.session.Session and imufuse.tune.Tuner (the messages are written
once, for both).

  in_users_terms(command_line)   a context in which a ValueError's message is said
                       as_python says it (unless command_line: the command line's words)
  users_terms          a method decorator: the same for a method of an object whose
                       ``_command_line`` says whether it serves the command line
  as_python(message)   the message with "[Python: ...]" added when it names command-line
                       options: each option as the message gives it and what it is in
                       Python, e.g. "give --gyr-unit deg/s" -> "... [Python: --gyr-unit
                       deg/s is ReadOptions(gyr_unit='deg/s')]"; a message that has its
                       part already is returned as it is

Every option maps to the field of the same name (dashes as underscores) of ReadOptions,
ScoreOptions, Tuner or Tuner.search, ``-p NAME=VALUE`` to run()'s params, ``imufuse
calibrate SENSOR`` to imufuse.calibration.log.run_log. A glossary, not advice: "--rate 100 Hz
... leave it out" says which setting the message means; the message says what to do with it.
A value the message does not give is the command line's placeholder (FILE, HZ, ...).
"""
import contextlib
import functools
import re
from typing import Any, Callable, Dict, Iterator, List, Tuple, TypeVar

#: option -> (where it is in Python, field, the pattern of its value in a message, the
#: placeholder); no pattern: a switch (True)
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
    "metric": ("Tuner", "metric", r"inclination|heading|total", "METRIC"),
    "grid": ("Tuner.search", "grid", r"(?!)", "GRID"),
    "refine": ("Tuner.search", "refine", r"[0-9]+", "N"),
}
_OPTION = re.compile(r"(?<![\w-])--(" + "|".join(sorted(_OPTIONS, key=len, reverse=True))
                     + r")(?![\w-])(?:(?=[ =]+(\S+)))?")
_PARAM = re.compile(r"(?<![\w-])-p (\w+)=([^\s,;)]+)")
_CALIBRATE = re.compile(r"imufuse calibrate (gyro|acc|mag)\b")


def _value(field: str, pattern: str, placeholder: str, text: str) -> Tuple[str, str]:
    """(the value as the message gives it, the value in Python)"""
    if not pattern:
        return "", "True"
    m = re.match(pattern, text or "")
    v = placeholder if m is None else m.group(0)
    if field == "columns":
        k, h = v.split("=", 1)
        return v, "{" + repr(k) + ": " + repr(h.strip('"')) + "}"
    if v == placeholder:
        return v, v
    if field in ("rate", "skip", "refine"):
        return v, v.rstrip(".")
    return v, repr(v)


def as_python(message: str) -> str:
    """``message`` with what the command-line options it names are in Python."""
    if "[Python: " in message:
        return message
    # each option once: as the message first gives it with a value, else its placeholder
    found: Dict[str, Tuple[str, str]] = {}
    for m in _OPTION.finditer(message):
        where, field, pattern, placeholder = _OPTIONS[m.group(1)]
        given, value = _value(field, pattern, placeholder, m.group(2))
        if m.group(1) not in found or found[m.group(1)][0] == placeholder != given:
            found[m.group(1)] = (given, value)
    said: List[str] = []
    for opt, (given, value) in found.items():
        where, field = _OPTIONS[opt][:2]
        said.append(f"--{opt}{' ' + given if given else ''} is {where}({field}={value})")
    for k, v in _PARAM.findall(message):
        said.append(f"-p {k}={v} is Session.run(name, params={{{k!r}: {v}}})")
    for s in dict.fromkeys(_CALIBRATE.findall(message)):
        said.append(f"imufuse calibrate {s} is run_log({s!r}, LOG, OUTPUT) of "
                    "imufuse.calibration.log")
    return f"{message} [Python: {'; '.join(said)}]" if said else message


@contextlib.contextmanager
def in_users_terms(command_line: bool) -> Iterator[None]:
    """A ValueError (LogError, FilterError, StrictError...) raised inside, its message said
    in a Python user's terms as well (unless ``command_line``); its type and traceback kept."""
    try:
        yield
    except ValueError as e:
        if not command_line and e.args and isinstance(e.args[0], str):
            e.args = (as_python(e.args[0]), *e.args[1:])
        raise


F = TypeVar("F", bound=Callable[..., Any])


def users_terms(method: F) -> F:
    """A method whose ValueErrors are said in its object's user's terms (in_users_terms with
    the object's ``_command_line``)."""
    @functools.wraps(method)
    def said(self: Any, *args: Any, **kwargs: Any) -> Any:
        with in_users_terms(self._command_line):
            return method(self, *args, **kwargs)
    return said  # type: ignore[return-value]
