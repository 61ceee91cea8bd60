"""Header rows of a CSV log: the headers that motion-capture and logging tools export over
two or three rows, combined into one name per column that imufuse.io.columns recognises.

    Time;Vicon Orientation;;;;IMU Acceleration (m/s^2);;;IMU Gyroscope;;;IMU Magnetometer;;
    s;W;X;Y;Z;X;Y;Z;X [deg/s];Y [deg/s];Z [deg/s];X;Y;Z

reads as 'Time (s)', 'Vicon Orientation W', ..., 'IMU Acceleration X (m/s^2)', ...,
'IMU Gyroscope X (deg/s)', ... . The row after the first is a header row when none of its
cells is a number and either the first row's names span empty cells with a label under
them (a group row: each group name is carried over the empty cells after it), or every cell
is an axis (X, Y, Z, W) or a unit (s, deg/s, m/s^2, uT, ...). A third row is one more
header row when every cell of it is a unit. A unit comes from the lowest row that gives one
(the unit row, then the axis cell's "X [deg/s]", then the group's "(m/s^2)")."""
import csv
import re

from .columns import _UNIT_SPELLINGS, split_unit

__all__ = ["header_rows"]

#: units a unit row may hold besides those imufuse reads (a motion-capture tool's position
#: in mm, angles in deg, a temperature)
_OTHER_UNITS = {"mm", "cm", "m", "km", "deg", "rad", "degc", "°c", "c", "k", "pa", "hpa",
                "kpa", "mbar", "bar", "%", "v", "mv", "a", "ma", "lsb", "counts", "n", "nm",
                "hz", "m/s", "mm/s", "rad/s^2", "deg/s^2", "-"}
_AXIS = re.compile(r"^([xyzw])(?:\s*[\(\[]\s*([^\)\]]*?)\s*[\)\]])?$", re.I)
#: rows looked at after the first (the header is at most this many rows more)
MAX_EXTRA = 2


def _cells(line, delim):
    return next(csv.reader([line], delimiter=delim)) if delim else line.split()


def _number(cell):
    """True for a cell that is a number (a decimal comma too, nan and inf included)."""
    try:
        float(cell.strip().replace(",", "."))
    except ValueError:
        return False
    return True


def _unit(cell):
    """The cell as a unit ('deg/s', '(s)', '[m/s^2]'), or None."""
    c = cell.strip()
    if len(c) > 2 and c[0] + c[-1] in ("()", "[]"):
        c = c[1:-1].strip()
    low = c.lower().replace(" ", "")
    return c if low and (low in _UNIT_SPELLINGS or low in _OTHER_UNITS) else None


def _label_row(cells):
    """True when ``cells`` can be a header row: something in it, no number."""
    full = [c for c in cells if c.strip()]
    return bool(full) and not any(_number(c) for c in full)


def _spans(first, cells):
    """True when the first row's names span empty cells with a label under them."""
    named = False
    for i, g in enumerate(first):
        if g.strip():
            named = True
        elif named and i < len(cells) and cells[i].strip():
            return True
    return False


def _axes_or_units(cells):
    return all(_AXIS.match(c.strip()) or _unit(c) for c in cells if c.strip())


def _combine(first, second, units, spans):
    """One name per column from the group row, the axis (or sub-name) row and the unit row."""
    n = max(len(first), len(second), len(units))
    out, group = [], ""
    for i in range(n):
        g = first[i].strip() if i < len(first) else ""
        if g or not spans:
            group = g
        gname, gunit = split_unit(group) if group else ("", None)
        a = second[i].strip() if i < len(second) else ""
        u = units[i].strip() if i < len(units) else ""
        sub, aunit = "", None
        m = _AXIS.match(a)
        if m:
            sub, aunit = m.group(1).upper(), m.group(2)
        elif _unit(a):
            aunit = _unit(a)
        elif a:
            sub, aunit = split_unit(a)
        unit = _unit(u) or aunit or gunit
        name = " ".join(p for p in (gname, sub) if p)
        out.append(f"{name} ({unit})" if name and unit else name)
    return out


def header_rows(first, lines, delim):
    """(the header's names, how many of ``lines`` it took): ``first`` the first header row's
    cells, ``lines`` the text lines after it, ``delim`` the delimiter (None: whitespace).
    A one-row header comes back as it is, with 0."""
    rows, used = [], 0
    for k, ln in enumerate(lines):
        if len(rows) == MAX_EXTRA:
            break
        if not ln.strip():
            continue
        if ln.lstrip().startswith("#"):
            break
        cells = _cells(ln, delim)
        if not _label_row(cells):
            break
        if not rows:
            spans = _spans(first, cells)
            if not (spans or _axes_or_units(cells)):
                break
        elif not all(_unit(c) for c in cells if c.strip()):
            break
        rows.append(cells)
        used = k + 1
    if not rows:
        return first, 0
    units = rows[1] if len(rows) > 1 else []
    if len(rows) == 1 and not _spans(first, rows[0]) and all(_unit(c) for c in rows[0]
                                                             if c.strip()):
        # one row of units under the names: 'Gyroscope X' over 'deg/s'
        units, second = rows[0], []
    else:
        second = rows[0]
    return _combine(first, second, units, _spans(first, second)), used
