"""Shared fixtures. Warnings are errors (pyproject); ray-tracing tests use tiny scenes."""

from __future__ import annotations

import os

# one BLAS thread, as the CLI sets: the chain's matrices are small and multithreaded BLAS on
# them was measured ~10x slower on a loaded 2-core machine (must precede numpy's import)
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pytest


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)
