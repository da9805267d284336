"""``acc_gym._io.json_safe``: its exact-type fast path gives what the general checks
(``json_safe_reference``) give, types, signed zeros and key order included."""

from __future__ import annotations

import math

import numpy as np

from acc_gym._io import json_safe, json_safe_reference


def same(a, b) -> bool:
    if type(a) is not type(b):
        return False
    if isinstance(a, dict):
        return list(a) == list(b) and all(same(a[k], b[k]) for k in a)
    if isinstance(a, list):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    if isinstance(a, float):
        return math.copysign(1.0, a) == math.copysign(1.0, b) and a == b
    return a == b


def test_json_safe_equals_the_general_checks():
    values = [0.0, -0.0, 1.5, -2.25e-300, 1e308, math.nan, math.inf, -math.inf, 0, -7, 2 ** 70, True, False, "x",
              None, np.float64(3.5), np.float64(np.nan), np.float32(-np.inf), np.int64(-3), np.bool_(False),
              (1, 2.0, math.nan), [math.inf, {"a": -math.inf}]]
    nested = {"items": {"safety": {"min_q": math.nan, "first": None, "n": 3, "ok": True}}, 5: values}
    for x in values + [nested, {"k": values}]:
        assert same(json_safe(x), json_safe_reference(x)), x
