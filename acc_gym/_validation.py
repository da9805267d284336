"""Input checks used at the package's public boundaries.

Each raises ``ValueError`` with a message naming the offending argument and value, so
that a NaN never reaches a solver (ProxQP was seen to iterate for 12 s on a NaN in the
linear term) and a wrong sign never silently produces nonsense.
"""

from __future__ import annotations

import math

import numpy as np

_SCALARS = (float, int, np.float64)  # checked with math, without building an array


def _describe(value) -> str:
    arr = np.asarray(value)
    if arr.ndim == 0:
        return repr(arr.item())
    bad = arr[~np.isfinite(arr)] if arr.dtype.kind == "f" else arr
    head = np.array2string(bad.ravel()[:5], precision=4)
    return f"{head} (shape {arr.shape})"


def check_finite(name: str, value) -> None:
    """Raise ``ValueError`` if ``value`` holds NaN or infinity."""
    if type(value) in _SCALARS:
        if math.isfinite(value):
            return
        raise ValueError(f"{name} must be finite, got {float(value)!r}")
    arr = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {_describe(arr)}")


def check_not_nan(name: str, value) -> None:
    """Raise ``ValueError`` if ``value`` holds NaN (infinity is allowed, e.g. 'no vehicle ahead')."""
    arr = np.asarray(value, dtype=float)
    if np.any(np.isnan(arr)):
        raise ValueError(f"{name} must not be NaN, got {_describe(arr)}")


def check_positive(name: str, value) -> None:
    """Raise ``ValueError`` unless every element of ``value`` is finite and > 0."""
    check_finite(name, value)
    if type(value) in _SCALARS:
        if value > 0:
            return
        raise ValueError(f"{name} must be > 0, got {value!r}")
    arr = np.asarray(value, dtype=float)
    if np.any(arr <= 0):
        raise ValueError(f"{name} must be > 0, got {value!r}")


def check_nonnegative(name: str, value) -> None:
    """Raise ``ValueError`` unless every element of ``value`` is finite and >= 0."""
    check_finite(name, value)
    if type(value) in _SCALARS:
        if value >= 0:
            return
        raise ValueError(f"{name} must be >= 0, got {value!r}")
    arr = np.asarray(value, dtype=float)
    if np.any(arr < 0):
        raise ValueError(f"{name} must be >= 0, got {value!r}")


def from_mapping(cls, d, what: str):
    """``cls(**d)`` for a dataclass, with a ``ValueError`` naming any unknown key (a misspelt
    setting is an error, unlike a dict update)."""
    from dataclasses import fields

    if not isinstance(d, dict):
        raise ValueError(f"{what} must be a mapping, got {type(d).__name__}")
    known = [f.name for f in fields(cls)]
    unknown = set(d) - set(known)
    if unknown:
        raise ValueError(f"unknown {what} setting(s) {sorted(unknown)}; known: {known}")
    return cls(**d)

