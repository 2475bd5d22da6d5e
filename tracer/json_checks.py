"""Checks of parsed JSON values for the scene loader: each returns the value in the type asked
for or raises a SceneError naming the key path and what was expected."""
import json
import math

import numpy as np

from tracer.errors import SceneError
from tracer.formats.source import quote, shown

JSON_INT_DIGITS = 400  # longer integers are no finite float64 (1.8e308 has 309 digits)


def no_duplicates(pairs):
    d = {}
    for k, v in pairs:
        if k in d:
            raise SceneError(f"duplicate key {quote(k)} in a JSON object")
        d[k] = v
    return d


def show_value(v, limit=60) -> str:
    """Short JSON rendering of a value for error messages."""
    try:
        s = json.dumps(v)
    except (TypeError, ValueError, RecursionError):
        s = "<" + type(v).__name__ + ">"
    return s if len(s) <= limit else s[:limit - 3] + "..."


def got(v) -> str:
    """'a list [1, 2]', 'a string "x"', 'null', '3': the value, with its kind where useful."""
    kind = {dict: "an object ", list: "a list ", str: "a string "}.get(type(v), "")
    return kind + show_value(v)


def as_object(v, key) -> dict:
    if not isinstance(v, dict):
        raise SceneError(f"expected an object, got {got(v)}", key=key or None)
    return v


def as_list(v, key) -> list:
    if not isinstance(v, list):
        raise SceneError(f"expected a list, got {got(v)}", key=key)
    return v


def as_string(v, key) -> str:
    if not isinstance(v, str) or not v:
        raise SceneError(f"expected a non-empty string, got {show_value(v)}", key=key)
    return v


def check_keys(d, allowed, key, required=()):
    """d must be an object whose keys are all allowed and include the required ones."""
    as_object(d, key)
    prefix = f"{key}." if key else ""
    for k in d:
        if k not in allowed:
            raise SceneError(f"unknown key (expected one of: {', '.join(allowed)})",
                             key=prefix + shown(k))
    for k in required:
        if k not in d:
            raise SceneError(f"missing required key '{k}'", key=key or None)


def json_int(text: str) -> int:
    """JSON integers as int, but none longer than any finite number (int() has a digit limit)."""
    digits = len(text.lstrip("-"))
    if digits > JSON_INT_DIGITS:
        raise SceneError(f"a number of {digits:,} digits: too long (at most {JSON_INT_DIGITS})")
    return int(text)


def is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def is_number(v) -> bool:
    if not isinstance(v, (int, float)) or isinstance(v, bool):
        return False
    try:
        return math.isfinite(v)
    except OverflowError:  # an integer too large for a float
        return False


def number(v, key, lo=None, hi=None, open_lo=False, open_hi=False) -> float:
    if not is_number(v):
        raise SceneError(f"expected a finite number, got {show_value(v)}", key=key)
    v = float(v)
    if (lo is not None and (v < lo or (open_lo and v == lo))) or \
       (hi is not None and (v > hi or (open_hi and v == hi))):
        if hi is None:
            rng = f"{'>' if open_lo else '>='} {lo:g}"
        else:
            rng = "in " + ("(" if open_lo else "[") + f"{lo:g}, {hi:g}" + (")" if open_hi else "]")
        raise SceneError(f"expected a number {rng}, got {show_value(v)}", key=key)
    return v


def numbers(v, count, key, lo=None, hi=None, what=None) -> np.ndarray:
    """A list of `count` finite numbers (optionally in [lo, hi]) as float64."""
    what = what or f"{count} finite numbers"
    if not isinstance(v, list) or len(v) != count or not all(is_number(x) for x in v):
        raise SceneError(f"expected a list of {what}, got {show_value(v)}", key=key)
    for i, x in enumerate(v):
        number(x, f"{key}[{i}]", lo=lo, hi=hi)
    return np.array(v, dtype=np.float64)


def integer(v, key, lo: int, hi: int) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
        raise SceneError(f"expected an integer in [{lo}, {hi}], got {show_value(v)}", key=key)
    return int(v)
