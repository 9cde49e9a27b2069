"""The one input validator: arrays and numbers from users, checked and named.

Every entry point (the compiled observers, the numpy reference, the baselines) takes its vectors
and matrices through ``as_vector`` and ``as_matrix``: text, dicts, complex numbers, ragged
nesting, a wrong shape or a NaN/Inf raise a ValueError that names the argument and says what was
expected. numpy only, so the independent reference may use it too.
"""
from __future__ import annotations

import math

import numpy as np


def _floats(name, value, expected):
    """value as a float64 array, or ValueError naming ``name``: text, dicts, complex numbers
    and integers beyond a double are refused (numpy would raise without the name, or silently
    drop an imaginary part)."""
    try:
        a = np.asarray(value)
    except (TypeError, ValueError) as e:              # ragged nesting
        raise ValueError(f"{name}: expected {expected}, got {type(value).__name__} ({e})") from None
    if a.dtype.kind == "c" or (a.dtype.kind == "O" and any(isinstance(v, complex) for v in a.flat)):
        raise ValueError(f"{name}: expected {expected}, got complex numbers")
    try:
        if a.dtype.kind not in "biufO":
            raise TypeError(a.dtype)
        return a.astype(float)
    except OverflowError:
        raise ValueError(f"{name}: a value is too large for a double (expected {expected})") from None
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected {expected}, got {type(value).__name__} "
                         f"{str(value)[:60]!r}") from None


def _as_real(name, a, dtype):
    """Finite float64 ``a`` as ``dtype``, or ValueError naming ``name`` if it overflows there."""
    if dtype == np.float64:
        return a
    with np.errstate(over="ignore"):
        r = a.astype(dtype)
    if not np.all(np.isfinite(r)):
        raise ValueError(f"{name}: value {a[~np.isfinite(r)][0]:g} outside the {np.dtype(dtype).name} range")
    return r


def as_vector(name, value, size, dtype=np.float64):
    """value as a finite vector of length size and type ``dtype``, or ValueError naming ``name``."""
    a = _floats(name, value, f"{size} real numbers")
    if a.shape not in ((size,), (size, 1), (1, size)):
        raise ValueError(f"{name}: expected shape ({size},), got {np.shape(value)}")
    a = a.reshape(size)
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: expected {size} finite numbers, shape ({size},); NaN or Inf at "
                         f"index {int(np.argmax(~np.isfinite(a)))}: {a}")
    return _as_real(name, a, dtype)


def as_matrix(name, value, cols, rows=None, dtype=np.float64):
    """value as a finite C-contiguous (rows, cols) matrix of type ``dtype``, or ValueError naming ``name``
    (``cols`` = 0: any empty value is the (rows, 0) matrix)."""
    a = _floats(name, value, f"an (N, {cols}) array of real numbers")
    if cols == 0 and a.size == 0:
        return np.zeros((rows if rows is not None else (a.shape[0] if a.ndim == 2 else 0), 0), dtype)
    if a.ndim != 2 or a.shape[1] != cols or (rows is not None and a.shape[0] != rows):
        want = f"({rows if rows is not None else 'N'}, {cols})"
        raise ValueError(f"{name}: expected shape {want}, got {np.shape(value)}")
    if not np.all(np.isfinite(a)):
        bad = np.argwhere(~np.isfinite(a))[0]
        raise ValueError(f"{name}: NaN or Inf at row {bad[0]}, column {bad[1]}")
    return np.ascontiguousarray(_as_real(name, a, dtype))


def positive(name, value):
    """``value`` as a positive finite float, or ValueError naming ``name`` (booleans refused)."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}") from None
    if isinstance(value, bool) or not (math.isfinite(v) and v > 0):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")
    return v


def time_stamps(name, value, rows, dtype=np.float64):
    """value as ``rows`` finite, strictly increasing time stamps (s) of type ``dtype`` (checked
    after the conversion: float32 may merge close stamps), or ValueError naming ``name`` and the
    first sample whose stamp does not increase."""
    t = as_vector(name, value, rows, dtype)
    bad = np.flatnonzero(np.diff(t) <= 0)
    if len(bad):
        k = int(bad[0]) + 1
        raise ValueError(f"{name}: time stamps must increase; t[{k}] = {float(t[k])!r} after "
                         f"t[{k - 1}] = {float(t[k - 1])!r}")
    return t
