"""A filter's settings as one record: a frozen dataclass that mirrors the C settings struct
(imf_<filter>_settings_t) member for member, its values in the C's units, and beside each
member the user's default and unit, the check of a user's value and the one conversion to
the C's unit (`setting`).

    @dataclasses.dataclass(frozen=True)
    class XSettings(SettingsRecord):
        dt: float = setting(REQUIRED, "s", real(lo=0.0, lo_open=True))
        rate: float = setting(100.0, "deg/s", real(lo=0.0), to_c=deg_to_rad)

The constructor's keywords are the members in order with their defaults (`keywords()`:
the filter class's `_params`, whose signature the compiled classes, the catalogue and the
stubs show); `from_user` checks each value in that order (a check sees the values checked
before it) and converts it once. The record's constructor takes C values by name,
unchecked (a filter's init builds one from another, as the C does).

For the generic tools that pair the C init's member names with the values
(imufuse.reference._base.init_names) and for the fixed-point twins that extend a float
twin's values (reference/fixed_robust.py), a record reads as the tuple of its values in
the struct's order (iteration, indexing, slicing, + a tuple); a filter's own code reads
them by name.
"""
import dataclasses
import inspect
import math
import types

from ..shared import checks as _checks

#: the default of a setting the user must give (dt)
REQUIRED = inspect.Parameter.empty
#: setting(keyword=FIXED): a member the constructor does not take (always its default)
FIXED = ""
#: prior[USER]: every keyword as the user gave it (a check that reads two keywords at once,
#: as Complementary1DBias's kp and ki from omega0 and xi)
USER = "<user>"

_DEG = math.pi / 180.0


def setting(default, unit, check, to_c=None, *, keyword=None, kw_only=False):
    """A member of a settings record: its `default` in the user's `unit` (REQUIRED: none),
    `check(name, value, prior)` -> the checked value (prior: the values checked before,
    by name, and the record's extra keywords; raises ValueError naming the setting), and
    `to_c` the one conversion of the checked value to the C's unit (None: the same unit).

    keyword: the constructor keyword the value comes from when it is not the member's name
    (Mahony2D's error="exact" -> exact = 1; Madgwick's acc_gate=(lo, hi) -> acc_gate_lo
    and acc_gate_hi, one keyword for two members); FIXED: no keyword, always the default
    (a member of a shared C struct that one form does not take). kw_only: the keyword is
    keyword-only in the constructor."""
    return dataclasses.field(metadata={"default": default, "unit": unit, "check": check,
                                       "to_c": to_c, "keyword": keyword, "kw_only": kw_only})


def real(**bounds):
    """The check of a real number within imufuse.shared.checks.check_real's bounds."""
    return lambda name, value, prior: _checks.check_real(name, value, **bounds)


def choice(*choices):
    """The check of one of `choices`."""
    return lambda name, value, prior: _checks.check_choice(name, value, choices)


def dt():
    """The check of a sample period (imufuse.shared.checks.check_dt)."""
    return lambda name, value, prior: _checks.check_dt(value)


def fixed(name, value, prior):
    """The check of a FIXED member: its default, as declared."""
    return value


def deg_to_rad(v):
    """deg or deg/s -> rad or rad/s, in double (for both backends)."""
    return v * _DEG


class SettingsRecord:
    """The base of a settings record (a frozen dataclass of `setting` members).

    extra: keywords of the constructor that are no member (Complementary1D's T, an
    alternative to alpha), as (name, default, keyword-only) after the members' keywords;
    the checks see their values in `prior`."""

    extra: tuple = ()

    @classmethod
    def _keyword(cls, f):
        k = f.metadata.get("keyword")
        return f.name if k is None else k

    @classmethod
    def signature(cls) -> inspect.Signature:
        """The constructor's keywords: every member's (a shared keyword once, at its first
        member), with its default in the user's unit, then the extra keywords."""
        params, seen = [], set()
        for f in dataclasses.fields(cls):  # type: ignore[arg-type]
            k = cls._keyword(f)
            if k == FIXED or k in seen:
                continue
            seen.add(k)
            kind = (inspect.Parameter.KEYWORD_ONLY if f.metadata.get("kw_only")
                    else inspect.Parameter.POSITIONAL_OR_KEYWORD)
            params.append(inspect.Parameter(k, kind, default=f.metadata["default"]))
        params += [inspect.Parameter(n, inspect.Parameter.KEYWORD_ONLY if kw
                                     else inspect.Parameter.POSITIONAL_OR_KEYWORD, default=d)
                   for n, d, kw in cls.extra]
        return inspect.Signature(params)

    @classmethod
    def from_user(cls, *args, **kwargs):
        """The record of the user's settings (the constructor's keywords): each checked
        in the members' order, then converted to the C's unit."""
        bound = cls.signature().bind(*args, **kwargs)
        bound.apply_defaults()
        checked = {n: bound.arguments[n] for n, _, _ in cls.extra}
        for n, v in checked.items():
            if isinstance(v, _checks.COMPLEX):
                raise ValueError(f"{n}: must be a real number, not complex, got {v!r}")
        checked[USER] = dict(bound.arguments)
        c = {}
        for f in dataclasses.fields(cls):
            k = cls._keyword(f)
            user = f.metadata["default"] if k == FIXED else bound.arguments[k]
            if isinstance(user, _checks.COMPLEX):
                # before any check: one that compares (1+0j == 1 == True) would let it
                # through to a float() or int() that drops the imaginary part
                raise ValueError(f"{k or f.name}: must be a real number, not complex, "
                                 f"got {user!r}")
            v = f.metadata["check"](k or f.name, user, checked)
            checked[f.name] = v
            c[f.name] = v if f.metadata["to_c"] is None else f.metadata["to_c"](v)
        return cls(**c)

    @classmethod
    def keywords(cls):
        """A filter class's `_params`: from_user, with the keywords as its signature."""
        def params(*args, **kwargs):
            return cls.from_user(*args, **kwargs)
        params.__signature__ = cls.signature()
        params.__name__ = params.__qualname__ = "_params"
        params.__doc__ = f"The constructor's settings, checked: a {cls.__name__} (C units)."
        return staticmethod(params)

    @classmethod
    def names(cls):
        """The members' names, in the C struct's order."""
        return tuple(f.name for f in dataclasses.fields(cls))

    def members(self):
        """{member: value} in the C struct's order (C units)."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}

    def as_real(self, R):
        """The settings as the C filter keeps its copy of the struct: every real member of
        type R (imf_real: float or numpy.float32), the others as they are; mutable, as that
        copy is (set_dt changes dt)."""
        return types.SimpleNamespace(**{k: R(v) if isinstance(v, float) else v
                                        for k, v in self.members().items()})

    # the values in the struct's order, for the generic tools (module docstring)
    def __iter__(self):
        return iter(self.members().values())

    def __len__(self):
        return len(dataclasses.fields(self))

    def __getitem__(self, i):
        return tuple(self)[i]

    def __add__(self, other):
        return tuple(self) + tuple(other)
