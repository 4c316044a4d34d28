"""Shared fixtures. Warnings are errors (pyproject); ray-tracing tests use tiny scenes."""

from __future__ import annotations

import os

# one BLAS thread, as the CLI sets: the chain's matrices are small and multithreaded BLAS on
# them was measured ~10x slower on a loaded 2-core machine (must precede numpy's import)
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pytest
from hypothesis import HealthCheck, settings

# property-based tests (tests/integration/test_bad_inputs_properties.py): derandomized, so CI
# runs the same examples every time and a failure reproduces; no example database written
settings.register_profile("ci", derandomize=True, database=None, print_blob=True,
                          suppress_health_check=[HealthCheck.too_slow])
# HYPOTHESIS_PROFILE=explore: random examples, for a local search beyond the fixed ones
settings.register_profile("explore", parent=settings.get_profile("ci"), derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)
