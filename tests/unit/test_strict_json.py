"""``json_text``: strict JSON with the documented encoding of non-finite floats (issue #40)."""

from __future__ import annotations

import json
import math

import numpy as np

from veriloc_rt.fileio import NONFINITE, json_text


def _reject(token):
    raise AssertionError(token)


def test_non_finite_floats_are_strings_or_null_and_read_back():
    obj = {"a": float("inf"), "b": -math.inf, "c": float("nan"), "d": [np.float64(np.inf), 1.5],
           "e": np.array([0.25, -np.inf]), "f": np.int64(3), "g": (1, 2), "h": True}
    back = json.loads(json_text(obj), parse_constant=_reject)
    assert back == {"a": "inf", "b": "-inf", "c": None, "d": ["inf", 1.5], "e": [0.25, "-inf"],
                    "f": 3, "g": [1, 2], "h": True}
    assert NONFINITE == {"inf": "inf", "-inf": "-inf", "nan": None}
    # the documented read-back: float() of the strings
    assert float(back["a"]) == math.inf and float(back["b"]) == -math.inf


def test_finite_floats_are_exact():
    x = [0.1, 1 / 3, 1e-300, 1.7976931348623157e308]
    assert json.loads(json_text(x)) == x
