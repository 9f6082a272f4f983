"""Small checks that turn YAML-like data into typed values or raise :class:`Invalid`.

Each check is a callable ``check(value, path) -> converted value``; ``path`` is the dotted key path
used in the message (``robots.speed_mps``, ``world.objects[1].type``). :func:`section` builds a check
for a mapping from a dict of per-key checks and a constructor, rejecting unknown keys. The scenario
loader adds the file name and turns :class:`Invalid` into its one-line error.
"""

from __future__ import annotations

import math


class Invalid(Exception):
    """A value at ``path`` that does not fit; ``message`` says what was expected. ``text``, the one line
    naming both, is ``path + sep + message`` (``sep`` "": a merger rule's words, which follow the key)."""

    def __init__(self, path: str, message: str, sep: str = ": ") -> None:
        super().__init__(f"{path}{sep}{message}")
        self.path, self.message, self.text = path, message, f"{path}{sep}{message}"


def bad(path: str, expected: str, v) -> Invalid:
    return Invalid(path, f"expected {expected}, got {v!r}")


def number(gt=None, ge=None, lt=None, le=None, why: str = ""):
    """A finite int or float (not a bool) within the given bounds, returned as float; ``why`` says where
    a physical range comes from (a sensor's datasheet, a ROS package's default: the scenario reference
    prints it)."""
    low = ("(", f"{gt:g}") if gt is not None else ("[", f"{ge:g}") if ge is not None else None
    high = (f"{lt:g}", ")") if lt is not None else (f"{le:g}", "]") if le is not None else None
    if low and high:
        bounds = f" in {low[0]}{low[1]}, {high[0]}{high[1]}"
    elif low:
        bounds = f" {'>' if gt is not None else '>='} {low[1]}"
    elif high:
        bounds = f" {'<' if lt is not None else '<='} {high[0]}"
    else:
        bounds = ""

    def check(v, path):
        ok = isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
        if not ok or (gt is not None and v <= gt) or (ge is not None and v < ge) \
                or (lt is not None and v >= lt) or (le is not None and v > le):
            raise bad(path, "a number" + bounds, v)
        return float(v)
    check.bounds = bounds
    check.expected = "a number" + bounds
    check.why = why
    return check


def refused(e: ValueError, path: str) -> Invalid:
    """A merger rule's refusal as an :class:`Invalid` at ``path``: the rule's words after the key when it
    gives them (``rest``, :class:`merger.settings.SettingError`), else its whole message."""
    rest = getattr(e, "rest", None)
    return Invalid(path, rest, sep="") if rest is not None else Invalid(path, str(e))


def ruled(rule, expected: str | None = None, why: str | None = None):
    """A check that is a merger rule ``rule(value, key) -> value`` (one rule per setting, its message
    naming ``key``: the scenario's key path); ``expected`` and ``why`` are its words for the scenario
    reference (by default the rule's own, ``rule.expected`` and ``rule.why``:
    :class:`merger.team.params.Rule`)."""
    def check(v, path):
        try:
            return rule(v, path)
        except ValueError as e:
            raise refused(e, path) from None
    check.expected = getattr(rule, "expected", "") if expected is None else expected
    check.why = getattr(rule, "why", "") if why is None else why
    return check


def integer(ge=None, le=None):
    exp = "an integer" + (f" in [{ge}, {le}]" if ge is not None and le is not None else
                          f" >= {ge}" if ge is not None else f" <= {le}" if le is not None else "")

    def check(v, path):
        if not isinstance(v, int) or isinstance(v, bool) or (ge is not None and v < ge) \
                or (le is not None and v > le):
            raise bad(path, exp, v)
        return int(v)
    check.expected = exp
    return check


def boolean(v, path):
    """``true`` or ``false`` (YAML booleans; not 0/1 or strings)."""
    if not isinstance(v, bool):
        raise bad(path, "true or false", v)
    return v


boolean.expected = "true or false"


def string(v, path):
    if not isinstance(v, str):
        raise bad(path, "a string", v)
    return v


def choice(*options):
    exp = "one of " + ", ".join(repr(o) for o in options)

    def check(v, path):
        if isinstance(v, list | dict) or v not in options:
            raise bad(path, exp, v)
        return v
    check.expected = exp
    return check


string.expected = "a string"


def optional_path(v, path):
    if v is not None and not isinstance(v, str):
        raise bad(path, "null or a path", v)
    return v


optional_path.expected = "null or a path"


def optional(check):
    """``None`` (YAML null) or a value that passes ``check``."""
    def f(v, path):
        return None if v is None else check(v, path)
    f.expected = f"null or {describe(check)}"
    return f


def seq(item, expected: str, min_len: int = 0, length: int | None = None):
    """A list (or tuple) whose items pass ``item``; returned as a tuple."""
    def check(v, path):
        if not isinstance(v, list | tuple) or len(v) < min_len or (length is not None and len(v) != length):
            raise bad(path, expected, v)
        return tuple(item(x, f"{path}[{i}]") for i, x in enumerate(v))
    check.expected = expected
    check.item = item
    return check


def vec2(**bounds):
    """``[x, y]``: two numbers with optional bounds on each."""
    num = number(**bounds)
    return seq(num, f"a list [x, y] of two numbers{num.bounds}", length=2)


def section(cls, schema: dict, required=()):
    """A mapping checked key by key with ``schema`` and passed to ``cls(**values)``.

    Absent keys are left to ``cls``'s defaults; a ``type`` key (object discriminator) is checked
    but not passed on.
    """
    def check(v, path):
        v = {} if v is None else v
        if not isinstance(v, dict):
            raise bad(path, f"a mapping with keys {', '.join(schema)}", v)
        for k in v:
            if k not in schema:
                raise Invalid(join(path, k), f"unknown key; expected one of {', '.join(schema)}")
        for k in required:
            if k not in v:
                raise Invalid(join(path, k), "missing required key")
        return cls(**{k: schema[k](x, join(path, k)) for k, x in v.items() if k != "type"})
    check.schema, check.cls, check.required = schema, cls, tuple(required)
    check.expected = "a mapping"
    return check


def describe(check) -> str:
    """What ``check`` expects, in the words of its error message, and why (for the scenario reference)."""
    why = getattr(check, "why", "")
    return (getattr(check, "expected", None) or "(see the loader)") + (f" — {why}" if why else "")


def join(path: str, key) -> str:
    return f"{path}.{key}" if path else str(key)
