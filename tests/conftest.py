"""Shared fixtures. Warnings are errors (pyproject); ray-tracing tests use tiny scenes."""

from __future__ import annotations

import numpy as np
import pytest


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)
