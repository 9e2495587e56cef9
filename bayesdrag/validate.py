"""Checks of single values read from files or given by users: one message per failure that names
the key, what was found and what is allowed (the readers add the file and line)."""
from __future__ import annotations

import math

import numpy as np


def type_name(value):
    if isinstance(value, bool):
        return f"boolean {str(value).lower()}"
    if isinstance(value, str):
        return f"string {value!r}"
    if isinstance(value, dict):
        return "a table"
    if isinstance(value, list):
        return "an array"
    return f"{type(value).__name__} {value!r}"


def number(key, value, unit="", optional=False):
    """``value`` as a finite float, or ValueError naming ``key`` (bools are not numbers)."""
    if value is None and optional:
        return None
    u = f" ({unit})" if unit else ""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{key} must be a number{u}, got {type_name(value)}")
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"{key} must be a finite number{u}, got {value}")
    return value


def positive(key, value, unit):
    value = number(key, value, unit)
    if value <= 0:
        raise ValueError(f"{key} = {value:g} must be > 0 ({unit})")
    return value


def float_tuple(name, values):
    """``values`` as a tuple of finite floats, or ValueError naming ``name`` (and the level of a
    non-finite value)."""
    try:
        a = np.asarray(values, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a sequence of numbers") from None
    if not np.all(np.isfinite(a)):
        i = int(np.argmax(~np.isfinite(a)))
        raise ValueError(f"{name} value {a[i]} (level {i + 1}) is not a finite number")
    return tuple(float(v) for v in a)
