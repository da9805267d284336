"""Small file helpers shared by every writer of results: atomic writes and JSON-safe values.

Results files (leaderboard reports, campaign chunks and summaries, plots, training
manifests) are written through a temporary file in the same directory, flushed to disk
and moved into place with ``os.replace``, so a reader (or a resumed run) sees either the
whole file or none. Temporary files are named ``.<name>.<random>.tmp``, so a folder's
leftovers from a killed process match ``.*.tmp``.
"""

from __future__ import annotations

import math
import os
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np


def atomic_write(path, data: str | bytes | Callable) -> Path:
    """Write ``data`` (text, bytes, or a callable ``write(binary_file)``) to ``path`` atomically."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            if callable(data):
                data(f)
            else:
                f.write(data.encode("utf-8") if isinstance(data, str) else data)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o644)  # mkstemp's 0600 would otherwise carry over
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


def json_safe(x):
    """NaN -> None, infinities -> their string (``"inf"``), numpy scalars -> Python, recursively.

    Plain Python floats, ints, bools, strings and None (most of a report) are recognised
    by their exact type first; every other value takes :func:`_json_value`'s general
    checks, which give the same result for them (:func:`json_safe_reference` is the
    definition without the fast path; ``tests/test_io.py`` compares the two)."""
    t = type(x)
    if t is float:
        return None if x != x else (str(x) if x - x != 0.0 else x)  # NaN; +-inf (inf - inf is NaN)
    if t is int or t is bool or t is str or x is None:
        return x
    if t is dict:  # a report's dicts: their plain leaves converted here, without a call each
        out = {}
        for k, v in x.items():
            tv = type(v)
            if tv is float:
                v = v if v - v == 0.0 else (None if v != v else str(v))
            elif not (tv is int or tv is bool or tv is str or v is None):
                v = json_safe(v)
            out[k if type(k) is str else str(k)] = v
        return out
    if isinstance(x, dict):
        return {str(k): json_safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [json_safe(v) for v in x]
    return _json_value(x)


def json_leaf(x):
    """:func:`json_safe` of one value, by its exact type first (a report's leaves, one at a time)."""
    t = type(x)
    if t is float:
        return x if x - x == 0.0 else (None if x != x else str(x))
    if t is int or t is bool or t is str or x is None:
        return x
    return json_safe(x)


def json_safe_reference(x):
    """:func:`json_safe` by the general checks alone (its definition)."""
    if isinstance(x, dict):
        return {str(k): json_safe_reference(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [json_safe_reference(v) for v in x]
    return _json_value(x)


def _json_value(x):
    """One non-container value: bools and integers (numpy's too) to Python, floats to Python
    with NaN -> None and infinities -> their string; anything else as it is."""
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        x = float(x)
        return None if math.isnan(x) else (str(x) if math.isinf(x) else x)
    return x
